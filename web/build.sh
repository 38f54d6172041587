#!/usr/bin/env bash
# Builds the dashboard into web/dist (what `aliquot coordinator --http` serves). Installs the
# locked npm packages when they are missing or the lock file changed, and rebuilds only when
# a source is newer than the last build, so running it again costs a few milliseconds.
set -euo pipefail
cd "$(dirname "$0")"

if ! command -v npm >/dev/null 2>&1; then
    echo "web/build.sh: npm not found; the dashboard is not built (scripts/install-deps.sh installs it)" >&2
    exit 1
fi

fail() {
    echo "web/build.sh: $*; the dashboard is not built" >&2
    exit 1
}

if [[ ! -f node_modules/.package-lock.json || package-lock.json -nt node_modules/.package-lock.json ]]; then
    # Some npm 11 releases refuse `npm ci` on this lock file, reporting rollup's optional
    # per-platform packages as missing although they are in it; `npm install` then installs
    # the same locked versions. npm's own words are shown either way: a network or
    # registry failure must be readable where it happened.
    if ! npm ci --no-audit --no-fund --loglevel=error; then
        echo "web/build.sh: npm ci failed (above); trying npm install with the same lock file" >&2
        npm install --no-audit --no-fund --loglevel=error || fail "npm install failed (above)"
    fi
fi

stamp=dist/index.html
if [[ -f $stamp ]] && [[ -z $(find index.html src package.json package-lock.json vite.config.ts \
        tsconfig.json -newer "$stamp" -print -quit) ]]; then
    exit 0
fi
npm run --silent build || fail "npm run build failed (above)"
[[ -f $stamp ]] || fail "the build wrote no $stamp"
