#!/usr/bin/env python3
"""Samples/s and noise per sample against Mitsuba 3 llvm_ad_rgb where a pixel gets few
samples and where it gets many (issue 31), every case in one interleaved run.

  python3 bench/spp_regimes.py [--aliquot build/bin/aliquot] [--repeat 3] [--threads 2]
        [--cases SCENE:WxH:SPP ...] [--reference-factor 64] [--reference-spp-max 4096]
        [--out-dir build/validation] [--no-install]

Default cases: cornell-box and cornell-caustics at 1024x1024 4 spp, 512x512 16 spp and
256x256 64 spp (the same 4.2 M samples each: only the samples a pixel gets changes), and
cornell-box at 1920x1080 16 spp. Mitsuba renders its film at each case's size (both
renderers take the field of view along the smaller axis, so the images are the same);
its LLVM variant splits a render into passes of at most 2^23 samples
(tests/validation/mitsuba_cornell.py), so 1920x1080 16 spp is 4 passes of 4 spp over
the whole film, their render times added.

Interleaved: each of --repeat rounds runs every case as Mitsuba, then ours, so a change
of the machine's load hits every case and both renderers alike. Per case, as
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
import os
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


def commands(case, args, py, aliquot):
    def out(name):
        return os.path.join(args.out_dir, f"regimes-{case['scene']}-{name}-"
                                          f"{case['resolution']}-{case['spp']}spp.exr")
    common = ["--resolution", case["resolution"], "--spp", str(case["spp"]),
              "--seed", str(args.seed), "--threads", str(args.threads)]
    return {PEER: [py, ps.MITSUBA_SCRIPT, "--scene", case["scene"], "--variant", "llvm_rgb",
                   "--warmup-spp", "1", *common, "--out", out(PEER)],
            "ours": [aliquot, "render", "--scene", case["scene"], *common, "--json",
                     "--out", out("ours")]}, out


def markdown(results):
    rows = ["| case | Mitsuba llvm_ad_rgb M samples/s | ours | speed ratio (paired) | "
            "noise ratio | efficiency | ours render / process s (best) |",
            "|---|---|---|---|---|---|---|"]
    for r in results:
        peer, ours, cmp = r["renderers"][PEER], r["renderers"]["ours"], r["ratios"][PEER]
        runs = (lambda s: " / ".join(f"{x / 1e6:.2f}" for x in s["samples_per_second_all"]))
        paired = " / ".join(f"{x:.2f}" for x in cmp["paired_ratios"])
        rows.append(f"| {r['case']} | {runs(peer)} | {runs(ours)} | "
                    f"**{cmp['speed_ratio']:.2f}** ({paired}) | {cmp['noise_ratio']:.3f} | "
                    f"{cmp['efficiency_ratio']:.2f} | {ps.seconds_pair(ours)} |")
    return "\n".join(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description="Aliquot vs Mitsuba llvm_ad_rgb across spp regimes.")
    ap.add_argument("--aliquot", default=os.path.join("build", "bin", "aliquot"))
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

    aliquot = ps.aliquot_binary(args.aliquot, "spp-regimes")
    os.makedirs(args.out_dir, exist_ok=True)
    py = sys.executable

    # References first, so that making them cannot disturb the timings.
    refs = [reference(c, args, env, py) for c in cases]
    plans = [commands(c, args, py, aliquot) for c in cases]

    load_start = os.getloadavg()
    runs = [{PEER: [], "ours": []} for _ in cases]
    paired = [[] for _ in cases]
    for rep in range(args.repeat):
        for i, case in enumerate(cases):
            cmds, _ = plans[i]
            for name in (PEER, "ours"):
                runs[i][name].append(ps.run_json(
                    cmds[name], f"{case['name']}: {name} ({rep + 1}/{args.repeat})", env))
            paired[i].append((runs[i]["ours"][-1]["samples_per_second"],
                              runs[i][PEER][-1]["samples_per_second"]))
    load_end = os.getloadavg()

    results = []
    for i, case in enumerate(cases):
        ref_path, ref_spp = refs[i]
        try:
            ref = read_exr_rgb(ref_path)
        except InputError as e:
            raise SystemExit(f"spp-regimes: {e}")
        ref_mean = float(ref.mean())
        _, out = plans[i]
        result = {"case": case["name"], **case, "reference": ref_path,
                  "reference_spp": ref_spp, "renderers": {}, "warnings": []}
        for name in (PEER, "ours"):
            s = ps.summarize(runs[i][name])
            img = read_exr_rgb(out(name))
            s["noise"] = mean_abs_diff(img, ref)
            s["mean_rel"] = float(img.mean()) / ref_mean - 1.0
            if runs[i][name][0].get("variant"):
                s["variant"] = runs[i][name][0]["variant"]
            if abs(s["mean_rel"]) > ps.MEAN_TOLERANCE[case["scene"]]:
                result["warnings"].append(
                    f"{name}: image mean {100 * s['mean_rel']:+.2f} % off the reference: "
                    "not the same image, its noise ratio is not a comparison")
            result["renderers"][name] = s
        if result["renderers"][PEER]["samples"] != result["renderers"]["ours"]["samples"]:
            result["warnings"].append("the sample counts differ")
        result["ratios"] = {PEER: ps.ratios(result["renderers"]["ours"],
                                            result["renderers"][PEER], paired[i])}
        results.append(result)

    print(markdown(results), file=sys.stderr, flush=True)
    for r in results:
        for w in r["warnings"]:
            log(f"{r['case']}: {w}")
    print(json.dumps({"results": results, "threads": args.threads, "repeat": args.repeat,
                      "seed": args.seed, "peer": PEER,
                      "load_start": [round(x, 2) for x in load_start],
                      "load_end": [round(x, 2) for x in load_end],
                      "measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
