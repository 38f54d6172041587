#!/usr/bin/env bash
# The farm over TLS as an operator sets it up: a throwaway CA made with openssl signs the
# coordinator's certificate (127.0.0.1 and localhost); a worker and the CLI trust that CA
# and carry their role's token. A render over TLS is byte-identical to `aliquot render`;
# clients without the CA, or with another CA, are refused with a message naming TLS; the
# HTTP API answers HTTPS only, and under TLS takes https://HOST as its own Origin.
#
# Usage: tests/tls/run.sh [path/to/aliquot]      (needs openssl, curl, python3)
set -uo pipefail
cd "$(dirname "$0")/../.." || exit 1
ALIQUOT=$(realpath "${1:-build/bin/aliquot}")
TMP=$(mktemp -d "${TMPDIR:-/tmp}/aliquot-tls.XXXXXX")
START=$(date +%s)
passed=0 failed=0
PIDS=()

say() { printf '[%3ss] %s\n' "$(($(date +%s) - START))" "$*"; }
ok() { passed=$((passed + 1)); say "ok   $*"; }
fail() { failed=$((failed + 1)); say "FAIL $*"; }
check() {  # check NAME COMMAND...: passes when COMMAND succeeds
    local name=$1
    shift
    if "$@"; then ok "$name"; else fail "$name"; fi
}

finish() {
    trap - EXIT INT TERM
    local p
    for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done
    for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null; done
    if ((failed)); then
        for log in "$TMP"/*.log; do
            echo "--- $log"
            tail -15 "$log"
        done
        echo "files kept in $TMP"
    else
        rm -rf "$TMP"
    fi
    echo "$passed passed, $failed failed ($(($(date +%s) - START)) s)"
    ((failed == 0))
    exit
}
trap finish EXIT
trap 'fail "interrupted"; exit 1' INT TERM

[[ -x $ALIQUOT ]] || { fail "no aliquot binary at $ALIQUOT"; exit 1; }
for tool in openssl curl python3; do
    command -v "$tool" >/dev/null || { fail "$tool is missing (scripts/install-deps.sh)"; exit 1; }
done

free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

wait_for() {  # wait_for SECONDS COMMAND...: until COMMAND succeeds
    local deadline=$(($(date +%s) + $1))
    shift
    until "$@"; do
        (($(date +%s) < deadline)) || return 1
        sleep 0.2
    done
}

# ---------------------------------------------------------------- certificates

# ca_cert NAME: a CA key and its self-signed certificate (req -x509 marks it CA:TRUE).
ca_cert() {
    openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 \
        -subj "/CN=Aliquot test $1" -keyout "$TMP/$1.key" -out "$TMP/$1.pem" 2>>"$TMP/openssl.log"
}
make_certificates() {
    ca_cert ca && ca_cert other-ca &&
        openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes \
            -subj "/CN=aliquot coordinator" -keyout "$TMP/server.key" -out "$TMP/server.csr" \
            2>>"$TMP/openssl.log" &&
        printf '%s\n' 'subjectAltName = IP:127.0.0.1, DNS:localhost' 'basicConstraints = CA:FALSE' \
            'keyUsage = digitalSignature' 'extendedKeyUsage = serverAuth' >"$TMP/server.ext" &&
        openssl x509 -req -in "$TMP/server.csr" -CA "$TMP/ca.pem" -CAkey "$TMP/ca.key" \
            -CAcreateserial -days 2 -extfile "$TMP/server.ext" -out "$TMP/server.pem" \
            2>>"$TMP/openssl.log" &&
        openssl verify -CAfile "$TMP/ca.pem" "$TMP/server.pem" >/dev/null
}
check "openssl makes a CA, another CA, and a server certificate for 127.0.0.1 signed by the CA" \
    make_certificates || exit 1

# ---------------------------------------------------------------- the farm over TLS

GRPC_PORT=$(free_port)
HTTP_PORT=$(free_port)
ADDR=127.0.0.1:$GRPC_PORT
URL=https://127.0.0.1:$HTTP_PORT
DATA=$TMP/data
RENDER=(--scene cornell-box --resolution 64x48 --spp 16 --seed 5 --method uniform)
# The client's endpoint: the CA and the client token the coordinator writes at its first start.
CLIENT=(--coordinator "$ADDR" --tls-ca "$TMP/ca.pem" --token-file "$DATA/client.token")

"$ALIQUOT" coordinator --grpc "$ADDR" --http "127.0.0.1:$HTTP_PORT" --data "$DATA" \
    --tls-cert "$TMP/server.pem" --tls-key "$TMP/server.key" >"$TMP/coordinator.log" 2>&1 &
PIDS+=($!)
coordinator_answers() {
    [[ -s $DATA/client.token ]] && "$ALIQUOT" status "${CLIENT[@]}" >/dev/null 2>&1
}
check "the coordinator answers a client with the CA and the client token over TLS" \
    wait_for 30 coordinator_answers || exit 1
grep -q "listening service=grpc .* tls=on" "$TMP/coordinator.log" &&
    grep -q "listening service=https .* tls=on" "$TMP/coordinator.log"
check "the coordinator says it serves gRPC over TLS and HTTPS" test $? -eq 0

"$ALIQUOT" worker --coordinator "$ADDR" --tls-ca "$TMP/ca.pem" \
    --token-file "$DATA/worker.token" --threads 2 --name tls-worker >"$TMP/worker.log" 2>&1 &
PIDS+=($!)

# The embedded twin, traced while the farm renders the same spec.
"$ALIQUOT" render "${RENDER[@]}" --threads 1 --out "$TMP/embedded.exr" >"$TMP/embedded.log" 2>&1 &
EMBEDDED_PID=$!

t0=$(date +%s)
if "$ALIQUOT" submit "${CLIENT[@]}" "${RENDER[@]}" --json --wait --out "$TMP/farm.exr" \
    >"$TMP/submit.json" 2>"$TMP/submit.log"; then
    ok "submit --wait over TLS completes ($(($(date +%s) - t0)) s)"
else
    fail "submit --wait over TLS completes"
fi
RENDER_ID=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["id"])' "$TMP/submit.json" 2>/dev/null)
wait "$EMBEDDED_PID"
check "aliquot render of the same spec" test $? -eq 0
check "the EXR rendered over TLS is byte-identical to aliquot render" \
    cmp -s "$TMP/farm.exr" "$TMP/embedded.exr"
check "aliquot fetch over TLS gives the same bytes" \
    eval '"$ALIQUOT" fetch "$RENDER_ID" --out "$TMP/fetched.exr" "${CLIENT[@]}" >/dev/null 2>&1 &&
        cmp -s "$TMP/fetched.exr" "$TMP/embedded.exr"'

# ---------------------------------------------------------------- refusals

# refused NAME PATTERN ARGS...: `aliquot status ARGS` exits non-zero and says PATTERN. A
# handshake that fails looks to gRPC like a coordinator still starting: the client waits
# its --connect-timeout before it reports, so the timeout is short here.
refused() {
    local name=$1 pattern=$2 err status
    shift 2
    err=$("$ALIQUOT" status --coordinator "$ADDR" --connect-timeout 1 "$@" 2>&1 >/dev/null)
    status=$?
    if ((status != 0)) && grep -q -- "$pattern" <<<"$err"; then
        ok "$name: $(grep -- "$pattern" <<<"$err")"
    else
        fail "$name (exit $status): $err"
    fi
}
refused "a client without --tls-ca is refused, told to pass it" "pass --tls-ca" \
    --token-file "$DATA/client.token"
refused "a client trusting another CA is refused, told the CA did not sign the certificate" \
    "not signed by the --tls-ca CA" --token-file "$DATA/client.token" --tls-ca "$TMP/other-ca.pem"
refused "a client with the CA but the worker token is refused" "needs the client token" \
    --token-file "$DATA/worker.token" --tls-ca "$TMP/ca.pem"

# ---------------------------------------------------------------- HTTPS

BEARER="Authorization: Bearer $(cat "$DATA/client.token")"
https() { curl -sS --max-time 10 --cacert "$TMP/ca.pem" -H "$BEARER" "$@"; }
check "HTTPS /healthz answers with the CA" eval '[[ $(https "$URL/healthz") == *"\"ok\":true"* ]]'
check "HTTPS /api/renders lists the render" \
    eval 'https "$URL/api/renders" | grep -q "\"$RENDER_ID\""'
check "curl without the CA refuses the certificate" \
    eval '! curl -sS --max-time 10 -o /dev/null "$URL/healthz" 2>"$TMP/curl-noca.log"'
check "plain http:// to the TLS port gets no answer" \
    eval '! curl -sS --max-time 10 -o /dev/null "http://127.0.0.1:$HTTP_PORT/healthz" 2>"$TMP/curl-plain.log"'

# Under TLS the dashboard's own Origin is https://HOST; http://HOST is another site.
post_status() {  # post_status ORIGIN: the HTTP status of a cancel sent with that Origin
    https -o /dev/null -w '%{http_code}' -X POST -H "Origin: $1" \
        -H "Content-Type: application/json" --data '{}' "$URL/api/renders/$RENDER_ID/cancel"
}
same=$(post_status "https://127.0.0.1:$HTTP_PORT")
other=$(post_status "http://127.0.0.1:$HTTP_PORT")
check "a write with Origin https://HOST passes the cross-site check (status $same)" \
    eval '[[ $same =~ ^[0-9]+$ && $same != 403 && $same != 000 ]]'
check "a write with Origin http://HOST is refused as cross-site (status $other)" test "$other" = 403

# Signing in over HTTPS sets a cookie the browser will send over HTTPS only, named with
# __Host- and the port (docs/SECURITY.md, "The session cookie").
cookie=$(curl -sS --max-time 10 --cacert "$TMP/ca.pem" -o /dev/null -D - -X POST \
    -H "Content-Type: application/json" --data "{\"token\": \"$(cat "$DATA/client.token")\"}" \
    "$URL/api/session" | grep -i '^set-cookie:' || true)
check "signing in over HTTPS sets a Secure, HttpOnly, SameSite=Strict cookie" \
    eval '[[ $cookie == *"__Host-aliquot_session_$HTTP_PORT="* && $cookie == *Secure* && $cookie == *HttpOnly* && $cookie == *SameSite=Strict* ]]'

# The gRPC listener watchdog asks the TLS port as it asks a plaintext one (docs/SECURITY.md).
check "the gRPC watchdog runs over TLS and never found the port deaf" \
    eval '! grep -q "listening again\|no listener watchdog" "$TMP/coordinator.log"'
check "the worker traced over TLS and is still running" \
    eval 'kill -0 "${PIDS[1]}" && [[ $(https "$URL/api/workers") == *tls-worker* ]]'

# ---------------------------------------------------------------- JSON logs

# With --log-format json every line a coordinator or worker writes on stderr is one JSON
# object, gRPC core's own too: here a plaintext client and a worker trusting another CA
# fail their handshakes, which gRPC reports on both sides; then both are stopped.
JSON_ADDR=127.0.0.1:$(free_port)
"$ALIQUOT" coordinator --log-format json --grpc "$JSON_ADDR" --data "$TMP/json-data" \
    --tls-cert "$TMP/server.pem" --tls-key "$TMP/server.key" 2>"$TMP/json-coordinator.log" &
JSON_COORDINATOR=$!
PIDS+=("$JSON_COORDINATOR")
check "a coordinator with --log-format json starts" \
    wait_for 30 grep -q '"event":"listening"' "$TMP/json-coordinator.log"
"$ALIQUOT" status --coordinator "$JSON_ADDR" --connect-timeout 1 \
    --token-file "$TMP/json-data/client.token" >/dev/null 2>&1
"$ALIQUOT" worker --log-format json --coordinator "$JSON_ADDR" --tls-ca "$TMP/other-ca.pem" \
    --token-file "$TMP/json-data/worker.token" --threads 1 2>"$TMP/json-worker.log" &
JSON_WORKER=$!
PIDS+=("$JSON_WORKER")
check "gRPC's own lines reach the coordinator's log: a failed handshake" \
    wait_for 30 grep -q '"event":"grpc".*andshake' "$TMP/json-coordinator.log"
check "gRPC's own lines reach the worker's log: a failed handshake" \
    wait_for 30 grep -q '"event":"grpc".*andshake' "$TMP/json-worker.log"
kill -TERM "$JSON_WORKER" "$JSON_COORDINATOR"
wait "$JSON_WORKER" "$JSON_COORDINATOR" 2>/dev/null
every_line_json() {  # every_line_json FILE: every line an object with a time and an event
    python3 -c '
import json, sys
lines = open(sys.argv[1], encoding="utf-8").read().splitlines()
for line in lines:
    try:
        record = json.loads(line)
    except ValueError:
        sys.exit("not JSON: " + line)
    if not isinstance(record, dict) or "time" not in record or "event" not in record:
        sys.exit("no time or event: " + line)
if not lines:
    sys.exit("no lines")
' "$1"
}
check "every line of the JSON coordinator's stderr, start-up to stop, is JSON" \
    eval 'every_line_json "$TMP/json-coordinator.log" &&
        grep -q "\"event\":\"token_written\"" "$TMP/json-coordinator.log" &&
        grep -q "\"event\":\"coordinator_stopping\"" "$TMP/json-coordinator.log"'
check "every line of the JSON worker's stderr is JSON" every_line_json "$TMP/json-worker.log"
exit 0
