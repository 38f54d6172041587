#!/bin/sh
# aliquot-healthcheck: the image's HEALTHCHECK, one command for both roles.
#
# The role is the container's command, so it is read from PID 1's command line
# (`aliquot coordinator --grpc 0.0.0.0:7070 ...`, possibly behind an init such as tini):
#   coordinator  healthy when it answers `aliquot status` on its own gRPC port;
#   worker       healthy while its process runs (a worker has no server to ask; whether its
#                coordinator answers is the coordinator's health, not the worker's);
#   anything else (`aliquot render`, `--help`, ...) counts as healthy.
set -eu

role=""
grpc=""
found=0
want_grpc=0
# Walk PID 1's NUL-separated arguments: the first word after an `aliquot` word is the role.
for arg in $(tr '\0' ' ' </proc/1/cmdline); do
    if [ "$want_grpc" = 1 ]; then grpc=$arg; want_grpc=0; continue; fi
    case "$arg" in
        */aliquot | aliquot) [ -n "$role" ] || found=1 ;;
        --grpc) want_grpc=1 ;;
        --grpc=*) grpc=${arg#--grpc=} ;;
        *) if [ "$found" = 1 ] && [ -z "$role" ]; then role=$arg; fi ;;
    esac
done

case "$role" in
    coordinator)
        port=${grpc##*:}
        exec aliquot status --coordinator "127.0.0.1:${port:-7070}" >/dev/null
        ;;
    *)
        exit 0
        ;;
esac
