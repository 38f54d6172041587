#!/bin/sh
# aliquot-healthcheck: the image's HEALTHCHECK, one command for both roles.
#
# The role is the container's command, so it is read from PID 1's command line
# (`aliquot coordinator --grpc 0.0.0.0:7070 ...`, possibly behind an init such as tini):
#   coordinator  healthy when gRPC's health service on its own port answers SERVING
#                (`aliquot health`, no token: what Kubernetes' gRPC probes ask), trusting,
#                when it serves TLS, the CA in $ALIQUOT_TLS_CA (else its own certificate,
#                which works when that is self-signed); the certificate must then name
#                127.0.0.1, the address this check dials;
#   worker       with --health-file FILE: healthy while FILE's modification time, which the
#                worker keeps at the moment all its threads were last known not stuck, is
#                at most $ALIQUOT_WORKER_STALL_SECONDS (default 120) old: longer than any
#                call to the coordinator may take (their deadlines) and than a job's trace
#                (jobs are sized to a few seconds). Without --health-file, healthy while
#                its process runs. Whether its coordinator answers is the coordinator's
#                health, not the worker's: a worker waiting for it is alive;
#   anything else (`aliquot render`, `--help`, ...) counts as healthy.
set -eu

role=""
grpc=""
cert=""
health=""
found=0
want=""
# Walk PID 1's NUL-separated arguments: the first word after an `aliquot` word is the role.
# (Arguments with spaces are not expected in these options.)
for arg in $(tr '\0' ' ' </proc/1/cmdline); do
    case "$want" in
        grpc) grpc=$arg; want=""; continue ;;
        cert) cert=$arg; want=""; continue ;;
        health) health=$arg; want=""; continue ;;
    esac
    case "$arg" in
        */aliquot | aliquot) [ -n "$role" ] || found=1 ;;
        --grpc) want=grpc ;;
        --grpc=*) grpc=${arg#--grpc=} ;;
        --tls-cert) want=cert ;;
        --tls-cert=*) cert=${arg#--tls-cert=} ;;
        --health-file) want=health ;;
        --health-file=*) health=${arg#--health-file=} ;;
        *) if [ "$found" = 1 ] && [ -z "$role" ]; then role=$arg; fi ;;
    esac
done

case "$role" in
    coordinator)
        port=${grpc##*:}
        # A probe answers within its own timeout (5 s in the image and the manifests):
        # one health call of at most 2 s.
        set -- health --coordinator "127.0.0.1:${port:-7070}" --timeout 2
        if [ -n "$cert" ]; then set -- "$@" --tls-ca "${ALIQUOT_TLS_CA:-$cert}"; fi
        exec aliquot "$@" >/dev/null
        ;;
    worker)
        [ -n "$health" ] || exit 0
        modified=$(stat -c %Y "$health" 2>/dev/null) || {
            echo "worker: no health file $health" >&2
            exit 1
        }
        age=$(($(date +%s) - modified))
        if [ "$age" -gt "${ALIQUOT_WORKER_STALL_SECONDS:-120}" ]; then
            echo "worker: a thread has been stuck for ${age} s ($health)" >&2
            exit 1
        fi
        ;;
    *)
        exit 0
        ;;
esac
