#!/usr/bin/env bash
# The local cluster of deploy/docker-compose.yml, for real, on a real Docker engine.
#
# Installs docker.io, docker-compose and debootstrap from Debian's packages when missing,
# starts dockerd when none runs, makes the base images locally (no image registry is
# reachable here), builds deploy/Dockerfile, brings up a coordinator and 3 workers, submits a
# render from the host CLI, kills one worker container in the middle of it, and checks the
# fetched EXR is byte-identical to `aliquot render` of the same render on the host. Then the
# dashboard answers 200, a crashed worker is restarted, the workers scale to 4, the farm is
# recreated with deploy/docker-compose.tls.yml and renders over TLS, and everything is torn
# down (volumes too), after a failure as well. The tokens and TLS files are made by
# deploy/make-secrets.sh in the run's temporary directory (ALIQUOT_SECRETS); the host CLI
# carries the client token in ALIQUOT_TOKEN. The Kubernetes manifests
# are validated alongside (tests/compose/k8s_check.sh). docs/DEPLOY.md has the details.
#
# Usage: tests/compose/run.sh [path/to/aliquot]     (needs root, or sudo, for Docker)
#        ALIQUOT_COMPOSE="docker compose" tests/compose/run.sh ...   to use compose v2
# Caches (git-ignored, under build/compose-cache/): the base rootfs tarball, kubeconform and
# its schemas. Docker's own layer cache keeps the build packages between runs.
set -uo pipefail
cd "$(dirname "$0")/../.." || exit 1
ROOT=$PWD
ALIQUOT=$(realpath "${1:-build/bin/aliquot}")
CACHE=$ROOT/build/compose-cache
mkdir -p "$CACHE"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/aliquot-compose.XXXXXX")
PROJECT="aliquot-test-$$-$RANDOM"
IMAGE=aliquot:compose-test
COMPOSE_FILE_ARGS=(-f deploy/docker-compose.yml)
# A render long enough that a worker can die in the middle of it: 33M samples, about ten
# seconds on 2 cores (96x96 at 512 spp ended, once, before the test could pick a victim).
RENDER=(--scene cornell-box --resolution 128x128 --spp 2048 --seed 11)

SUDO=()
[[ $(id -u) -eq 0 ]] || SUDO=(sudo --preserve-env)  # the ALIQUOT_* settings reach compose
START=$(date +%s)
passed=0 failed=0 skipped=0
DOCKERD_PID=""
K8S_PID=""
UP=0
COMPLETED=0

say() { printf '[%4ss] %s\n' "$(($(date +%s) - START))" "$*"; }
ok() { passed=$((passed + 1)); say "ok   $*"; }
fail() { failed=$((failed + 1)); say "FAIL $*"; }
skip() { skipped=$((skipped + 1)); say "skip $*"; }

docker() { "${SUDO[@]}" env DOCKER_BUILDKIT=0 docker "$@"; }
dc() { "${SUDO[@]}" "${COMPOSE[@]}" -p "$PROJECT" "${COMPOSE_FILE_ARGS[@]}" "$@"; }

free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

json_field() {  # json_field FIELD < JSON
    python3 -c 'import json, sys; v = json.load(sys.stdin)[sys.argv[1]]; print(v)' "$1"
}

# ---------------------------------------------------------------- tools and engine

install_missing() {
    local missing=() p
    for p in "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
            missing+=("$p")
    done
    ((${#missing[@]})) || return 0
    say "installing ${missing[*]}"
    "${SUDO[@]}" apt-get update -qq &&
        "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive \
            apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

start_engine() {
    if docker info >/dev/null 2>&1; then return 0; fi
    say "starting dockerd (log: build/compose-cache/dockerd.log)"
    "${SUDO[@]}" dockerd >"$CACHE/dockerd.log" 2>&1 &
    DOCKERD_PID=$!
    local i
    for ((i = 0; i < 120; i++)); do
        docker info >/dev/null 2>&1 && return 0
        kill -0 "$DOCKERD_PID" 2>/dev/null || break
        sleep 0.5
    done
    tail -20 "$CACHE/dockerd.log"
    return 1
}

# debian:bookworm and debian:bookworm-slim, made here with debootstrap and `docker import`
# because no image registry is reachable. Both tags are the same minbase rootfs (one
# debootstrap, one import): the build stage only needs apt, and the runtime stage gets the
# slim image's main property, no documentation or man pages installed by dpkg.
ensure_base_images() {
    local missing=() tag
    for tag in debian:bookworm debian:bookworm-slim; do
        docker image inspect "$tag" >/dev/null 2>&1 || missing+=("$tag")
    done
    ((${#missing[@]})) || return 0
    local tarball=$CACHE/debian-bookworm-minbase.tar
    if [[ ! -s $tarball ]]; then
        say "debootstrap bookworm (minbase) into build/compose-cache"
        local rootfs=$CACHE/rootfs
        "${SUDO[@]}" rm -rf "$rootfs"
        "${SUDO[@]}" debootstrap --variant=minbase bookworm "$rootfs" >"$CACHE/debootstrap.log" 2>&1 ||
            { tail -20 "$CACHE/debootstrap.log"; return 1; }
        # The suites the published images have: bookworm, its updates and security, from the
        # mirror debootstrap used.
        local mirror
        mirror=$(awk '$1 == "deb" { print $2; exit }' "$rootfs/etc/apt/sources.list")
        printf 'deb %s bookworm main\ndeb %s bookworm-updates main\ndeb %s-security bookworm-security main\n' \
            "$mirror" "$mirror" "$mirror" | "${SUDO[@]}" tee "$rootfs/etc/apt/sources.list" >/dev/null
        printf '%s\n' 'path-exclude /usr/share/doc/*' 'path-include /usr/share/doc/*/copyright' \
            'path-exclude /usr/share/man/*' 'path-exclude /usr/share/info/*' \
            'path-exclude /usr/share/locale/*' 'path-include /usr/share/locale/locale.alias' |
            "${SUDO[@]}" tee "$rootfs/etc/dpkg/dpkg.cfg.d/excludes" >/dev/null
        "${SUDO[@]}" rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/* \
            "$rootfs"/var/log/*.log
        "${SUDO[@]}" tar -C "$rootfs" --numeric-owner -cf "$tarball.part" . &&
            "${SUDO[@]}" mv "$tarball.part" "$tarball" || return 1
        "${SUDO[@]}" rm -rf "$rootfs"
    fi
    say "docker import ${missing[*]}"
    docker import --change 'CMD ["bash"]' "$tarball" "${missing[0]}" >/dev/null || return 1
    for tag in "${missing[@]:1}"; do docker tag "${missing[0]}" "$tag" || return 1; done
}

# The build context: the files git would commit (tracked, or untracked and not ignored, so
# no build*/, .venv or node_modules), plus the built dashboard web/dist when there is one,
# less what .dockerignore leaves out, matched as Docker matches it (the
# classic builder applies a .dockerignore only when it makes the context from a directory),
# but with the Dockerfile, which the builder reads from the context.
build_context() {
    {
        git ls-files -z -co --exclude-standard
        [[ ! -f web/dist/index.html ]] || find web/dist -type f -print0
    } | python3 -c '
import os, re, sys

def pattern(p):
    out, i = "", 0
    while i < len(p):
        if p.startswith("**/", i): out, i = out + "(?:.*/)?", i + 3
        elif p.startswith("**", i): out, i = out + ".*", i + 2
        elif p[i] == "*": out, i = out + "[^/]*", i + 1
        elif p[i] == "?": out, i = out + "[^/]", i + 1
        else: out, i = out + re.escape(p[i]), i + 1
    return re.compile(out + "$")

rules = []
for line in open(".dockerignore"):
    line = line.strip()
    if line and not line.startswith("#"):
        keep = line.startswith("!")
        rules.append((keep, pattern(os.path.normpath(line.lstrip("!").strip()).lstrip("/"))))
for path in sorted(set(sys.stdin.read().split("\0")) - {""}):
    parts = path.split("/")
    prefixes = ["/".join(parts[:i]) for i in range(1, len(parts) + 1)]
    excluded = False
    for keep, rx in rules:  # the last pattern that matches the path or a parent decides
        if any(rx.match(p) for p in prefixes):
            excluded = not keep
    if (not excluded or path == "deploy/Dockerfile") and os.path.isfile(path):
        sys.stdout.write(path + "\0")
' | tar --null -T - -cf -
}

build_image() {
    # The build stage gets a tag of its own so that pruning old images below never removes
    # the cached layer of build packages.
    build_context | docker build --force-rm -f deploy/Dockerfile --target build -t "$IMAGE-build" - \
        >"$TMP/build.log" 2>&1 &&
        build_context | docker build --force-rm -f deploy/Dockerfile -t "$IMAGE" - >>"$TMP/build.log" 2>&1
    local rc=$?
    ((rc == 0)) || { tail -30 "$TMP/build.log"; return "$rc"; }
    # Replaced images of earlier runs (only ours, by label) so that runs do not pile up.
    docker image prune -f --filter label=org.opencontainers.image.title=aliquot >/dev/null
    docker image prune -f --filter label=org.opencontainers.image.title=aliquot-build >/dev/null
    return 0
}

# The Dockerfile keeps up with the project: every package scripts/install-deps.sh installs is
# in its build list or is one the image build does not use, and every directory the CMake
# build reads is copied into its build stage.
dockerfile_keeps_up() {
    python3 - <<'EOF'
import glob, re, sys
# Tools for tests and development (the format check, the fuzzers), not for building the image.
NOT_FOR_THE_IMAGE = {"git", "sqlite3", "python3", "python3-venv", "python3-pip", "nodejs", "npm",
                     "python3-matplotlib", "python3-numpy",
                     "golang-go", "clang", "clang-format", "libclang-rt-14-dev", "openssl", "curl",
                     "python3-prometheus-client", "python3-grpcio", "python3-protobuf",
                     "openimageio-tools", "iproute2", "iptables"}
# Built only with -DALIQUOT_FUZZ=ON, by scripts/fuzz.sh.
DIRS_NOT_FOR_THE_IMAGE = {"fuzz"}
dockerfile = open("deploy/Dockerfile").read()
script = re.sub(r"#.*", "", open("scripts/install-deps.sh").read())
# Package names only: a list built from other lists ("${build_packages[@]}") names none.
listed = {w for m in re.finditer(r"packages\+?=\(([^)]*)\)", script) for w in m.group(1).split()
          if re.fullmatch(r"[a-z0-9][a-z0-9+.-]+", w)}
m = re.search(r'ARG BUILD_PACKAGES="([^"]*)"', dockerfile)
image = set(m.group(1).replace("\\", " ").split()) if m else set()
problems = []
missing = sorted(listed - image - NOT_FOR_THE_IMAGE)
if not listed or not image or missing:
    problems.append("scripts/install-deps.sh installs packages that BUILD_PACKAGES does not "
                    f"account for: {' '.join(missing) or '(could not read the lists)'}")
cmake = open("CMakeLists.txt").read()
dirs = set(re.findall(r"add_subdirectory\(\s*([\w.-]+)", cmake))
for sub in [""] + sorted(dirs):
    for f in glob.glob(f"{sub}/**/CMakeLists.txt" if sub else "CMakeLists.txt", recursive=True):
        dirs |= set(re.findall(r"\$\{(?:PROJECT|CMAKE)_SOURCE_DIR\}/([\w.-]+)", open(f).read()))
copied = set(re.findall(r"^COPY (?!--)([\w.-]+)/ ", dockerfile, re.M))
dirs -= DIRS_NOT_FOR_THE_IMAGE
if not dirs or dirs - copied:
    problems.append("the build stage does not copy what CMake reads: "
                    f"{' '.join(sorted(dirs - copied)) or '(no directories found)'}")
for p in problems:
    print("deploy/Dockerfile: " + p)
sys.exit(1 if problems else 0)
EOF
}

# ---------------------------------------------------------------- the farm

wait_for() {  # wait_for SECONDS COMMAND...: until COMMAND succeeds
    local deadline=$(($(date +%s) + $1))
    shift
    until "$@"; do
        (($(date +%s) < deadline)) || return 1
        sleep 0.3
    done
}

# The host CLI's TLS options: none until the farm is recreated with TLS.
TLS_ARGS=()
coordinator_answers() { "$ALIQUOT" status --coordinator "$ADDR" "${TLS_ARGS[@]}" >/dev/null 2>&1; }

workers_alive() {  # workers_alive N: N workers registered and not lost
    "$ALIQUOT" workers --json --coordinator "$ADDR" "${TLS_ARGS[@]}" 2>/dev/null | python3 -c '
import json, sys
ws = json.load(sys.stdin)
sys.exit(0 if sum(w["state"] != "lost" for w in ws) >= int(sys.argv[1]) else 1)' "$1"
}

render_has_samples() {
    local s
    s=$("$ALIQUOT" status "$RENDER_ID" --json --coordinator "$ADDR" 2>/dev/null) || return 1
    (($(json_field samples_done <<<"$s") > 0))
}

render_done() {
    local s
    s=$("$ALIQUOT" status "$RENDER_ID" --json --coordinator "$ADDR" 2>/dev/null) || return 1
    [[ $(json_field state <<<"$s") == "done" ]]
}

# The worker container to kill: one holding a lease right now when there is one. A worker's
# default name is HOSTNAME-PID, and a container's hostname is its short id.
pick_victim() {
    local busy id
    busy=$("$ALIQUOT" workers --json --coordinator "$ADDR" 2>/dev/null | python3 -c '
import json, sys
busy = [w["name"] for w in json.load(sys.stdin) if w["leases"]]
print(busy[0].rsplit("-", 1)[0] if busy else "")') || busy=""
    for id in $(dc ps -q worker); do
        if [[ -n $busy && $id == "$busy"* ]]; then
            echo "$id busy"
            return
        fi
    done
    echo "$(dc ps -q worker | head -1) idle"
}

http_ok() {  # http_ok URL [BODY_FILE]: the URL answers 200 (its body saved to BODY_FILE)
    python3 - "$1" "${2:-/dev/null}" <<'EOF'
import sys, urllib.request
try:
    with urllib.request.urlopen(sys.argv[1], timeout=5) as r:
        open(sys.argv[2], "wb").write(r.read())
        sys.exit(0 if r.status == 200 else 1)
except Exception:
    sys.exit(1)
EOF
}

restarted() {  # restarted CONTAINER: running again after at least one restart
    [[ $(docker inspect -f '{{.State.Running}} {{.RestartCount}}' "$1") =~ ^true\ [1-9] ]]
}

# A Kubernetes-style gRPC probe: grpc.health.v1.Health/Check with no token, for the
# server ("") and each service, as the kubelet's `grpc:` probe asks it.
grpc_healthy() {  # grpc_healthy [--ca PEM]
    local service
    for service in "" aliquot.v1.ClientService aliquot.v1.WorkerService; do
        # Debian's Python, for which python3-grpcio is installed.
        /usr/bin/python3 tests/ops/grpc_probe.py "$@" health "$ADDR" $service >/dev/null 2>&1 ||
            return 1
    done
}

# Every worker container's own HEALTHCHECK passes: its --health-file is fresh.
workers_healthy() {
    local ids id
    ids=$(dc ps -q worker)
    [[ -n $ids ]] || return 1
    for id in $ids; do
        [[ $(docker inspect -f '{{if .State.Health}}{{.State.Health.Status}}{{end}}' "$id") == healthy ]] ||
            return 1
    done
}

running_workers() { dc ps -q worker | xargs -r "${SUDO[@]}" docker inspect -f '{{.State.Running}}' | grep -c true; }

# ---------------------------------------------------------------- teardown

teardown() {
    if ((UP)); then
        if ((failed)); then
            say "logs of the failed run:"
            dc logs --no-color --tail 40 2>&1 | sed 's/^/    /'
        fi
        dc down -v --remove-orphans -t 5 >"$TMP/down.log" 2>&1
        # Whatever `down` may have missed, found by the project's label.
        local left
        left=$(docker ps -aq --filter "label=com.docker.compose.project=$PROJECT")
        [[ -z $left ]] || docker rm -f $left >/dev/null
        left=$(docker volume ls -q --filter "label=com.docker.compose.project=$PROJECT")
        [[ -z $left ]] || docker volume rm -f $left >/dev/null
        if [[ -z $(docker ps -aq --filter "label=com.docker.compose.project=$PROJECT") &&
            -z $(docker volume ls -q --filter "label=com.docker.compose.project=$PROJECT") ]]; then
            ok "teardown: no container or volume of $PROJECT left"
        else
            fail "teardown: containers or volumes of $PROJECT left"
        fi
        UP=0
    fi
}

finish() {
    trap - EXIT INT TERM
    # An exit nobody counted (a syntax error, `set -u`) must not read as a pass.
    ((COMPLETED || failed)) || fail "the run stopped before its end (see above)"
    teardown
    if [[ -n $K8S_PID ]]; then
        if wait "$K8S_PID"; then ok "kubernetes manifests (kubeconform)"; else fail "kubernetes manifests (kubeconform)"; fi
        sed 's/^/    /' "$TMP/k8s.log"
    fi
    if [[ -n $DOCKERD_PID ]]; then  # leave the machine as it was found
        "${SUDO[@]}" kill "$DOCKERD_PID" 2>/dev/null
        wait "$DOCKERD_PID" 2>/dev/null
    fi
    say "done"
    if ((failed)); then echo "files kept in $TMP"; else rm -rf "$TMP"; fi
    echo "$passed passed, $failed failed, $skipped skipped"
    ((failed == 0))
    exit
}
trap finish EXIT
trap 'fail "interrupted"; exit 1' INT TERM

# ---------------------------------------------------------------- the run

[[ -x $ALIQUOT ]] || { fail "no aliquot binary at $ALIQUOT"; exit 1; }

# The manifests need no engine: checked in the background meanwhile.
bash tests/compose/k8s_check.sh >"$TMP/k8s.log" 2>&1 &
K8S_PID=$!

# docker, compose and the base rootfs; TLS files; the gRPC health probe's Python gRPC,
# protobuf, protoc and grpc-proto (tests/ops/grpc_probe.py).
HOST_PACKAGES=(docker.io docker-compose debootstrap openssl curl
    python3-grpcio python3-protobuf protobuf-compiler grpc-proto)
install_missing "${HOST_PACKAGES[@]}" || { fail "install ${HOST_PACKAGES[*]}"; exit 1; }
# ALIQUOT_COMPOSE picks the compose command ("docker compose" for v2); by default Debian's
# docker-compose (v1), else `docker compose`.
if [[ -n ${ALIQUOT_COMPOSE:-} ]]; then
    read -ra COMPOSE <<<"$ALIQUOT_COMPOSE"
elif command -v docker-compose >/dev/null; then
    COMPOSE=(docker-compose)
else
    COMPOSE=(docker compose)
fi
start_engine || { fail "start dockerd"; exit 1; }
say "engine up ($(docker version -f '{{.Server.Version}}' 2>/dev/null)), compose: $("${COMPOSE[@]}" version --short 2>/dev/null)"

# The farm's secrets as an operator makes them (tokens, a CA and the coordinator's
# certificate), here in the run's directory; the host CLI's client token.
export ALIQUOT_SECRETS=$TMP/secrets
if bash deploy/make-secrets.sh --tls >"$TMP/secrets.log" 2>&1; then
    ok "deploy/make-secrets.sh --tls makes the tokens and TLS files"
else
    cat "$TMP/secrets.log"
    fail "deploy/make-secrets.sh --tls"
    exit 1
fi
ALIQUOT_TOKEN=$(cat "$ALIQUOT_SECRETS/client.token")
export ALIQUOT_TOKEN

if dc config -q; then ok "compose file is valid for ${COMPOSE[*]}"; else fail "compose file is invalid for ${COMPOSE[*]}"; fi
if dc -f deploy/docker-compose.tls.yml config -q; then
    ok "compose file with the TLS override is valid"
else
    fail "compose file with the TLS override is invalid"
fi

dockerfile_keeps_up && ok "the Dockerfile covers install-deps.sh's packages and CMake's directories" ||
    fail "the Dockerfile covers install-deps.sh's packages and CMake's directories"
ensure_base_images || { fail "base images debian:bookworm, debian:bookworm-slim"; exit 1; }
say "building $IMAGE (log in the run's files)"
if build_image; then ok "image builds"; else fail "image builds"; exit 1; fi
size=$(docker image inspect -f '{{.Size}}' "$IMAGE")
user=$(docker image inspect -f '{{.Config.User}}' "$IMAGE")
say "image: $((size / 1024 / 1024)) MiB, user '$user'"
[[ -n $user && $user != root && $user != 0 ]] && ok "image runs as a non-root user ($user)" || fail "image runs as root"

# The embedded twin of the farm's render, made before the farm starts so neither slows
# the other.
"$ALIQUOT" render "${RENDER[@]}" --threads 2 --out "$TMP/embedded.exr" >"$TMP/embedded.log" 2>&1 ||
    { fail "aliquot render on the host"; exit 1; }
say "embedded render on the host done"

export ALIQUOT_IMAGE=$IMAGE ALIQUOT_BIND=127.0.0.1
ALIQUOT_GRPC_PORT=$(free_port)
ALIQUOT_HTTP_PORT=$(free_port)
export ALIQUOT_GRPC_PORT ALIQUOT_HTTP_PORT ALIQUOT_LEASE_SECONDS=3 ALIQUOT_LOST_SECONDS=3
ADDR=127.0.0.1:$ALIQUOT_GRPC_PORT

# The coordinator's --http flag (the dashboard) may not exist yet in this tree: without it,
# the coordinator runs without --http and the dashboard check is skipped, not passed.
HAS_HTTP=0
if docker run --rm "$IMAGE" coordinator --help 2>/dev/null | grep -q -- '--http'; then
    HAS_HTTP=1
else
    cat >"$TMP/no-http.yml" <<'EOF'
services:
  coordinator:
    command: [coordinator, --grpc, "0.0.0.0:7070", --data, /data,
              --lease-seconds, "${ALIQUOT_LEASE_SECONDS:-30}", --lost-seconds, "${ALIQUOT_LOST_SECONDS:-10}"]
EOF
    COMPOSE_FILE_ARGS+=(-f "$TMP/no-http.yml")
fi

UP=1
if dc up -d --no-build --scale worker=3 >"$TMP/up.log" 2>&1; then
    ok "up: coordinator healthy, 3 workers started (project $PROJECT)"
else
    cat "$TMP/up.log"
    fail "up: coordinator and 3 workers"
    exit 1
fi
wait_for 30 coordinator_answers && ok "host CLI reaches the coordinator on $ADDR" ||
    { fail "host CLI reaches the coordinator on $ADDR"; exit 1; }
wait_for 30 workers_alive 3 && ok "3 workers registered with the worker token" || fail "3 workers registered"
if grpc_healthy; then
    ok "gRPC health answers SERVING without a token, for the server and both services (a Kubernetes grpc probe)"
else
    fail "gRPC health answers SERVING without a token (a Kubernetes grpc probe)"
fi
if wait_for 60 workers_healthy; then
    ok "the worker containers' healthcheck passes on their --health-file"
else
    fail "the worker containers' healthcheck passes on their --health-file"
fi
# The worker token is not a client's.
if ALIQUOT_TOKEN=$(cat "$ALIQUOT_SECRETS/worker.token") "$ALIQUOT" status --coordinator "$ADDR" \
    >/dev/null 2>"$TMP/wrong-token.log"; then
    fail "a client with the worker token is refused"
else
    ok "a client with the worker token is refused: $(cat "$TMP/wrong-token.log")"
fi

RENDER_ID=$("$ALIQUOT" submit --coordinator "$ADDR" --json "${RENDER[@]}" | json_field id) ||
    { fail "submit from the host CLI"; exit 1; }
say "submitted $RENDER_ID"
if wait_for 60 render_has_samples; then
    read -r victim held < <(pick_victim)
    if render_done; then
        fail "the render finished before a worker could be killed"
    elif docker kill "$victim" >/dev/null; then
        ok "killed worker container ${victim:0:12} mid-render ($held)"
    else
        fail "docker kill $victim"
    fi
else
    fail "render got no samples in 60 s"
fi
if wait_for 300 render_done; then
    "$ALIQUOT" fetch "$RENDER_ID" --out "$TMP/farm.exr" --coordinator "$ADDR" >/dev/null &&
        cmp -s "$TMP/farm.exr" "$TMP/embedded.exr" &&
        ok "EXR fetched from the farm is byte-identical to aliquot render" ||
        fail "EXR fetched from the farm differs from aliquot render (or fetch failed)"
else
    fail "render not done in 300 s"
fi

if ((HAS_HTTP)); then
    URL=http://127.0.0.1:$ALIQUOT_HTTP_PORT/
    if wait_for 20 http_ok "$URL" "$TMP/dashboard.html"; then
        if grep -q "dashboard is not built" "$TMP/dashboard.html"; then
            ok "dashboard $URL answers 200 (its placeholder: web/dist was not built before the image)"
        else
            ok "dashboard $URL answers 200 (the built dashboard)"
        fi
    else
        fail "dashboard $URL answers 200"
    fi
    http_ok "http://127.0.0.1:$ALIQUOT_HTTP_PORT/healthz" && ok "HTTP /healthz answers 200" ||
        fail "HTTP /healthz answers 200"
else
    skip "dashboard: this coordinator has no --http flag yet"
fi

# `docker kill` counts as a deliberate stop, which restart policies respect; a worker that
# crashes (its process killed from outside Docker) must be restarted by `unless-stopped`.
crashed=$(dc ps -q worker | while read -r id; do
    [[ $(docker inspect -f '{{.State.Running}}' "$id") == true ]] && echo "$id" && break
done)
if [[ -n $crashed ]] && "${SUDO[@]}" kill -9 "$(docker inspect -f '{{.State.Pid}}' "$crashed")" &&
    wait_for 30 restarted "$crashed"; then
    ok "a crashed worker container is restarted (restart: unless-stopped)"
else
    fail "a crashed worker container is restarted (restart: unless-stopped)"
fi

if dc up -d --no-build --scale worker=4 >"$TMP/scale.log" 2>&1 && wait_for 30 workers_alive 4; then
    ok "scaled to 4 workers ($(running_workers) running)"
else
    cat "$TMP/scale.log"
    fail "scale to 4 workers"
fi

# The same farm recreated with TLS (deploy/docker-compose.tls.yml): the data volume is
# kept; the coordinator serves gRPC and HTTPS with the certificate make-secrets.sh signed
# for `coordinator` and 127.0.0.1; the workers and the host CLI trust its CA.
COMPOSE_FILE_ARGS+=(-f deploy/docker-compose.tls.yml)
TLS_ARGS=(--tls-ca "$ALIQUOT_SECRETS/ca.pem")
if dc up -d --no-build --scale worker=2 >"$TMP/tls-up.log" 2>&1 && wait_for 30 coordinator_answers; then
    ok "recreated with TLS: the coordinator is healthy and answers the CLI with --tls-ca"
else
    cat "$TMP/tls-up.log"
    fail "recreate the farm with TLS"
fi
if "$ALIQUOT" status --coordinator "$ADDR" >/dev/null 2>"$TMP/plain.log"; then
    fail "a client without --tls-ca is refused by the TLS farm"
else
    ok "a client without --tls-ca is refused: $(cat "$TMP/plain.log")"
fi
wait_for 30 workers_alive 2 && ok "2 workers registered over TLS" || fail "2 workers registered over TLS"
grpc_healthy --ca "$ALIQUOT_SECRETS/ca.pem" && ok "gRPC health answers over TLS with the CA" ||
    fail "gRPC health answers over TLS with the CA"
if "$ALIQUOT" submit --coordinator "$ADDR" "${TLS_ARGS[@]}" --scene cornell-box --resolution 32x32 \
    --spp 8 --out "$TMP/tls.exr" >"$TMP/tls-submit.log" 2>&1 &&
    "$ALIQUOT" render --scene cornell-box --resolution 32x32 --spp 8 --out "$TMP/tls-embedded.exr" \
        >/dev/null 2>&1 && cmp -s "$TMP/tls.exr" "$TMP/tls-embedded.exr"; then
    ok "a render over TLS is byte-identical to aliquot render"
else
    cat "$TMP/tls-submit.log"
    fail "a render over TLS is byte-identical to aliquot render"
fi
if ((HAS_HTTP)); then
    if curl -sS --max-time 5 --cacert "$ALIQUOT_SECRETS/ca.pem" -H "Authorization: Bearer $ALIQUOT_TOKEN" \
        "https://127.0.0.1:$ALIQUOT_HTTP_PORT/healthz" | grep -q '"ok":true'; then
        ok "HTTPS /healthz answers with the CA"
    else
        fail "HTTPS /healthz answers with the CA"
    fi
fi
COMPLETED=1
exit 0
