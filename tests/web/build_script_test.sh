#!/usr/bin/env bash
# web/build.sh fails loudly (issue 32): npm's own error reaches the terminal, the script
# exits non-zero and says the dashboard is not built. Runs build.sh on a copy of web/'s
# package files with a stand-in npm that fails as told; takes well under a second.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/web" "$tmp/bin"
cp "$here/../../web/build.sh" "$here/../../web/package.json" "$here/../../web/package-lock.json" "$tmp/web/"
# The stand-in: prints what a failing npm prints, fails the commands named in NPM_FAILS.
cat > "$tmp/bin/npm" <<'STUB'
#!/usr/bin/env bash
echo "npm error code E_STUB_$1 (npm $*)" >&2
[[ " $NPM_FAILS " == *" $1 "* ]] && exit 1
[[ $1 == run ]] && { mkdir -p dist && echo "<title>Aliquot</title>" > dist/index.html; }
[[ $1 == ci || $1 == install ]] && { mkdir -p node_modules && touch node_modules/.package-lock.json; }
exit 0
STUB
chmod +x "$tmp/bin/npm"
failed=0
expect() { # what, NPM_FAILS, expected status, words the output must hold...
    local what=$1 fails=$2 want=$3
    shift 3
    rm -rf "$tmp/web/node_modules" "$tmp/web/dist"
    local out status=0
    out=$(cd "$tmp/web" && PATH="$tmp/bin:$PATH" NPM_FAILS=$fails bash build.sh 2>&1) || status=$?
    local ok=1
    [[ $status == "$want" ]] || ok=0
    for word in "$@"; do [[ $out == *"$word"* ]] || ok=0; done
    if ((ok)); then
        echo "PASS $what"
    else
        echo "FAIL $what: status $status, output: $out"
        failed=1
    fi
}
expect "npm ci and install both fail: npm's errors shown, status 1" "ci install" 1 \
    E_STUB_ci E_STUB_install "the dashboard is not built"
expect "npm ci fails, install works: built, ci's error still shown" "ci" 0 E_STUB_ci "trying npm install"
expect "the build fails: status 1, named" "run" 1 E_STUB_run "npm run build failed"
expect "all works: status 0" "" 0
exit $failed
