#!/usr/bin/env python3
"""Speed and noise of Aliquot against Mitsuba 3 on the Cornell box, measured in one run.

  .venv/bin/python bench/mitsuba_speed.py [--aliquot build/bin/aliquot] [--spp 64]
        [--resolution 256x256] [--threads 2] [--repeat 3] [--reference REF.exr]
        [--variant scalar_rgb|llvm_rgb] [--mitsuba-only]

Both renderers draw the same scene (Mitsuba's cornell_box(), box filter, path tracer
max depth 8, Russian roulette from depth 5) at the same resolution and spp, each in its
own process with the same number of threads, one after the other, --repeat times
interleaved (Mitsuba, ours, Mitsuba, ours, ...). Each reports the time of its render
alone (not start-up or scene loading); a renderer's speed is its best run's samples/s,
the least disturbed by whatever else the machine is doing, and all runs are listed.

A faster sample that is noisier is no gain, so each image's noise is measured too:
noise = mean |image - reference| (averaged over pixels and RGB). The reference is
--reference if given, else build/validation/mitsuba-256-ref.exr if it exists at the
benchmark's resolution, else a Mitsuba render at --reference-spp that is made once and
cached under build/validation/. Both noises include the reference's own residual noise
equally, which pulls their ratio slightly towards 1.

Printed JSON (stdout): per renderer samples, seconds, samples_per_second, noise; and
  speed_ratio          = samples/s ours / samples/s Mitsuba
  noise_ratio          = noise ours / noise Mitsuba (at equal spp)
  efficiency_ratio     = speed_ratio / noise_ratio^2: how many times faster ours
                         reaches a given error (Monte Carlo error ~ 1/sqrt(samples));
                         > 1 means ours is ahead.
Ratios are the result; absolute times depend on the machine and its load.
"""

import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "tests", "validation"))

from compare_to_mitsuba import InputError, mean_abs_diff, read_exr_rgb  # noqa: E402

MITSUBA_SCRIPT = os.path.join(ROOT, "tests", "validation", "mitsuba_cornell.py")


def last_json_object(text):
    for line in reversed(text.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                obj = json.loads(line)
            except ValueError:
                continue
            if isinstance(obj, dict):
                return obj
    return None


def run_json(cmd, what):
    print(f"bench: {what}: {' '.join(cmd)}", file=sys.stderr, flush=True)
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.stderr.write(p.stdout + p.stderr)
        raise SystemExit(f"bench: {what} failed with exit status {p.returncode}")
    obj = last_json_object(p.stdout)
    if obj is None:
        sys.stderr.write(p.stdout + p.stderr)
        raise SystemExit(f"bench: {what} printed no JSON object")
    for key in ("samples", "seconds", "samples_per_second"):
        if key not in obj:
            raise SystemExit(f"bench: {what}: JSON lacks {key!r}: {obj}")
    return obj


def main(argv=None):
    ap = argparse.ArgumentParser(description="Aliquot vs Mitsuba 3: samples/s and noise.")
    ap.add_argument("--aliquot", default=os.path.join("build", "bin", "aliquot"))
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--resolution", default="256x256")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--variant", default="scalar_rgb", choices=["scalar_rgb", "llvm_rgb"],
                    help="Mitsuba variant to time (default scalar_rgb)")
    ap.add_argument("--reference", default=None, help="high-spp EXR to measure noise against")
    ap.add_argument("--reference-spp", type=int, default=1024,
                    help="spp of the cached Mitsuba reference made when none is given")
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "build", "validation"))
    ap.add_argument("--repeat", type=int, default=3,
                    help="interleaved timed runs of each renderer; the best counts (default 3)")
    ap.add_argument("--mitsuba-only", action="store_true",
                    help="time Mitsuba alone (before Aliquot's binary exists)")
    args = ap.parse_args(argv)

    if args.repeat < 1 or args.spp < 1 or args.threads < 1:
        ap.error("--repeat, --spp and --threads must be positive")
    os.makedirs(args.out_dir, exist_ok=True)
    py = sys.executable
    res = args.resolution
    aliquot = args.aliquot
    if not os.path.isabs(aliquot) and not os.path.exists(aliquot):
        aliquot = os.path.join(ROOT, aliquot)
    if not args.mitsuba_only and not os.access(aliquot, os.X_OK):
        raise SystemExit(f"bench: aliquot binary not found: {args.aliquot} "
                         "(build it, or pass --mitsuba-only)")

    # Reference (made before timing anything, so it cannot disturb the timings).
    ref_path = args.reference
    if ref_path is None:
        default_ref = os.path.join(args.out_dir, "mitsuba-256-ref.exr")
        cached = os.path.join(args.out_dir,
                              f"mitsuba-{res}-ref-{args.reference_spp}spp-seed5000.exr")
        if res == "256x256" and os.path.exists(default_ref):
            ref_path = default_ref
        elif os.path.exists(cached):
            ref_path = cached
        else:
            run_json([py, MITSUBA_SCRIPT, "--resolution", res, "--spp",
                      str(args.reference_spp), "--seed", "5000", "--out", cached],
                     f"reference at {args.reference_spp} spp (cached for next time)")
            ref_path = cached
    try:
        ref = read_exr_rgb(ref_path)
    except InputError as e:
        raise SystemExit(f"bench: {e}")

    mit_out = os.path.join(args.out_dir, f"bench-mitsuba-{res}-{args.spp}spp.exr")
    ours_out = os.path.join(args.out_dir, f"bench-ours-{res}-{args.spp}spp.exr")
    mit_cmd = [py, MITSUBA_SCRIPT, "--variant", args.variant, "--resolution", res,
               "--spp", str(args.spp), "--seed", str(args.seed),
               "--threads", str(args.threads), "--out", mit_out]
    ours_cmd = [aliquot, "render", "--scene", "cornell-box", "--resolution", res,
                "--spp", str(args.spp), "--seed", str(args.seed),
                "--threads", str(args.threads), "--json", "--out", ours_out]

    # Interleaved repeats (M, O, M, O, ...): a change of machine load during the run
    # hits both renderers alike; each renderer's best run is its speed (the least
    # disturbed one), and all runs are reported.
    mit_runs, ours_runs = [], []
    for rep in range(args.repeat):
        mit_runs.append(run_json(mit_cmd, f"Mitsuba {args.variant} ({rep + 1}/{args.repeat})"))
        if not args.mitsuba_only:
            ours_runs.append(run_json(ours_cmd, f"Aliquot ({rep + 1}/{args.repeat})"))

    def summary(runs):
        best = max(runs, key=lambda r: r["samples_per_second"])
        # Mitsuba's script says "samples"; aliquot render --json says "samples_done".
        samples = best.get("samples_done", best.get("samples"))
        return {"samples": samples, "seconds": best["seconds"],
                "samples_per_second": best["samples_per_second"],
                "samples_per_second_all": [r["samples_per_second"] for r in runs]}

    results = {"mitsuba": summary(mit_runs)}
    results["mitsuba"].update(variant=mit_runs[0].get("variant"),
                              version=mit_runs[0].get("mitsuba_version"),
                              noise=mean_abs_diff(read_exr_rgb(mit_out), ref),
                              image=mit_out)

    if not args.mitsuba_only:
        ours_img = ours_runs[0].get("output") or ours_out
        results["ours"] = summary(ours_runs)
        results["ours"].update(noise=mean_abs_diff(read_exr_rgb(ours_img), ref),
                               image=ours_img)
        o, m = results["ours"], results["mitsuba"]
        results["speed_ratio"] = o["samples_per_second"] / m["samples_per_second"]
        results["noise_ratio"] = o["noise"] / m["noise"]
        results["efficiency_ratio"] = results["speed_ratio"] / results["noise_ratio"] ** 2
        if o["samples"] != m["samples"]:
            results["warning"] = "sample counts differ: the noise ratio is not at equal spp"

    results.update(resolution=res, spp=args.spp, threads=args.threads, repeat=args.repeat,
                   reference=ref_path, measured_at=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    print(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
