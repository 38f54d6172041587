#!/usr/bin/env bash
# The render and compare commands as a user runs them: determinism of the output bytes and
# one clear line for every kind of bad input. Usage: render_test.sh [path/to/aliquot]
set -uo pipefail
aliquot=${1:-build/bin/aliquot}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
passed=0 failed=0

pass() { passed=$((passed + 1)); echo "ok   $1"; }
fail() { failed=$((failed + 1)); echo "FAIL $1"; }

render() { "$aliquot" render --scene cornell-box --resolution 40x30 --spp 8 "$@" >/dev/null; }

render --seed 3 --threads 1 --out "$tmp/a1.exr"
render --seed 3 --threads 1 --out "$tmp/a2.exr"
render --seed 3 --threads 2 --out "$tmp/a3.exr"
render --seed 4 --threads 2 --out "$tmp/b.exr"
cmp -s "$tmp/a1.exr" "$tmp/a2.exr" && pass "same seed gives identical bytes" || fail "same seed gives identical bytes"
cmp -s "$tmp/a1.exr" "$tmp/a3.exr" && pass "1 and 2 threads give identical bytes" || fail "1 and 2 threads give identical bytes"
cmp -s "$tmp/a1.exr" "$tmp/b.exr" && fail "a different seed gives a different image" || pass "a different seed gives a different image"

json=$("$aliquot" render --scene cornell-box --resolution 8x8 --spp 2 --out "$tmp/j.exr" --json)
python3 - "$json" <<'PY' && pass "render --json prints the summary" || fail "render --json prints the summary"
import json, sys
s = json.loads(sys.argv[1])
assert s["samples_done"] == 128 and s["seconds"] > 0 and s["samples_per_second"] > 0, s
assert s["state"] == "done" and s["progress"] == 1 and s["rounds"] >= 1, s
assert s["scene"] == "cornell-box" and s["width"] == 8 and s["spp"] == 2, s
assert s["output"].endswith("j.exr"), s
PY

cmpjson=$("$aliquot" compare "$tmp/a1.exr" "$tmp/b.exr" --json)
python3 - "$cmpjson" <<'PY' && pass "compare --json reports E, RMSE and relMSE" || fail "compare --json reports E, RMSE and relMSE"
import json, sys
s = json.loads(sys.argv[1])
assert s["mean_abs"] > 0 and s["rmse"] >= s["mean_abs"] and s["relative_mse"] > 0, s
PY

# Each bad input: non-zero exit and exactly one line on stderr that names the problem.
expect_error() {
    local name=$1 pattern=$2
    shift 2
    local err status
    err=$("$@" 2>&1 >/dev/null)
    status=$?
    if [[ $status -ne 0 && $(printf '%s\n' "$err" | wc -l) -eq 1 && $err == *$pattern* ]]; then
        pass "$name"
    else
        fail "$name (status $status, stderr: $err)"
    fi
}
mkdir -p "$tmp/ro"
echo '{"camera": ' > "$tmp/broken.json"
expect_error "missing scene file" "cannot open" "$aliquot" render --scene "$tmp/nope.json" --out "$tmp/x.exr"
expect_error "unknown built-in scene" "unknown scene" "$aliquot" render --scene cornel-box --out "$tmp/x.exr"
expect_error "malformed scene file" "broken.json" "$aliquot" render --scene "$tmp/broken.json" --out "$tmp/x.exr"
expect_error "resolution 0x0" "--resolution" "$aliquot" render --resolution 0x0 --out "$tmp/x.exr"
expect_error "resolution not WxH" "--resolution" "$aliquot" render --resolution 64 --out "$tmp/x.exr"
expect_error "spp 0" "--spp" "$aliquot" render --spp 0 --out "$tmp/x.exr"
expect_error "output directory missing" "does not exist" "$aliquot" render --out "$tmp/no/such/dir/x.exr"
expect_error "output is a directory" "is a directory" "$aliquot" render --out "$tmp/ro"
expect_error "compare with different resolutions" "resolution differs" "$aliquot" compare "$tmp/a1.exr" "$tmp/j.exr"
expect_error "compare with a missing file" "missing.exr" "$aliquot" compare "$tmp/a1.exr" "$tmp/missing.exr"

echo "$passed passed, $failed failed"
[[ $failed -eq 0 ]]
