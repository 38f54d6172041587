#!/usr/bin/env bash
# Web end-to-end test: installs what it needs (Debian's chromium, playwright-core from this
# folder's lock file, the built dashboard), then runs e2e.mjs against a real coordinator and
# worker. Screenshots and logs go to build/web-e2e (beside the binary's bin/).
# Usage: tests/web/run.sh [path/to/aliquot]
set -euo pipefail
aliquot=$(realpath "${1:-build/bin/aliquot}")
here=$(cd "$(dirname "$0")" && pwd)
out=${WEB_E2E_OUT:-$(dirname "$(dirname "$aliquot")")/web-e2e}

if [[ ! -x /usr/bin/chromium ]]; then
    echo "installing chromium" >&2
    sudo_cmd=()
    [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
    "${sudo_cmd[@]}" apt-get update -qq
    DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq chromium
fi

# The dashboard's build script fails loudly, with npm's own words (a stand-in npm).
bash "$here/build_script_test.sh"
bash "$here/../../web/build.sh"

cd "$here"
if [[ ! -f node_modules/.package-lock.json || package-lock.json -nt node_modules/.package-lock.json ]]; then
    PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --no-audit --no-fund --loglevel=error
fi
exec node e2e.mjs "$aliquot" "$out"
