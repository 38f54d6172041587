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
# Two seeds of one unbiased render: a mean bias within its noise, which is not zero.
python3 - "$cmpjson" <<'PY' && pass "compare --json reports the mean bias and its standard error" || fail "compare --json reports the mean bias and its standard error: $cmpjson"
import json, sys
s = json.loads(sys.argv[1])
assert s["mean_bias_se"] > 0 and abs(s["mean_bias"]) <= 3 * s["mean_bias_se"], s
assert s["bias_beyond_noise"] is False, s
PY
"$aliquot" compare "$tmp/a1.exr" "$tmp/b.exr" | grep -Eq '^mean bias +[-+][0-9.e-]+ % ± [0-9.e-]+ %, within 3 SE$' &&
    pass "compare prints the mean bias beside E" || fail "compare prints the mean bias beside E"

# Each bad input: exactly one line on stderr that names the problem, and the exit status
# that says whose fault it is: 2 for a command line that cannot be right (usage), 1 for one
# that failed while running (a missing file, a coordinator that does not answer).
expect_error() {
    local name=$1 code=$2 pattern=$3
    shift 3
    local err status
    err=$("$@" 2>&1 >/dev/null)
    status=$?
    if [[ $status -eq $code && $(printf '%s\n' "$err" | wc -l) -eq 1 && $err == *$pattern* ]]; then
        pass "$name"
    else
        fail "$name (status $status, expected $code, stderr: $err)"
    fi
}
mkdir -p "$tmp/ro"
echo '{"camera": ' > "$tmp/broken.json"
expect_error "missing scene file" 1 "cannot open" "$aliquot" render --scene "$tmp/nope.json" --out "$tmp/x.exr"
expect_error "unknown built-in scene" 2 "unknown scene" "$aliquot" render --scene cornel-box --out "$tmp/x.exr"
expect_error "malformed scene file" 1 "broken.json" "$aliquot" render --scene "$tmp/broken.json" --out "$tmp/x.exr"
expect_error "resolution 0x0" 2 "--resolution" "$aliquot" render --resolution 0x0 --out "$tmp/x.exr"
expect_error "resolution not WxH" 2 "--resolution" "$aliquot" render --resolution 64 --out "$tmp/x.exr"
expect_error "spp 0" 2 "--spp" "$aliquot" render --spp 0 --out "$tmp/x.exr"
expect_error "unknown method" 2 "method" "$aliquot" render --method magic --out "$tmp/x.exr"
expect_error "output directory missing" 1 "does not exist" "$aliquot" render --out "$tmp/no/such/dir/x.exr"
expect_error "output is a directory" 1 "is a directory" "$aliquot" render --out "$tmp/ro"
expect_error "compare with different resolutions" 1 "resolution differs" "$aliquot" compare "$tmp/a1.exr" "$tmp/j.exr"
expect_error "compare with a missing file" 1 "missing.exr" "$aliquot" compare "$tmp/a1.exr" "$tmp/missing.exr"
expect_error "compare with bucket size 0" 2 "--bucket-size" "$aliquot" compare "$tmp/a1.exr" "$tmp/b.exr" --bucket-size 0
expect_error "coordinator with lease 0 s" 2 "--lease-seconds" "$aliquot" coordinator --lease-seconds 0 --data "$tmp/d"
expect_error "coordinator with a bad memory limit" 2 "--memory-limit" "$aliquot" coordinator --memory-limit 3X --data "$tmp/d"
expect_error "a render name with a newline" 2 "--name" "$aliquot" render --name $'a\nb' --out "$tmp/x.exr"
expect_error "a render name of 201 bytes" 2 "at most 200 bytes" "$aliquot" render --name "$(printf 'n%.0s' $(seq 201))" --out "$tmp/x.exr"
expect_error "a submit name with an escape" 2 "control characters" "$aliquot" submit --name $'\e[2J' --coordinator 127.0.0.1:1
expect_error "coordinator with a bad log format" 2 "--log-format" "$aliquot" coordinator --log-format xml --data "$tmp/d"
expect_error "negative connect timeout" 2 "--connect-timeout" "$aliquot" status --connect-timeout -1
expect_error "unknown study scale" 2 "--scale" "$aliquot" study "$(dirname "$0")/../study/tiny.json" --scale huge --out "$tmp/s"
# Nothing listens on port 1: the client waits its connect timeout, then says so.
echo "0123456789abcdef0123456789abcdef" >"$tmp/token"
chmod 600 "$tmp/token"
expect_error "coordinator not answering" 1 "cannot reach coordinator at 127.0.0.1:1" \
    "$aliquot" status --coordinator 127.0.0.1:1 --token-file "$tmp/token" --connect-timeout 0.2
expect_error "ALIQUOT_COORDINATOR names the coordinator" 1 "cannot reach coordinator at 127.0.0.1:2" \
    env ALIQUOT_COORDINATOR=127.0.0.1:2 "$aliquot" status --token-file "$tmp/token" --connect-timeout 0
expect_error "--coordinator wins over ALIQUOT_COORDINATOR" 1 "cannot reach coordinator at 127.0.0.1:3" \
    env ALIQUOT_COORDINATOR=127.0.0.1:2 "$aliquot" status --coordinator 127.0.0.1:3 --token-file "$tmp/token" --connect-timeout 0

# CLI11's own parse errors are usage errors too (it numbers them 100 and up); their
# wording is checked below, with the near-miss suggestions.
"$aliquot" render --no-such-option >/dev/null 2>&1
[[ $? -eq 2 ]] && pass "an unknown option exits 2" || fail "an unknown option exits 2"
"$aliquot" render >/dev/null 2>&1
[[ $? -eq 2 ]] && pass "a missing required option exits 2" || fail "a missing required option exits 2"
"$aliquot" status --connect-timeout soon >/dev/null 2>&1
[[ $? -eq 2 ]] && pass "an option that is not a number exits 2" || fail "an option that is not a number exits 2"
# Integer options are decimal digits: CLI11 alone read -1 as 2^64-1, 010 as 8, 0x10 as 16
# and clamped an overflow, silently.
for bad in "--seed -1" "--seed 010" "--seed 0x10" "--seed 18446744073709551616" \
    "--threads -1" "--spp -4" "--budget -1"; do
    # shellcheck disable=SC2086 # the option and its value are two words
    err=$("$aliquot" render $bad --out "$tmp/x.exr" 2>&1 >/dev/null)
    status=$?
    [[ $status -eq 2 && $err == *"${bad%% *}: expected a whole number"* ]] &&
        pass "render $bad exits 2" || fail "render $bad exits 2 (status $status: $err)"
done
"$aliquot" worker --threads -2 >/dev/null 2>&1
[[ $? -eq 2 ]] && pass "worker --threads -2 exits 2" || fail "worker --threads -2 exits 2"
version=$("$aliquot" --version)
[[ $? -eq 0 && $version =~ ^aliquot\ [0-9]+\.[0-9]+\.[0-9]+$ ]] && pass "--version prints the version" ||
    fail "--version prints the version (got: $version)"

# An --aovs EXR as a tool reads it: OpenImageIO (Debian's openimageio-tools, installed by
# scripts/install-deps.sh) lists the two layers and the render's spec, and the file is
# still the same bytes for the same seed.
render --seed 18446744073709551615 --aovs --out "$tmp/aov1.exr"
render --seed 18446744073709551615 --aovs --threads 1 --out "$tmp/aov2.exr"
cmp -s "$tmp/aov1.exr" "$tmp/aov2.exr" && pass "an --aovs EXR is the same bytes for the same seed" ||
    fail "an --aovs EXR is the same bytes for the same seed"
if info=$(oiiotool --info -v "$tmp/aov1.exr" 2>&1); then
    python3 - "$info" <<'PY' && pass "oiiotool lists the layers and the spec" || fail "oiiotool lists the layers and the spec: $info"
import re, sys
info = sys.argv[1]
channels = re.search(r"channel list: (.*)", info).group(1).split(", ")
assert channels == ["R", "G", "B", "sampleCount.Y", "variance.Y"], channels
attrs = dict(re.findall(r'^\s*(aliquot:\w+): "(.*)"$', info, re.M))
assert attrs["aliquot:seed"] == "18446744073709551615", attrs
assert attrs["aliquot:method"] == "uniform" and attrs["aliquot:samples"] == str(40 * 30 * 8), attrs
assert attrs["aliquot:budget"] == str(40 * 30 * 8) and len(attrs["aliquot:sceneHash"]) == 32, attrs
assert '"spp":8' in attrs["aliquot:strategy"], attrs
PY
else
    fail "oiiotool --info -v runs (install openimageio-tools: scripts/install-deps.sh): $info"
fi

# --denoise (issue 34): a layer denoised.R/G/B made by Open Image Denoise from the colour and
# the render's first hits, the same bytes for the same seed on 1 and 2 threads; compare
# measures it beside the raw figures, or denoises A itself with --denoise. Without the
# library (scripts/install-deps.sh puts it in .venv) these are skipped, loudly, unless
# ALIQUOT_REQUIRE_OIDN is set (scripts/test.sh), and the error is one line naming the fix.
expect_error "render --denoise without the library" 1 "scripts/install-deps.sh" \
    env ALIQUOT_OIDN_LIBRARY="$tmp/none/libOpenImageDenoise.so.2" \
    "$aliquot" render --resolution 8x8 --spp 1 --denoise --out "$tmp/x.exr"
if denoise_err=$(render --seed 9 --denoise --out "$tmp/dn1.exr" 2>&1); then
    render --seed 9 --denoise --threads 1 --out "$tmp/dn2.exr"
    cmp -s "$tmp/dn1.exr" "$tmp/dn2.exr" && pass "a --denoise EXR is the same bytes for the same seed" ||
        fail "a --denoise EXR is the same bytes for the same seed"
    info=$(oiiotool --info -v "$tmp/dn1.exr" 2>&1)
    [[ $info == *"channel list: R, G, B, denoised.R, denoised.G, denoised.B"* &&
        $info == *"with first-hit albedo and normal"* ]] &&
        pass "--denoise adds the layer denoised.R/G/B, made with albedo and normal" ||
        fail "--denoise adds the layer denoised.R/G/B, made with albedo and normal: $info"
    "$aliquot" render --scene cornell-box --resolution 40x30 --spp 64 --seed 1 \
        --out "$tmp/ref64.exr" >/dev/null
    layer=$("$aliquot" compare "$tmp/dn1.exr" "$tmp/ref64.exr" --json)
    asked=$("$aliquot" compare "$tmp/a1.exr" "$tmp/ref64.exr" --json --denoise)
    plain=$("$aliquot" compare "$tmp/a1.exr" "$tmp/ref64.exr" --json)
    python3 - "$layer" "$asked" "$plain" <<'PY' && pass "compare reports E, RMSE, relMSE after denoising" || fail "compare reports E, RMSE, relMSE after denoising: $layer / $asked / $plain"
import json, sys
layer, asked, plain = (json.loads(a) for a in sys.argv[1:])
for s in (layer, asked):
    d = s["denoised"]
    assert d["mean_abs"] > 0 and d["rmse"] > 0 and d["relative_mse"] > 0, s
# 8 spp denoised is nearer the reference than raw: OIDN did denoise. (Not asserted of the
# layer made with albedo and normal: how much they help depends on the tracer's first hits.)
assert asked["denoised"]["mean_abs"] < asked["mean_abs"], asked
assert layer["denoised"]["source"] == "layer denoised.R/G/B", layer
assert asked["denoised"]["source"] == "Open Image Denoise, colour only", asked
assert "denoised" not in plain, plain
PY
elif [[ -z ${ALIQUOT_REQUIRE_OIDN:-} && $denoise_err == *"not found"* ]]; then
    echo "*** SKIPPING the --denoise checks: Open Image Denoise is not installed ***"
    echo "$denoise_err"
else
    fail "render --denoise: $denoise_err"
fi

# --png: an 8-bit sRGB PNG beside the EXR, the render's size, brighter with --exposure.
# png_size FILE: "WIDTHxHEIGHT" from the IHDR chunk after PNG's 8-byte signature.
png_size() {
    python3 - "$1" <<'PY'
import struct, sys
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n", "no PNG signature"
assert data[12:16] == b"IHDR", "no IHDR first"
w, h, depth, colour = struct.unpack(">IIBB", data[16:26])
assert depth == 8 and colour == 2, (depth, colour)  # 8-bit RGB
print(f"{w}x{h}")
PY
}
out=$("$aliquot" render --scene cornell-box --resolution 40x30 --spp 4 --seed 3 --png \
    --out "$tmp/p.exr" 2>/dev/null)
[[ $(png_size "$tmp/p.png") == 40x30 && $out == *"wrote $tmp/p.png"* ]] &&
    pass "render --png writes a 40x30 PNG beside the EXR and says where" ||
    fail "render --png writes a 40x30 PNG beside the EXR and says where (stdout: $out)"
"$aliquot" render --scene cornell-box --resolution 40x30 --spp 4 --seed 3 --png --exposure 2 \
    --out "$tmp/bright.exr" >/dev/null 2>&1
cmp -s "$tmp/p.exr" "$tmp/bright.exr" && ! cmp -s "$tmp/p.png" "$tmp/bright.png" &&
    pass "--exposure changes the PNG, not the EXR" || fail "--exposure changes the PNG, not the EXR"
expect_error "--exposure without --png" 2 "--exposure requires --png" \
    "$aliquot" render --exposure 1 --out "$tmp/x.exr"
expect_error "--exposure out of range" 2 "--exposure: must be -20..20" \
    "$aliquot" render --png --exposure 99 --out "$tmp/x.exr"
expect_error "--png over an --out named .png" 2 "--png: --out" \
    "$aliquot" render --png --out "$tmp/x.png"
expect_error "submit --png without --out" 2 "--png: needs --out" \
    "$aliquot" submit --png --coordinator 127.0.0.1:1 --connect-timeout 0

# Usage errors read alike, whoever found them: "aliquot: ", one line, exit status 2, and
# the nearest known word for a near miss.
expect_error "a mistyped command" 2 "aliquot: unknown command 'rendr'; did you mean 'render'?" \
    "$aliquot" rendr --out "$tmp/x.exr"
expect_error "a command swapped two letters" 2 "did you mean 'status'?" "$aliquot" stauts
expect_error "no command" 2 "aliquot: a command is required: render" "$aliquot"
expect_error "an unknown top-level option" 2 "aliquot: unknown option --frob" "$aliquot" --frob
expect_error "a mistyped option" 2 "aliquot: render: unknown option --spd; did you mean --spp?" \
    "$aliquot" render --spd 3 --out "$tmp/x.exr"
expect_error "CLI11's missing option" 2 "aliquot: render: --out is required" "$aliquot" render
expect_error "CLI11's conversion error" 2 "aliquot: status: " "$aliquot" status --connect-timeout soon
expect_error "a stray argument" 2 "aliquot: render: unexpected argument 'foo'" \
    "$aliquot" render foo --out "$tmp/x.exr"
expect_error "an unknown scene is a usage error, with the near name" 2 \
    "--scene: unknown scene 'cornel-box'; did you mean 'cornell-box'?" \
    "$aliquot" render --scene cornel-box --out "$tmp/x.exr"
# An image larger than the memory a render may use: refused in render's words, before
# any work; the farm's --memory-limit is no option of render.
err=$("$aliquot" render --resolution 8192x8192 --spp 1 --out "$tmp/x.exr" 2>&1 >/dev/null)
status=$?
[[ $status -eq 1 && $err == "aliquot: --resolution 8192x8192: "*"choose a smaller --resolution" &&
    $err != *memory-limit* ]] && pass "a render too large for memory names --resolution, not --memory-limit" ||
    fail "a render too large for memory names --resolution, not --memory-limit (status $status: $err)"
# Every method that needs a budget gets uniform's default, 64 samples per pixel.
json=$("$aliquot" render --method optimal --resolution 8x8 --out "$tmp/o.exr" --json 2>/dev/null)
python3 -c 'import json, sys; s = json.loads(sys.argv[1]); assert s["samples_done"] == 64 * 64, s' "$json" &&
    pass "optimal without --spp or --budget renders 64 samples per pixel" ||
    fail "optimal without --spp or --budget renders 64 samples per pixel ($json)"

# Strategy parameters: one table makes the flags, the spec's JSON and the bounds. The
# flags --help groups under the methods are the keys of the spec an EXR carries (read
# by oiiotool), each with its default shown; a value out of bounds names the bound; a
# parameter for another method is refused, not ignored.
help=$("$aliquot" render --help)
spec=$(oiiotool --info -v "$tmp/aov1.exr" 2>/dev/null | sed -n 's/^ *aliquot:strategy: "\(.*\)"$/\1/p')
flags_test="render's parameter flags are the spec's keys, grouped by method"
python3 - "$help" "$spec" <<'PY' && pass "$flags_test" || fail "$flags_test"
import json, re, sys
help, spec = sys.argv[1], json.loads(sys.argv[2].replace('\\"', '"'))
groups = re.split(r"\n\n+(?=\S)", help)
flags = set()
for g in groups:
    if g.startswith("Budget and caps") or g.startswith("Parameters of"):
        for flag, default in re.findall(r"^  (--[a-z-]+) \S+?=(\S+)", g, re.M):
            flags.add(flag)
keys = {"--" + k.replace("_", "-") for k in spec if k != "method"}
assert flags == keys, (sorted(flags ^ keys))
assert "Parameters of cycles:" in help and "Parameters of dammertz:" in help, help
PY
expect_error "a parameter above its bound names the bound" 2 \
    "--sigma-radius: must be a whole number from 0 to 64, got 65" \
    "$aliquot" render --method optimal --sigma-radius 65 --out "$tmp/x.exr"
expect_error "a number parameter out of bounds names the bound" 2 \
    "--floor-fraction: must be a number at least 0 and below 1, got 1" \
    "$aliquot" render --method optimal --floor-fraction 1 --out "$tmp/x.exr"
expect_error "a word parameter names its values" 2 "--error-norm: must be seed or paper" \
    "$aliquot" render --method dammertz --error-norm l2 --out "$tmp/x.exr"
expect_error "a parameter of another method is refused" 2 \
    "--alpha: only adaptive reads it, not --method optimal" \
    "$aliquot" render --method optimal --alpha 2 --out "$tmp/x.exr"

# A study whose report finds no python3 with matplotlib and numpy (the report module exits
# 3, as aliquot_report.py does then) names the project's installer, not pip, which Debian's
# python3 refuses.
echo 'import sys; sys.exit(3)' >"$tmp/lacks_modules.py"
err=$(ALIQUOT_REPORT="$tmp/lacks_modules.py" ALIQUOT_CACHE="$tmp/cache" "$aliquot" study \
    "$(dirname "$0")/../study/tiny.json" --out "$tmp/study" --threads 2 2>&1 >/dev/null)
status=$?
[[ $status -eq 1 && $err == *"aliquot: report not written: "*"run scripts/install-deps.sh"* &&
    $err != *pip* ]] && pass "a study report without matplotlib names scripts/install-deps.sh" ||
    fail "a study report without matplotlib names scripts/install-deps.sh (status $status: $err)"

# A small farm on a free port: fetch --png, and a client without a token.
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
addr=127.0.0.1:$port
"$aliquot" coordinator --grpc "$addr" --data "$tmp/farm" >"$tmp/coordinator.log" 2>&1 &
coordinator_pid=$!
worker_pid=
trap 'kill $coordinator_pid $worker_pid 2>/dev/null; wait 2>/dev/null; rm -rf "$tmp"' EXIT
for _ in $(seq 100); do [[ -s $tmp/farm/worker.token ]] && break; sleep 0.1; done
"$aliquot" worker --coordinator "$addr" --token-file "$tmp/farm/worker.token" --threads 1 \
    >"$tmp/worker.log" 2>&1 &
worker_pid=$!
id=$(timeout 120 "$aliquot" submit --coordinator "$addr" --token-file "$tmp/farm/client.token" \
    --scene cornell-box --resolution 24x16 --spp 4 --out "$tmp/s.exr" --png --json 2>/dev/null |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["id"])')
[[ -s $tmp/s.exr && $(png_size "$tmp/s.png") == 24x16 ]] &&
    pass "submit --out --png writes a 24x16 PNG beside the EXR" ||
    fail "submit --out --png writes a 24x16 PNG beside the EXR"
out=$("$aliquot" fetch "$id" --coordinator "$addr" --token-file "$tmp/farm/client.token" \
    --out "$tmp/f.exr" --png 2>&1)
[[ -n $id && -s $tmp/f.exr && $(png_size "$tmp/f.png") == 24x16 && $out == *"wrote $tmp/f.png"* ]] &&
    pass "fetch --png writes a 24x16 PNG beside the EXR" ||
    fail "fetch --png writes a 24x16 PNG beside the EXR (id '$id': $out)"
# In a directory without aliquot-data/: the coordinator answers, so its token is elsewhere
# and waiting for one to appear here is pointless. Before, the client waited out its
# whole --connect-timeout and then said only "no client token".
mkdir -p "$tmp/elsewhere"
expect_error "a client without a token next to a running coordinator says so at once" 1 \
    "no client token: the coordinator at $addr answers" \
    env -C "$tmp/elsewhere" -u ALIQUOT_TOKEN "$(realpath "$aliquot")" status --coordinator "$addr" --connect-timeout 60

# Issue 32: a render's events, its name in status, and the queue while no worker runs.
client=(--coordinator "$addr" --token-file "$tmp/farm/client.token")
logs=$("$aliquot" logs "$id" "${client[@]}" 2>&1)
[[ $logs == *" submitted render=$id "* && $logs == *" started render=$id"* &&
    $logs == *" round_ended render=$id round=0 "* && $logs == *" finished render=$id "* ]] &&
    pass "logs prints a render's events from submitted to finished" ||
    fail "logs prints a render's events from submitted to finished ($logs)"
grep -q "worker_registered worker=" "$tmp/coordinator.log" && grep -q " round_ended render=$id " "$tmp/coordinator.log" &&
    pass "the coordinator logs worker and render events on stderr" ||
    fail "the coordinator logs worker and render events on stderr ($(head -c 600 "$tmp/coordinator.log"))"
expect_error "logs of an unknown render" 1 "no render r-999999" "$aliquot" logs r-999999 "${client[@]}"
kill $worker_pid 2>/dev/null
wait $worker_pid 2>/dev/null
worker_pid=
a=$("$aliquot" submit "${client[@]}" --resolution 8x8 --spp 1 --name "shot 1")
b=$("$aliquot" submit "${client[@]}" --resolution 8x8 --spp 1)
sa=$("$aliquot" status "$a" "${client[@]}")
sb=$("$aliquot" status "$b" "${client[@]}")
[[ $sa == *"queued (position 1)"*"name: shot 1"* && $sb == *"queued (position 2)"* ]] &&
    pass "status shows queued renders with their place and name" ||
    fail "status shows queued renders with their place and name ($sa / $sb)"
"$aliquot" priority "$b" 5 "${client[@]}" >/dev/null
sa=$("$aliquot" status "$a" "${client[@]}")
sb=$("$aliquot" status "$b" "${client[@]}")
[[ $sa == *"queued (position 2)"* && $sb == *"queued (position 1)"* ]] &&
    pass "a priority change moves a queued render to the front" ||
    fail "a priority change moves a queued render to the front ($sa / $sb)"
json=$("$aliquot" status "$b" "${client[@]}" --json)
python3 - "$json" <<'PY' && pass "status --json has state queued and queue_position" || fail "status --json has state queued and queue_position ($json)"
import json, sys
s = json.loads(sys.argv[1])
assert s["state"] == "queued" and s["queue_position"] == 1 and s["name"] == "", s
PY

# Review of issue 33: a client command that fails says in one line what failed and what
# to do, never gRPC core's own lines ("E1204 ... Handshake failed ...", one per retry),
# and exits 1: a token the coordinator does not know, the worker token, TLS on one side
# only, a CA that did not sign the certificate, a coordinator that goes away.
for cmd in "status" "status $a" "watch $a" "logs $a" "logs $a --follow" "cancel $a" \
    "fetch $a --out $tmp/w.exr" "submit --resolution 8x8 --spp 1" "workers" "priority $a 1" "delete $a"; do
    # shellcheck disable=SC2086 # the command and its arguments are words
    expect_error "$cmd with a token the coordinator does not know" 1 \
        "the coordinator at $addr does not accept this token; this call needs the client token: pass the client.token" \
        "$aliquot" $cmd --coordinator "$addr" --token-file "$tmp/token"
done
expect_error "status with the worker token" 1 "refused the worker token; this call needs the client token" \
    "$aliquot" status --coordinator "$addr" --token-file "$tmp/farm/worker.token"
expect_error "a coordinator nobody runs" 1 "127.0.0.1:1 (status) after waiting 0.2 s (--connect-timeout): nothing listens there; start the coordinator" \
    "$aliquot" status --coordinator 127.0.0.1:1 --token-file "$tmp/token" --connect-timeout 0.2
if command -v openssl >/dev/null; then
    ca() {
        openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 \
            -subj "/CN=aliquot cli test $1" -keyout "$tmp/$1.key" -out "$tmp/$1.pem" 2>/dev/null
    }
    ca ca && ca other-ca &&
        openssl req -new -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj "/CN=coordinator" \
            -keyout "$tmp/server.key" -out "$tmp/server.csr" 2>/dev/null &&
        printf '%s\n' 'subjectAltName = IP:127.0.0.1' 'extendedKeyUsage = serverAuth' >"$tmp/server.ext" &&
        openssl x509 -req -in "$tmp/server.csr" -CA "$tmp/ca.pem" -CAkey "$tmp/ca.key" -CAcreateserial \
            -days 2 -extfile "$tmp/server.ext" -out "$tmp/server.pem" 2>/dev/null
    expect_error "status with --tls-ca against a plaintext coordinator" 1 \
        "$addr (status) after waiting 1.0 s (--connect-timeout): it does not serve TLS; drop --tls-ca" \
        "$aliquot" status "${client[@]}" --tls-ca "$tmp/ca.pem" --connect-timeout 1
    tls_port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    tls_addr=127.0.0.1:$tls_port
    "$aliquot" coordinator --grpc "$tls_addr" --data "$tmp/tls-farm" --tls-cert "$tmp/server.pem" \
        --tls-key "$tmp/server.key" >"$tmp/tls-coordinator.log" 2>&1 &
    tls_pid=$!
    trap 'kill $coordinator_pid $worker_pid $tls_pid 2>/dev/null; wait 2>/dev/null; rm -rf "$tmp"' EXIT
    tls_client=(--coordinator "$tls_addr" --token-file "$tmp/tls-farm/client.token")
    for _ in $(seq 100); do
        "$aliquot" status "${tls_client[@]}" --tls-ca "$tmp/ca.pem" --connect-timeout 0.2 >/dev/null 2>&1 && break
        sleep 0.1
    done
    expect_error "status without --tls-ca against a TLS coordinator" 1 \
        "$tls_addr (status) after waiting 1.0 s (--connect-timeout); if the coordinator serves TLS (--tls-cert), pass --tls-ca with its CA" \
        "$aliquot" status "${tls_client[@]}" --connect-timeout 1
    expect_error "status trusting another CA" 1 \
        "its TLS certificate is not signed by the --tls-ca CA or not issued for this address" \
        "$aliquot" status "${tls_client[@]}" --tls-ca "$tmp/other-ca.pem" --connect-timeout 1
    # A coordinator that goes away under `logs --follow` (a queued render: no worker here).
    queued=$("$aliquot" submit "${tls_client[@]}" --tls-ca "$tmp/ca.pem" --resolution 8x8 --spp 1)
    timeout 60 "$aliquot" logs "$queued" --follow "${tls_client[@]}" --tls-ca "$tmp/ca.pem" \
        >"$tmp/follow.out" 2>"$tmp/follow.err" &
    follow_pid=$!
    for _ in $(seq 100); do grep -q submitted "$tmp/follow.out" && break; sleep 0.1; done
    kill $tls_pid
    wait $tls_pid 2>/dev/null
    wait $follow_pid
    status=$?
    err=$(cat "$tmp/follow.err")
    [[ $status -eq 1 && $(wc -l <"$tmp/follow.err") -eq 1 &&
        $err == *"the coordinator at $tls_addr stopped answering (logs $queued); is it still running?"* ]] &&
        pass "logs --follow says in one line that its coordinator stopped answering" ||
        fail "logs --follow says in one line that its coordinator stopped answering (status $status: $err)"
else
    fail "openssl is needed for the TLS cases (scripts/install-deps.sh)"
fi

echo "$passed passed, $failed failed"
[[ $failed -eq 0 ]]
