#!/usr/bin/env python3
"""Samples/s and noise per sample against Mitsuba 3 llvm_ad_rgb where a pixel gets few
samples and where it gets many (issue 31), every case in one interleaved run.

  python3 bench/spp_regimes.py [--aliquot build/bin/aliquot] [--before OLD/aliquot]
        [--methods uniform optimal ... | all] [--repeat 3] [--threads 2]
        [--cases SCENE:WxH:SPP ...] [--reference-factor 64] [--reference-spp-max 4096]
        [--out-dir build/validation] [--no-install]

Default cases: cornell-box and cornell-caustics at 1024x1024 4 spp, 512x512 16 spp and
256x256 64 spp (the same 4.2 M samples each: only the samples a pixel gets changes), and
cornell-box at 1920x1080 16 spp. Mitsuba renders its film at each case's size (both
renderers take the field of view along the smaller axis, so the images are the same);
its LLVM variant splits a render into passes of at most 2^23 samples
(tests/validation/mitsuba_cornell.py), so 1920x1080 16 spp is 4 passes of 4 spp over
the whole film, their render times added.

Methods (--methods, default uniform; `all` is every method `aliquot render --help` lists
but oracle, which needs a separate sigma render): ours renders each case with each
method, the case's spp then being a steered method's budget (spp x pixels); Mitsuba
stays uniform at the case's spp. A method's samples/s is the samples it actually traced
over its render seconds, and its noise is compared per sample: noise x sqrt(samples),
ours over Mitsuba's, so that efficiency = speed ratio / noise ratio^2 is
(E_Mitsuba^2 t_Mitsuba) / (E_ours^2 t_ours) whatever the sample counts.

Before and after (--before, a second aliquot binary): every method of every case is also
rendered by that binary, just before ours, in the same round; its ratios against the
same Mitsuba runs and ours over it (paired: each of our runs over the before run just
ahead of it) are reported beside ours. A method the before binary does not list is
rendered by ours alone.

Interleaved: each of --repeat rounds runs every case as Mitsuba, then (for each method)
the before binary and ours, so a change of the machine's load hits every case and every
renderer alike. Per case, as
bench/peers_speed.py: the best run's samples/s of each (render time only: not start-up,
scene building, JIT warm-up or writing the image), every run listed; the paired ratios
(each of our runs over the Mitsuba run just before it); noise = mean |image - reference|
at equal spp, the noise ratio and the efficiency (speed ratio / noise ratio^2). The
whole process's wall time is recorded beside each render time.

References: a Mitsuba llvm_ad_rgb render of each scene and size at --reference-factor
times the case's spp (at most --reference-spp-max), made before any timing and cached
under --out-dir under the same names as bench/peers_speed.py's. At 64 times the spp the
reference's own noise is 1/8 of the measured images', which pulls noise ratios towards
1 by under 1 %. Making them once takes about 16 minutes on 2 idle cores (the 1920x1080
one at 1024 spp is 9 of them).

Set-up as bench/peers_speed.py: Debian's libllvm19 (DRJIT_LIBLLVM_PATH is set to it) and
the repository's .venv with mitsuba 3.9.1 and numpy, the same as tests/validation/run.sh.

Printed: JSON on stdout; a Markdown table on stderr.
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import peers_speed as ps  # noqa: E402  (set-up, runs and ratios are shared with it)

DEFAULT_CASES = ["cornell-box:1024x1024:4", "cornell-box:512x512:16",
                 "cornell-box:256x256:64", "cornell-caustics:1024x1024:4",
                 "cornell-caustics:512x512:16", "cornell-caustics:256x256:64",
                 "cornell-box:1920x1080:16"]
PEER = "mitsuba-llvm"
OURS, BEFORE = "ours", "before"
# Needs the sigma EXR of a separate high-spp render (aliquot render --sigma): not a method
# one command renders.
NOT_IN_ALL = ("oracle",)


def log(msg):
    print(f"spp-regimes: {msg}", file=sys.stderr, flush=True)


def parse_case(text):
    """'SCENE:WxH:SPP' -> dict; raises ValueError naming what is wrong."""
    parts = text.split(":")
    if len(parts) != 3 or parts[0] not in ps.SCENES:
        raise ValueError(f"expected SCENE:WxH:SPP with SCENE one of {', '.join(ps.SCENES)}, "
                         f"got {text!r}")
    w, h = (int(x) for x in parts[1].lower().split("x"))
    spp = int(parts[2])
    if w < 1 or h < 1 or spp < 1:
        raise ValueError(f"resolution and spp must be positive, got {text!r}")
    return {"scene": parts[0], "resolution": f"{w}x{h}", "spp": spp,
            "name": f"{parts[0]} {w}x{h} {spp} spp"}


def reference(case, args, env, py):
    spp = min(args.reference_spp_max, args.reference_factor * case["spp"])
    path = os.path.join(args.out_dir, f"mitsuba-{case['scene']}-{case['resolution']}-ref-"
                                      f"{spp}spp-seed5000.exr")
    if not os.path.exists(path):
        ps.run_json([py, ps.MITSUBA_SCRIPT, "--scene", case["scene"], "--variant", "llvm_rgb",
                     "--resolution", case["resolution"], "--spp", str(spp), "--seed", "5000",
                     "--threads", str(args.threads), "--out", path],
                    f"reference of {case['name']} at {spp} spp (cached for next time)", env)
    return path, spp


def methods_of(aliquot):
    """The methods `aliquot render --help` lists: the current binary's 'name: what it does'
    lines under --method, or an older one's 'uniform | dammertz | ...'."""
    text = subprocess.run([aliquot, "render", "--help"], capture_output=True,
                          text=True).stdout
    lines = text.splitlines()
    for n, line in enumerate(lines):
        if "--method" not in line:
            continue
        if "|" in line:  # "--method TEXT=uniform   uniform | dammertz | ..."
            return [m.strip().split()[-1] for m in line.split("|")]
        names = []
        for more in lines[n + 1:]:
            m = re.match(r"^\s{8,}([a-z][a-z0-9-]*):\s", more)
            if not m:
                break
            names.append(m.group(1))
        return names
    return []


def out_path(args, case, renderer, method=None):
    tag = renderer if method is None else f"{renderer}-{method}"
    return os.path.join(args.out_dir, f"regimes-{case['scene']}-{tag}-"
                                      f"{case['resolution']}-{case['spp']}spp.exr")


def commands(case, args, py):
    """Mitsuba's command for the case."""
    common = ["--resolution", case["resolution"], "--spp", str(case["spp"]),
              "--seed", str(args.seed), "--threads", str(args.threads)]
    return [py, ps.MITSUBA_SCRIPT, "--scene", case["scene"], "--variant", "llvm_rgb",
            "--warmup-spp", "1", *common, "--out", out_path(args, case, PEER)]


def aliquot_command(case, args, aliquot, renderer, method):
    """`aliquot render` of the case with `method`, the case's spp its count or budget."""
    return [aliquot, "render", "--scene", case["scene"], "--resolution", case["resolution"],
            "--spp", str(case["spp"]), "--method", method, "--seed", str(args.seed),
            "--threads", str(args.threads), "--json",
            "--out", out_path(args, case, renderer, method)]


def run_or_none(cmd, what, env):
    """ps.run_json, or None (said on stderr) if the render fails: one method's failure
    does not throw away a long run's other measurements."""
    try:
        return ps.run_json(cmd, what, env)
    except SystemExit as e:
        log(f"{what}: {e}; left out")
        return None


def per_sample_ratios(ours, peer, paired):
    """Ours over peer: samples/s (best runs, and paired), noise per sample
    (noise x sqrt(samples)) and efficiency = speed / noise ratio^2."""
    out = {"speed_ratio": ours["samples_per_second"] / peer["samples_per_second"],
           "paired_ratios": [o / p for o, p in paired]}
    if ours.get("noise") and peer.get("noise"):
        out["noise_ratio"] = (ours["noise"] * math.sqrt(ours["samples"])) / (
            peer["noise"] * math.sqrt(peer["samples"]))
        out["efficiency_ratio"] = out["speed_ratio"] / out["noise_ratio"] ** 2
    return out


def markdown(results, with_before):
    def runs(summary):
        if not summary:
            return "—"
        return " / ".join(f"{x / 1e6:.2f}" for x in summary["samples_per_second_all"])

    def ratio(cmp, key="speed_ratio", paired=True):
        if not cmp or key not in cmp:
            return "—"
        text = f"{cmp[key]:.2f}"
        if paired and cmp.get("paired_ratios"):
            text += " (" + " / ".join(f"{x:.2f}" for x in cmp["paired_ratios"]) + ")"
        return text

    head = ["case", "method", "Mitsuba llvm_ad_rgb M samples/s"]
    if with_before:
        head += ["before", "ours", "before ÷ Mitsuba", "ours ÷ Mitsuba (paired)",
                 "ours ÷ before (paired)", "noise/sample ratio, before / ours",
                 "efficiency, before / ours"]
    else:
        head += ["ours", "ours ÷ Mitsuba (paired)", "noise/sample ratio", "efficiency"]
    head.append("ours render / process s (best)")
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        rend, rat = r["renderers"], r["ratios"]
        ours = rend.get(OURS)
        cells = [r["case"], r["method"], runs(rend[PEER])]
        if with_before:
            pair = (lambda key: f"{ratio(rat.get(BEFORE), key, False)} / "
                                f"{ratio(rat.get(OURS), key, False)}")
            cells += [runs(rend.get(BEFORE)), runs(ours),
                      ratio(rat.get(BEFORE), paired=False),
                      "**" + ratio(rat.get(OURS)) + "**",
                      ratio(rat.get("ours_over_before")),
                      pair("noise_ratio"), pair("efficiency_ratio")]
        else:
            cells += [runs(ours), "**" + ratio(rat.get(OURS)) + "**",
                      ratio(rat.get(OURS), "noise_ratio", False),
                      ratio(rat.get(OURS), "efficiency_ratio", False)]
        cells.append(ps.seconds_pair(ours) if ours else "—")
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description="Aliquot vs Mitsuba llvm_ad_rgb across spp regimes.")
    ap.add_argument("--aliquot", default=os.path.join("build", "bin", "aliquot"))
    ap.add_argument("--before", default=None,
                    help="a second aliquot binary (the build before a change), run "
                         "interleaved with --aliquot's, so before and after are one run")
    ap.add_argument("--methods", nargs="+", default=["uniform"],
                    help="methods ours renders each case with, its spp a steered method's "
                         "budget (Mitsuba stays uniform); 'all': every method the binary "
                         "lists but " + ", ".join(NOT_IN_ALL))
    ap.add_argument("--cases", nargs="+", default=DEFAULT_CASES, help="SCENE:WxH:SPP ...")
    ap.add_argument("--repeat", type=int, default=3,
                    help="interleaved rounds; the best run of each renderer counts")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--reference-factor", type=int, default=64,
                    help="a reference has this many times its case's spp (default 64)")
    ap.add_argument("--reference-spp-max", type=int, default=4096)
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "build", "validation"))
    ap.add_argument("--no-install", action="store_true",
                    help="install nothing (no apt-get, no .venv, no pip)")
    args = ap.parse_args(argv)
    try:
        cases = [parse_case(c) for c in args.cases]
    except ValueError as e:
        ap.error(str(e))
    if args.repeat < 1 or args.threads < 1 or args.reference_factor < 1:
        ap.error("--repeat, --threads and --reference-factor must be positive")

    ps.ensure_venv([PEER], not args.no_install, script=__file__)  # re-runs this in .venv
    lib = ps.ensure_libllvm19(not args.no_install)
    if not lib:
        raise SystemExit("spp-regimes: needs libLLVM 19 (Debian package libllvm19)")
    env = dict(os.environ, DRJIT_LIBLLVM_PATH=lib)
    sys.path.insert(0, os.path.join(ROOT, "tests", "validation"))
    from compare_to_mitsuba import InputError, mean_abs_diff, read_exr_rgb

    binaries = {OURS: ps.aliquot_binary(args.aliquot, "spp-regimes")}
    if args.before:
        binaries[BEFORE] = ps.aliquot_binary(args.before, "spp-regimes")
    listed = {name: methods_of(path) for name, path in binaries.items()}
    methods = args.methods
    if methods == ["all"]:
        methods = [m for m in listed[OURS] if m not in NOT_IN_ALL]
    unknown = [m for m in methods if m not in listed[OURS]]
    if unknown:
        ap.error(f"{args.aliquot} has no method {', '.join(unknown)} "
                 f"(it lists {', '.join(listed[OURS])})")
    # Which binaries render which method: the before binary only those it has.
    renderers = {m: [n for n in (BEFORE, OURS) if n in binaries and m in listed[n]]
                 for m in methods}
    for m in methods:
        if BEFORE in binaries and BEFORE not in renderers[m]:
            log(f"{args.before} has no method {m}: ours alone renders it")
    os.makedirs(args.out_dir, exist_ok=True)
    py = sys.executable

    # References first, so that making them cannot disturb the timings.
    refs = [reference(c, args, env, py) for c in cases]
    peer_cmds = [commands(c, args, py) for c in cases]

    load_start = os.getloadavg()
    peer_runs = [[] for _ in cases]
    # runs[i][method][renderer]: JSON records; paired[i][method][renderer]: (sps, Mitsuba's
    # sps of the same round); ours_paired[i][method]: (ours, before of the same round).
    runs = [{m: {n: [] for n in renderers[m]} for m in methods} for _ in cases]
    paired = [{m: {n: [] for n in renderers[m]} for m in methods} for _ in cases]
    ours_paired = [{m: [] for m in methods} for _ in cases]
    for rep in range(args.repeat):
        for i, case in enumerate(cases):
            peer = ps.run_json(peer_cmds[i], f"{case['name']}: {PEER} "
                                             f"({rep + 1}/{args.repeat})", env)
            peer_runs[i].append(peer)
            for m in methods:
                got = {}
                for name in renderers[m]:
                    obj = run_or_none(aliquot_command(case, args, binaries[name], name, m),
                                      f"{case['name']}: {name} {m} ({rep + 1}/{args.repeat})",
                                      env)
                    if obj is None:
                        continue
                    got[name] = obj
                    runs[i][m][name].append(obj)
                    paired[i][m][name].append((obj["samples_per_second"],
                                               peer["samples_per_second"]))
                if OURS in got and BEFORE in got:
                    ours_paired[i][m].append((got[OURS]["samples_per_second"],
                                              got[BEFORE]["samples_per_second"]))
    load_end = os.getloadavg()

    results = []
    for i, case in enumerate(cases):
        ref_path, ref_spp = refs[i]
        try:
            ref = read_exr_rgb(ref_path)
        except InputError as e:
            raise SystemExit(f"spp-regimes: {e}")
        ref_mean = float(ref.mean())

        def measured(recs, path, name, warnings):
            s = ps.summarize(recs)
            img = read_exr_rgb(path)
            s["noise"] = mean_abs_diff(img, ref)
            s["mean_rel"] = float(img.mean()) / ref_mean - 1.0
            if recs[0].get("variant"):
                s["variant"] = recs[0]["variant"]
            if abs(s["mean_rel"]) > ps.MEAN_TOLERANCE[case["scene"]]:
                warnings.append(
                    f"{name}: image mean {100 * s['mean_rel']:+.2f} % off the reference: "
                    "not the same image, its noise ratio is not a comparison")
            return s

        peer_warnings = []
        peer = measured(peer_runs[i], out_path(args, case, PEER), PEER, peer_warnings)
        for m in methods:
            result = {"case": case["name"], "method": m, **case, "reference": ref_path,
                      "reference_spp": ref_spp, "renderers": {PEER: peer}, "ratios": {},
                      "warnings": list(peer_warnings)}
            for name in renderers[m]:
                if not runs[i][m][name]:
                    result["warnings"].append(f"{name}: every run failed")
                    continue
                s = measured(runs[i][m][name], out_path(args, case, name, m), name,
                             result["warnings"])
                result["renderers"][name] = s
                result["ratios"][name] = per_sample_ratios(s, peer, paired[i][m][name])
                if m == "uniform" and s["samples"] != peer["samples"]:
                    result["warnings"].append(f"{name}: the sample counts differ")
            rend = result["renderers"]
            if OURS in rend and BEFORE in rend:
                result["ratios"]["ours_over_before"] = {
                    "speed_ratio": rend[OURS]["samples_per_second"] /
                    rend[BEFORE]["samples_per_second"],
                    "paired_ratios": [o / b for o, b in ours_paired[i][m]]}
            results.append(result)

    print(markdown(results, BEFORE in binaries), file=sys.stderr, flush=True)
    for r in results:
        for w in r["warnings"]:
            log(f"{r['case']} {r['method']}: {w}")
    print(json.dumps({"results": results, "threads": args.threads, "repeat": args.repeat,
                      "seed": args.seed, "peer": PEER, "methods": methods,
                      "binaries": binaries,
                      "load_start": [round(x, 2) for x in load_start],
                      "load_end": [round(x, 2) for x in load_end],
                      "measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
