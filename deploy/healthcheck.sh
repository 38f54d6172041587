#!/bin/sh
# aliquot-healthcheck: the image's HEALTHCHECK, one command for both roles.
#
# The role is the container's command, so it is read from PID 1's command line
# (`aliquot coordinator --grpc 0.0.0.0:7070 ...`, possibly behind an init such as tini):
#   coordinator  healthy when it answers `aliquot status` on its own gRPC port, with the
#                client token it was given (--client-token-file, else DATA/client.token)
#                and, when it serves TLS, the CA in $ALIQUOT_TLS_CA (else its own
#                certificate, which works when that is self-signed); the certificate must
#                then name 127.0.0.1, the address this check dials;
#   worker       healthy while its process runs (a worker has no server to ask; whether its
#                coordinator answers is the coordinator's health, not the worker's);
#   anything else (`aliquot render`, `--help`, ...) counts as healthy.
set -eu

role=""
grpc=""
data="aliquot-data"
token=""
cert=""
found=0
want=""
# Walk PID 1's NUL-separated arguments: the first word after an `aliquot` word is the role.
# (Arguments with spaces are not expected in these options.)
for arg in $(tr '\0' ' ' </proc/1/cmdline); do
    case "$want" in
        grpc) grpc=$arg; want=""; continue ;;
        data) data=$arg; want=""; continue ;;
        token) token=$arg; want=""; continue ;;
        cert) cert=$arg; want=""; continue ;;
    esac
    case "$arg" in
        */aliquot | aliquot) [ -n "$role" ] || found=1 ;;
        --grpc) want=grpc ;;
        --grpc=*) grpc=${arg#--grpc=} ;;
        --data) want=data ;;
        --data=*) data=${arg#--data=} ;;
        --client-token-file) want=token ;;
        --client-token-file=*) token=${arg#--client-token-file=} ;;
        --tls-cert) want=cert ;;
        --tls-cert=*) cert=${arg#--tls-cert=} ;;
        *) if [ "$found" = 1 ] && [ -z "$role" ]; then role=$arg; fi ;;
    esac
done

case "$role" in
    coordinator)
        port=${grpc##*:}
        # A probe answers within its own timeout (5 s in the image and the manifests)
        # rather than wait the clients' default 10 s for a coordinator that is starting.
        set -- status --coordinator "127.0.0.1:${port:-7070}" \
            --token-file "${token:-$data/client.token}" --connect-timeout 2
        if [ -n "$cert" ]; then set -- "$@" --tls-ca "${ALIQUOT_TLS_CA:-$cert}"; fi
        exec aliquot "$@" >/dev/null
        ;;
    *)
        exit 0
        ;;
esac
