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

if [[ ! -f node_modules/.package-lock.json || package-lock.json -nt node_modules/.package-lock.json ]]; then
    # Some npm 11 releases refuse `npm ci` on this lock file, reporting rollup's optional
    # per-platform packages as missing although they are in it; `npm install` then installs
    # the same locked versions.
    npm ci --no-audit --no-fund --loglevel=error 2>/dev/null ||
        npm install --no-audit --no-fund --loglevel=error
fi

stamp=dist/index.html
if [[ -f $stamp ]] && [[ -z $(find index.html src package.json package-lock.json vite.config.ts \
        tsconfig.json -newer "$stamp" -print -quit) ]]; then
    exit 0
fi
npm run --silent build
