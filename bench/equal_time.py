#!/usr/bin/env python3
"""Speed x accuracy in one number: Aliquot against Mitsuba 3 llvm_ad_rgb at equal wall time.

  python3 bench/equal_time.py [--aliquot build/bin/aliquot] [--times 1 2 4 8 16]
        [--seeds 1 2] [--methods optimal uniform] [--reference-spp 16384]
        [--reference-seconds 1800] [--out-dir build/equal-time] [--report-dir DIR] [--no-install]

Cornell box (Mitsuba's cornell_box(), our cornell-box) at 256x256, box filter, paths of at
most 8 segments, 2 threads. Set-up as bench/peers_speed.py (Debian's libllvm19, the .venv
with mitsuba and numpy; matplotlib too, for the chart).

1. Reference: a high-spp Mitsuba llvm_ad_rgb render, made once and cached under --out-dir
   (its seeds never overlap a measured render's); --reference-seconds stops it early, after
   whole passes, on a loaded machine (the spp it reached is recorded and reported). Both
   renderers are judged against it: our image matches Mitsuba's within noise
   (docs/VALIDATION.md).
2. Throughput first: one calibration render each at 32 spp (Mitsuba's JIT warm-up
   excluded, as in peers_speed.py); its image is not scored. Then, per seed and per time
   budget t, interleaved: Mitsuba uniform at the spp that fits t, then each of our --methods with
   the budget (samples) that fits t. Each renderer's next budget uses the samples/s of
   its last run, so a change of machine load is followed. Times are each renderer's own
   render time (not process start, scene building or JIT compilation); the whole
   process's wall time is recorded beside it (process_seconds: for ours, loading the
   scene and writing the EXR too).
3. E = mean |image - reference| over pixels and RGB (`aliquot compare --json`, the seed's
   error). Per seed and budget: E_ours / E_mitsuba (raw, at the times actually taken) and
   the relative efficiency (E_peer^2 t_peer) / (E_ours^2 t_ours): how many times less
   time we need for the same error (Monte Carlo error ~ 1/sqrt(time)); > 1: we lead.
   E at exactly equal time, from that: E_ours / E_mitsuba = efficiency^-1/2. Over all
   pairs: the geometric mean of the efficiencies (a ratio's mean); the spread over seeds:
   each seed's geometric mean over its budgets, their min, max and standard deviation.

Written: REPORT_DIR/results.json, results.csv and charts/error-vs-time.svg|png (E against
seconds, log-log, both renderers). Both E include the reference's own noise, which pulls
ratios slightly towards 1; its size is estimated and reported.
"""

import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import peers_speed as ps  # noqa: E402  (set-up and JSON runs are shared with it)

RES = "256x256"
PIXELS = 256 * 256
# Mitsuba's LLVM variant keeps one wavefront in memory: split large spp into passes.
MAX_SPP_PER_PASS = 128


def log(msg):
    print(f"equal-time: {msg}", file=sys.stderr, flush=True)


def mitsuba_plan(spp):
    """(spp, passes) near `spp` with passes dividing it and <= MAX_SPP_PER_PASS per pass."""
    spp = max(1, int(round(spp)))
    passes = max(1, math.ceil(spp / MAX_SPP_PER_PASS))
    return passes * max(1, round(spp / passes)), passes


def efficiency(e_ours, t_ours, e_peer, t_peer):
    return (e_peer ** 2 * t_peer) / (e_ours ** 2 * t_ours)


def ensure_setup(install):
    """The .venv of peers_speed.py (re-exec in it), matplotlib, and libLLVM 19."""
    ps.ensure_venv(["mitsuba-llvm"], install, script=__file__)
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        if install:
            subprocess.run([sys.executable, "-m", "pip", "install", "--quiet",
                            "--disable-pip-version-check", "matplotlib"], check=True)
    lib = ps.ensure_libllvm19(install)
    if not lib:
        raise SystemExit("equal-time: needs libLLVM 19 (Debian package libllvm19)")
    return dict(os.environ, DRJIT_LIBLLVM_PATH=lib)


class Runner:
    """Builds and runs the renders; remembers each renderer's last samples/s."""

    def __init__(self, args, env, out_dir):
        self.args, self.env, self.out_dir = args, env, out_dir
        self.sps = {}

    def mitsuba(self, spp, seed, tag):
        spp, passes = mitsuba_plan(spp)
        out = os.path.join(self.out_dir, f"mitsuba-{tag}.exr")
        # Seeds seed*1000 .. +passes (and the warm-up's): apart from every other run's.
        cmd = [sys.executable, ps.MITSUBA_SCRIPT, "--variant", "llvm_rgb", "--warmup-spp", "1",
               "--resolution", RES, "--spp", str(spp), "--passes", str(passes),
               "--seed", str(seed * 1000), "--threads", str(self.args.threads), "--out", out]
        r = ps.run_json(cmd, f"mitsuba {tag}", self.env)
        r["output"] = out
        self.sps["mitsuba"] = r["samples_per_second"]
        return r

    def ours(self, method, samples, seed, tag):
        out = os.path.join(self.out_dir, f"{method}-{tag}.exr")
        cmd = [self.args.aliquot, "render", "--scene", "cornell-box", "--resolution", RES,
               "--method", method, "--seed", str(seed), "--threads", str(self.args.threads),
               "--json", "--out", out]
        if method == "uniform":
            cmd += ["--spp", str(max(1, round(samples / PIXELS)))]
        else:
            # optimal's pilot alone is 4 spp: a smaller budget cannot be spent as asked.
            cmd += ["--budget", str(max(PIXELS * 4, int(samples)))]
        r = ps.run_json(cmd, f"{method} {tag}", self.env)
        r["output"] = out
        self.sps[method] = r["samples_per_second"]
        return r

    def error(self, image, reference):
        p = subprocess.run([self.args.aliquot, "compare", "--json", image, reference],
                           capture_output=True, text=True, check=True)
        return json.loads(p.stdout)["mean_abs"]


def make_reference(args, env, out_dir):
    # Named by its spp, so that a short trial's reference is never taken for the real one.
    path = os.path.join(out_dir,
                        f"mitsuba-ref-256x256-{args.reference_spp}spp-seed100000.exr")
    meta = path + ".json"
    if not os.path.exists(path):
        # Seeds 100000.. are far from the measured runs' seed*1000 .. +passes.
        cmd = [sys.executable, ps.MITSUBA_SCRIPT, "--variant", "llvm_rgb", "--resolution", RES,
               "--spp", str(args.reference_spp), "--passes",
               str(max(1, args.reference_spp // MAX_SPP_PER_PASS)), "--seed", "100000",
               "--threads", str(args.threads), "--max-seconds", str(args.reference_seconds),
               "--out", path]
        r = ps.run_json(cmd, "reference (cached for next time)", env)
        with open(meta, "w") as f:
            json.dump(r, f)
    with open(meta) as f:
        return path, json.load(f)


def write_csv(rows, path):
    keys = ["seed", "target_seconds", "renderer", "samples", "spp", "seconds",
            "process_seconds", "E", "load_before"]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keys)
        for r in rows:
            w.writerow([r[k] for k in keys])


def chart(rows, report_dir, title):
    try:
        sys.path.insert(0, os.path.join(ROOT, "tools", "report"))
        import aliquot_report as rep  # same colours and SVG/PNG writer as the studies
    except SystemExit:
        log("no matplotlib: chart skipped")
        return None
    plt = rep.plt
    plt.rcParams["svg.hashsalt"] = "aliquot"
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    styles = {"mitsuba": ("#222222", "s", "Mitsuba 3 llvm_ad_rgb, uniform")}
    for name in sorted({r["renderer"] for r in rows}, key=lambda n: n != "mitsuba"):
        color, marker, label = styles.get(
            name, (rep.COLORS.get(name, "#888888"), "o", f"Aliquot {name}"))
        pts = sorted((r["seconds"], r["E"]) for r in rows if r["renderer"] == name)
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], marker, color=color, alpha=0.5,
                  markersize=4)
        means = {}
        for r in rows:
            if r["renderer"] == name:
                means.setdefault(r["target_seconds"], []).append((r["seconds"], r["E"]))
        line = [(statistics.mean(s for s, _ in v), statistics.mean(e for _, e in v))
                for _, v in sorted(means.items())]
        ax.loglog([p[0] for p in line], [p[1] for p in line], "-", color=color, label=label)
    ax.set_xlabel("render wall time (s), 2 threads")
    ax.set_ylabel("E = mean |image − Mitsuba reference|")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    os.makedirs(os.path.join(report_dir, "charts"), exist_ok=True)
    return rep.save(fig, report_dir, "error-vs-time")


def summarize(rows, methods):
    """Per method and time budget: mean ratios over seeds (and the worst seed)."""
    out = []
    by = {}
    for r in rows:
        by.setdefault((r["seed"], r["target_seconds"]), {})[r["renderer"]] = r
    for m in methods:
        for t in sorted({k[1] for k in by}):
            cells = [v for (s, tt), v in by.items() if tt == t and m in v and "mitsuba" in v]
            if not cells:
                continue
            ratio = [c[m]["E"] / c["mitsuba"]["E"] for c in cells]
            eff = [efficiency(c[m]["E"], c[m]["seconds"], c["mitsuba"]["E"],
                              c["mitsuba"]["seconds"]) for c in cells]
            out.append({"method": m, "target_seconds": t, "seeds": len(cells),
                        "t_ours": statistics.mean(c[m]["seconds"] for c in cells),
                        "t_mitsuba": statistics.mean(c["mitsuba"]["seconds"] for c in cells),
                        "t_ours_process": statistics.mean(
                            c[m]["process_seconds"] for c in cells),
                        "t_mitsuba_process": statistics.mean(
                            c["mitsuba"]["process_seconds"] for c in cells),
                        "E_ours": statistics.mean(c[m]["E"] for c in cells),
                        "E_mitsuba": statistics.mean(c["mitsuba"]["E"] for c in cells),
                        "E_ratio_raw": statistics.mean(ratio),
                        "efficiency": statistics.mean(eff),
                        "efficiency_min": min(eff), "efficiency_max": max(eff),
                        "E_ratio_equal_time": statistics.mean(e ** -0.5 for e in eff)})
    return out


def geomean(values):
    return math.exp(statistics.mean(math.log(v) for v in values))


def overall(rows, methods):
    """Per method: the geometric mean of every (seed, budget) pair's efficiency, and its
    spread over seeds (each seed's geometric mean over its budgets)."""
    by = {}
    for r in rows:
        by.setdefault((r["seed"], r["target_seconds"]), {})[r["renderer"]] = r
    out = {}
    for m in methods:
        per_seed = {}
        for (seed, _), v in sorted(by.items()):
            if m in v and "mitsuba" in v:
                per_seed.setdefault(seed, []).append(efficiency(
                    v[m]["E"], v[m]["seconds"], v["mitsuba"]["E"], v["mitsuba"]["seconds"]))
        eff = [e for seed_eff in per_seed.values() for e in seed_eff]
        if eff:
            g = geomean(eff)
            seeds = {seed: geomean(e) for seed, e in per_seed.items()}
            out[m] = {"pairs": len(eff), "efficiency_geomean": g, "E_ratio_equal_time": g ** -0.5,
                      "efficiency_min": min(eff), "efficiency_max": max(eff),
                      "efficiency_per_seed": seeds,
                      "seed_min": min(seeds.values()), "seed_max": max(seeds.values()),
                      "seed_stdev": (statistics.stdev(seeds.values())
                                     if len(seeds) > 1 else 0.0)}
    return out


def main():
    ap = argparse.ArgumentParser(description="Aliquot vs Mitsuba llvm_ad_rgb at equal time.")
    ap.add_argument("--aliquot", default=os.path.join("build", "bin", "aliquot"))
    ap.add_argument("--times", type=float, nargs="+", default=[1, 2, 4, 8, 16])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--methods", nargs="+", default=["optimal", "uniform"])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reference-spp", type=int, default=16384)
    ap.add_argument("--reference-seconds", type=float, default=1800,
                    help="stop the reference after this much render time (whole passes)")
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "build", "equal-time"))
    ap.add_argument("--report-dir", default=os.path.join(ROOT, "docs", "studies", "equal-time"))
    ap.add_argument("--no-install", action="store_true")
    args = ap.parse_args()
    args.aliquot = ps.aliquot_binary(args.aliquot, "equal-time")
    if min(args.times) <= 0 or args.threads < 1:
        ap.error("--times and --threads must be positive")

    env = ensure_setup(not args.no_install)
    os.makedirs(args.out_dir, exist_ok=True)
    os.makedirs(args.report_dir, exist_ok=True)
    ref_path, ref_meta = make_reference(args, env, args.out_dir)
    run = Runner(args, env, args.out_dir)

    load_start = os.getloadavg()
    # Calibration: samples/s of each renderer at a small fixed size, before the ladder.
    run.mitsuba(32, 900, "calibration")
    for m in args.methods:
        run.ours(m, 32 * PIXELS, 900, "calibration")

    rows, loads = [], []
    for seed in args.seeds:
        for t in args.times:
            tag = f"s{seed}-t{t:g}"
            # Interleaved: Mitsuba, then ours, so load changes hit both alike.
            runs = {"mitsuba": run.mitsuba(t * run.sps["mitsuba"] / PIXELS, seed, tag)}
            for m in args.methods:
                runs[m] = run.ours(m, t * run.sps[m], seed, tag)
            for name, r in runs.items():
                loads.append(r["load_before"])
                rows.append({"seed": seed, "target_seconds": t, "renderer": name,
                             "samples": r["samples"], "spp": r["samples"] / PIXELS,
                             "seconds": round(r["seconds"], 4),
                             "process_seconds": r["process_seconds"],
                             "E": run.error(r["output"], ref_path),
                             "load_before": r["load_before"]})
                log(f"  {name}: {r['seconds']:.2f} s, E {rows[-1]['E']:.6f}")

    summary = summarize(rows, args.methods)
    mits = [(r["E"], r["spp"]) for r in rows if r["renderer"] == "mitsuba"]
    ref_spp = ref_meta["spp"]
    # E scales as 1/sqrt(spp): the reference's own E from the measured Mitsuba runs.
    ref_error = statistics.median(e * math.sqrt(s / ref_spp) for e, s in mits)
    result = {"scene": "cornell-box", "resolution": RES, "threads": args.threads,
              "filter": "box", "max_depth": 8, "times": args.times, "seeds": args.seeds,
              "methods": args.methods,
              "reference": {"renderer": "mitsuba llvm_ad_rgb", "spp": ref_spp,
                            "seconds": ref_meta["seconds"], "estimated_E": ref_error},
              "mitsuba_version": ref_meta.get("mitsuba_version"),
              "load_start": [round(x, 2) for x in load_start],
              "load_end": [round(x, 2) for x in os.getloadavg()],
              "load_before_runs": {"min": min(loads), "median": statistics.median(loads),
                                   "max": max(loads)},
              "measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
              "overall": overall(rows, args.methods), "summary": summary, "runs": rows}
    with open(os.path.join(args.report_dir, "results.json"), "w") as f:
        json.dump(result, f, indent=2)
        f.write("\n")
    write_csv(rows, os.path.join(args.report_dir, "results.csv"))
    chart(rows, args.report_dir, f"cornell-box {RES}, equal time, {len(args.seeds)} seed(s)")

    print("| method | t budget | t ours / Mitsuba (s) | process ours / Mitsuba (s) | E ours | "
          "E Mitsuba | E ratio (raw) | efficiency (min-max) | E ratio at equal t |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s in summary:
        print(f"| {s['method']} | {s['target_seconds']:g} s | {s['t_ours']:.2f} / "
              f"{s['t_mitsuba']:.2f} | {s['t_ours_process']:.2f} / "
              f"{s['t_mitsuba_process']:.2f} | {s['E_ours']:.5f} | {s['E_mitsuba']:.5f} | "
              f"{s['E_ratio_raw']:.3f} | {s['efficiency']:.2f} ({s['efficiency_min']:.2f}-"
              f"{s['efficiency_max']:.2f}) | {s['E_ratio_equal_time']:.3f} |")
    for m, o in result["overall"].items():
        print(f"\n{m}, all {o['pairs']} pairs: efficiency {o['efficiency_geomean']:.3f} "
              f"(geometric mean; {o['efficiency_min']:.2f}-{o['efficiency_max']:.2f}), "
              f"E ratio at equal time {o['E_ratio_equal_time']:.3f}; over "
              f"{len(o['efficiency_per_seed'])} seed(s) {o['seed_min']:.2f}-"
              f"{o['seed_max']:.2f} (standard deviation {o['seed_stdev']:.2f}): " +
              ", ".join(f"seed {k} {v:.2f}" for k, v in o["efficiency_per_seed"].items()))
    print(f"\nreference: {ref_spp} spp, estimated E {ref_error:.6f}; load before runs "
          f"{result['load_before_runs']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
