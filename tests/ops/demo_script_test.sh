#!/usr/bin/env bash
# scripts/demo.sh stops at the first step that fails, names it and exits 1 (issue 32): runs
# a copy of demo.sh and install-deps.sh with stand-ins for the tools each step calls
# (dpkg-query, apt-get, cmake, the built binary), each failing when told; well under a second.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/scripts" "$tmp/bin"
cp "$here/../../scripts/demo.sh" "$here/../../scripts/install-deps.sh" "$tmp/scripts/"
# The stand-ins: each prints what it was asked and fails when its name is in DEMO_FAILS.
# dpkg-query finds nothing installed, so install-deps.sh calls apt-get (and sudo, when not
# root); cmake's --build (failing alone as cmake--build) writes the binary the render step runs.
for tool in dpkg-query apt-get sudo cmake; do
    cat >"$tmp/bin/$tool" <<'STUB'
#!/usr/bin/env bash
name=$(basename "$0")
echo "stand-in $name $*" >&2
[[ " $DEMO_FAILS " == *" $name "* ]] && exit 3
if [[ $name == sudo ]]; then exec "$@"; fi
if [[ $name == cmake && $1 == --build ]]; then
    [[ " $DEMO_FAILS " == *" cmake--build "* ]] && exit 5
    mkdir -p build/bin
    printf '#!/usr/bin/env bash\necho "stand-in aliquot $*" >&2\n[[ " $DEMO_FAILS " == *" aliquot "* ]] && exit 4\nexit 0\n' >build/bin/aliquot
    chmod +x build/bin/aliquot
fi
exit 0
STUB
    chmod +x "$tmp/bin/$tool"
done
failed=0
expect() { # what, DEMO_FAILS, expected status, words the output must hold...
    local what=$1 fails=$2 want=$3
    shift 3
    rm -rf "$tmp/build" "$tmp/out"
    local out status=0
    out=$(cd "$tmp" && PATH="$tmp/bin:$PATH" DEMO_FAILS=$fails bash scripts/demo.sh 2>&1) || status=$?
    local ok=1
    [[ $status == "$want" ]] || ok=0
    for word in "$@"; do
        if [[ $word == !* ]]; then
            [[ $out != *"${word#!}"* ]] || ok=0
        else
            [[ $out == *"$word"* ]] || ok=0
        fi
    done
    if ((ok)); then
        echo "PASS $what"
    else
        echo "FAIL $what: status $status, output: $out"
        failed=1
    fi
}
expect "apt-get fails: the install step is named, nothing after it runs" "apt-get" 1 \
    "step 'install the build packages" "!stand-in cmake"
expect "configure fails: named, the build does not run" "cmake" 1 \
    "step 'configure (cmake)' failed (exit status 3)" "!--build"
expect "the build fails: named, the render does not run" "cmake--build" 1 \
    "step 'build the aliquot binary' failed (exit status 5)" "!stand-in aliquot"
expect "the render fails: named, no output line" "aliquot" 1 \
    "step 'render the Cornell box' failed (exit status 4)" "!output:"
expect "every step works: status 0 and where the images are" "" 0 \
    "output: out/cornell-box.exr" "out/cornell-box.png"
exit $failed
