#!/usr/bin/env bash
# The farm's secrets for deploy/docker-compose.yml (and the Kubernetes Secret, see
# deploy/k8s/README.md): client.token and worker.token, 256 random bits each as hex. With
# --tls, also a CA (ca.pem, ca.key) and a coordinator certificate signed by it (server.pem,
# server.key) for `coordinator`, `localhost`, 127.0.0.1 and any NAME given.
#
# Usage: deploy/make-secrets.sh [--tls [NAME...]]     (DIR: $ALIQUOT_SECRETS, else deploy/secrets)
#
# Files that exist are kept: delete a token file and run again to rotate that token
# (docs/SECURITY.md, "Rotating tokens"). The directory is mode 0700; the files but ca.key
# are 0644 because compose mounts them as they are into containers that run as uid 10001.
set -euo pipefail
dir=${ALIQUOT_SECRETS:-$(dirname "$0")/secrets}
mkdir -p "$dir"
chmod 700 "$dir"

for role in client worker; do
    file=$dir/$role.token
    if [[ -s $file ]]; then
        echo "kept    $file"
    else
        (umask 022 && openssl rand -hex 32 >"$file")
        echo "wrote   $file"
    fi
done

[[ ${1:-} == --tls ]] || exit 0
shift
if [[ ! -s $dir/ca.pem ]]; then
    openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 825 \
        -subj "/CN=Aliquot farm CA" -keyout "$dir/ca.key" -out "$dir/ca.pem" 2>/dev/null
    chmod 600 "$dir/ca.key"
    echo "wrote   $dir/ca.pem (and ca.key, which only signs: keep it off the farm)"
fi
if [[ ! -s $dir/server.pem ]]; then
    san="DNS:coordinator,DNS:localhost,IP:127.0.0.1"
    for name in "$@"; do
        if [[ $name =~ ^[0-9.]+$ || $name == *:* ]]; then san+=",IP:$name"; else san+=",DNS:$name"; fi
    done
    ext=$(mktemp)
    trap 'rm -f "$ext" "$dir/server.csr"' EXIT
    printf '%s\n' "subjectAltName = $san" 'basicConstraints = CA:FALSE' \
        'keyUsage = digitalSignature' 'extendedKeyUsage = serverAuth' >"$ext"
    (umask 022 && openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes \
        -subj "/CN=aliquot coordinator" -keyout "$dir/server.key" -out "$dir/server.csr" 2>/dev/null)
    openssl x509 -req -in "$dir/server.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" \
        -CAcreateserial -days 825 -extfile "$ext" -out "$dir/server.pem" 2>/dev/null
    # openssl writes keys 0600; the coordinator's container user must read this one.
    chmod 644 "$dir/server.key"
    echo "wrote   $dir/server.pem for $san (and server.key)"
fi
