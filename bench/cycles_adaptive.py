#!/usr/bin/env python3
"""Blender Cycles' own adaptive sampling against its uniform sampling, at equal samples.

  .venv/bin/python bench/cycles_adaptive.py [--spp 64] [--min-samples 32] [--seeds 1 2 3]
        [--resolution 128x128] [--reference-spp 8192] [--max-samples 4096] [--threads 2]
        [--aliquot build/bin/aliquot]

Issue 15 asks how much production adaptive sampling gains at equal budget, to set our
`cycles` method (Cycles' algorithm re-implemented in Aliquot) beside the real one. This
renders, with bpy (Blender 5 as a Python module), the Cornell box of
bench/cycles_cornell.py (the same scene and settings as the peers bench):
  (a) a Cycles reference at --reference-spp, adaptive sampling off, its own seed
      (--reference-seed), cached under --out-dir;
  (b) for each seed: Cycles uniform at --spp, and Cycles adaptive (min samples
      --min-samples, at most --max-samples per pixel) with its noise threshold tuned
      until the mean samples per pixel is --spp within --spp-tolerance. The samples each
      pixel took are Cycles' own: its "Debug Sample Count" pass, read from the multilayer
      EXR (bench/exr_parts.py) and scaled as samples_per_pixel() explains.
E = mean |image - reference| per pixel over RGB, against Cycles' own reference, so Cycles'
low-discrepancy pattern is judged against itself. A seed's adaptive and uniform renders
share its seed. Reported per seed: E(adaptive) / E(uniform), also scaled to exactly --spp samples (E ~ 1/sqrt(samples):
times sqrt(adaptive spp / spp), a correction of at most half --spp-tolerance), and E of
the first --spp samples of a --max-samples uniform render (Cycles lays its sample pattern
out for the count asked for: these are the samples adaptive draws, without stopping; the
adaptive render is the first of these samples exactly, pixel by pixel, up to where each
pixel stops).

With --aliquot, our `cycles` method the same way: per seed, `aliquot render` uniform at
--spp and `--method cycles` (the same min samples and cap) with its threshold tuned to the
same mean spp (from its samples_done), E against our own uniform render at --reference-spp
(seed 2^40). Our threshold's scale is not Cycles' (--ours-start-threshold).

Tuning: the threshold starts at --start-threshold (0.026, the issue's Blender measurement)
and moves by secant steps on log(mean spp) against log(threshold), staying inside the
bracket found so far; each step is one adaptive render. Ratios of errors do not depend on
the machine's load; the wall times printed beside them do.

Output: JSON on stdout, a Markdown table on stderr; the images stay in --out-dir.
"""

import argparse
import json
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
VENV_PY = os.path.join(ROOT, ".venv", "bin", "python")
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "tests", "validation"))

from mitsuba_cornell import parse_resolution  # noqa: E402


OURS_REFERENCE_SEED = 2**40  # the studies' reference seed: never a test render's

# Cycles checks convergence every 16 samples (Integrator's adaptive step, fixed in Cycles;
# our `cycles` method's default --adaptive-step too).
ADAPTIVE_STEP = 16


def log(msg):
    print(f"cycles-adaptive: {msg}", file=sys.stderr, flush=True)


def next_threshold(tried, target):
    """The next threshold to try, from [(threshold, mean spp), ...] (spp falls as t rises).

    Secant steps on log(spp) against log(threshold): between the two tries that bracket
    the target when there are such (kept inside the bracket), else through the two
    latest tries, at most 4x away, or with slope -1 when there is a single try.
    """
    below = [p for p in tried if p[1] < target]   # threshold too high
    above = [p for p in tried if p[1] >= target]  # threshold too low (or exact)
    if above and below:
        lo = max(above, key=lambda p: p[0])
        hi = min(below, key=lambda p: p[0])
        x0, y0 = math.log(lo[0]), math.log(lo[1])
        x1, y1 = math.log(hi[0]), math.log(hi[1])
        if y1 == y0:
            return math.exp(0.5 * (x0 + x1))
        x = x0 + (math.log(target) - y0) * (x1 - x0) / (y1 - y0)
        margin = 0.1 * (x1 - x0)
        return math.exp(min(max(x, x0 + margin), x1 - margin))
    t, spp = tried[-1]
    slope = -1.0
    if len(tried) >= 2:
        (ta, sa), (tb, sb) = tried[-2], tried[-1]
        if ta != tb and sa != sb:
            slope = min(-0.1, (math.log(sb) - math.log(sa)) / (math.log(tb) - math.log(ta)))
    step = (math.log(target) - math.log(spp)) / slope
    return t * math.exp(min(max(step, -math.log(4)), math.log(4)))


def tune(render_at, start, target, tolerance, max_tries, what):
    """Threshold whose render's mean spp is target within tolerance (or the closest tried).

    render_at(t) -> (image, mean spp); returns (t, image, mean spp, [(t, spp), ...]).
    """
    tried, renders = [], {}
    t = start
    for _ in range(max_tries):
        img, spp = render_at(t)
        tried.append((t, spp))
        renders[t] = (img, spp)
        log(f"{what}: threshold {t:.5g}: mean {spp:.2f} spp")
        if abs(spp / target - 1) <= tolerance:
            break
        t = next_threshold(tried, target)
    best = min(tried, key=lambda p: abs(p[1] / target - 1))[0]
    return (best, *renders[best], tried)


def read_rgb(path):
    """RGB (H, W, 3) float64 of a single-part EXR such as `aliquot render` writes."""
    import numpy as np
    from exr_parts import read_parts
    (part,) = read_parts(path).values()
    return np.stack([part[k] for k in "RGB"], axis=2).astype(np.float64)


def ours_rows(args, aliquot):
    """Our `cycles` method under the same protocol, against our own uniform reference."""
    import subprocess
    import numpy as np
    w, h = args.resolution
    res = f"{w}x{h}"

    def render(out, *extra):
        cmd = [aliquot, "render", "--scene", "cornell-box", "--resolution", res,
               "--threads", str(args.threads), "--json", "--out", out, *extra]
        done = subprocess.run(cmd, capture_output=True, text=True, check=True)
        summary = json.loads(done.stdout)
        return read_rgb(out), summary["samples_done"] / (w * h)

    ref_path = os.path.join(args.out_dir, f"ours-reference-{res}-{args.reference_spp}spp-"
                                          f"seed{OURS_REFERENCE_SEED}.exr")
    if not os.path.exists(ref_path):
        log(f"ours: reference {args.reference_spp} spp, seed {OURS_REFERENCE_SEED}")
        render(ref_path + ".tmp.exr", "--spp", str(args.reference_spp),
               "--seed", str(OURS_REFERENCE_SEED))
        os.replace(ref_path + ".tmp.exr", ref_path)
    ref = read_rgb(ref_path)
    rows = []
    for seed in args.seeds:
        uni, _ = render(os.path.join(args.out_dir, f"ours-uniform-seed{seed}.exr"),
                        "--spp", str(args.spp), "--seed", str(seed))

        def cycles_at(t, seed=seed):
            return render(os.path.join(args.out_dir, f"ours-cycles-seed{seed}.exr"),
                          "--method", "cycles", "--noise-threshold", f"{t:.6g}",
                          "--adaptive-min-samples", str(args.min_samples),
                          "--max-spp", str(args.max_samples), "--seed", str(seed))

        t, img, spp, tried = tune(cycles_at, args.ours_start_threshold, args.spp,
                                  args.spp_tolerance, args.max_tries, f"ours seed {seed}")
        e_a = float(np.mean(np.abs(img - ref)))
        e_u = float(np.mean(np.abs(uni - ref)))
        rows.append({"seed": seed, "threshold": t, "adaptive_mean_spp": spp,
                     "E_adaptive": e_a, "E_uniform": e_u,
                     "ratio_at_equal_samples": e_a / e_u * math.sqrt(spp / args.spp),
                     "tries": [[round(a, 6), round(b, 3)] for a, b in tried],
                     "within_tolerance": abs(spp / args.spp - 1) <= args.spp_tolerance})
    return rows


class CyclesRenderer:
    """One bpy scene, rendered again and again with other seeds, spp and thresholds."""

    def __init__(self, args, out_dir):
        import bpy
        import cycles_cornell
        self.bpy = bpy
        self.out_dir = out_dir
        self.settings = {}
        ns = argparse.Namespace(resolution=args.resolution, spp=args.spp, seed=0,
                                threads=args.threads, bounces=args.bounces)
        self.scene = cycles_cornell.build_scene(bpy, ns, self.settings)
        self.scene.view_layers[0].cycles.pass_debug_sample_count = True
        img = self.scene.render.image_settings
        img.media_type = "MULTI_LAYER_IMAGE"
        img.file_format = "OPEN_EXR_MULTILAYER"
        img.color_depth = "32"
        self.version = bpy.app.version_string

    def render(self, name, spp, seed, threshold=None, min_samples=0, subset=None):
        """Render; returns (RGB float64 (H, W, 3), the sample count pass, seconds).

        subset: render only the first `subset` samples of an spp-sample render.
        """
        import numpy as np
        from exr_parts import read_parts
        c = self.scene.cycles
        c.samples = spp
        c.seed = seed
        c.use_sample_subset = subset is not None
        if subset is not None:
            c.sample_offset = 0
            c.sample_subset_length = subset
        c.use_adaptive_sampling = threshold is not None
        if threshold is not None:
            c.adaptive_threshold = threshold
            c.adaptive_min_samples = min_samples
        t0 = time.perf_counter()
        self.bpy.ops.render.render(write_still=False)
        seconds = time.perf_counter() - t0
        path = os.path.join(self.out_dir, f"{name}.exr")
        self.bpy.data.images["Render Result"].save_render(filepath=path, scene=self.scene)
        parts = read_parts(path)
        combined = parts["ViewLayer.Combined"]
        rgb = np.stack([combined[f"ViewLayer.Combined.{k}"] for k in "RGB"], axis=2)
        count = parts["ViewLayer.Debug Sample Count"]["ViewLayer.Debug Sample Count.X"]
        return rgb.astype(np.float64), count.astype(np.float64), seconds


def samples_per_pixel(count, first_check, step=ADAPTIVE_STEP):
    """Each pixel's samples, from Cycles' sample count pass of an adaptive render.

    The pass holds k / S: k the pixel's samples, S the samples the render ran for (its
    loop stops when every pixel has converged, so S is not the maximum asked for, and
    Blender reports no S). Pixels stop at convergence checks: after `first_check`
    samples, then every `step`; in a render at a mean of a few times the minimum many
    pixels stop at the first check, so the smallest value is first_check / S. Refused
    (ValueError) when the counts this gives are not whole checks.
    """
    import numpy as np
    s = first_check / float(count.min())
    k = count * s
    whole = np.abs(k - np.round(k)) < 1e-3
    on_checks = (np.round(k) - first_check) % step == 0
    full = np.abs(k - round(s)) < 1e-3  # pixels that ran to the end
    if abs(s - round(s)) > 1e-3 or not np.all(whole & (on_checks | full)):
        raise ValueError(f"sample count pass does not fit checks at {first_check} + "
                         f"{step}j samples (S = {s:.4f})")
    return np.round(k)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--resolution", type=parse_resolution, default=(128, 128))
    ap.add_argument("--spp", type=int, default=64, help="the budget N, mean spp (default 64)")
    ap.add_argument("--min-samples", type=int, default=32,
                    help="Cycles' adaptive min samples (default 32, as the issue's)")
    ap.add_argument("--max-samples", type=int, default=4096,
                    help="adaptive renders' samples cap per pixel (default 4096, as our "
                         "cycles method's in the allocation-limit study)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--reference-spp", type=int, default=8192)
    ap.add_argument("--reference-seed", type=int, default=1000)
    ap.add_argument("--start-threshold", type=float, default=0.026)
    ap.add_argument("--spp-tolerance", type=float, default=0.01,
                    help="relative tolerance on the adaptive mean spp (default 0.01)")
    ap.add_argument("--max-tries", type=int, default=12,
                    help="adaptive renders per seed at most while tuning (default 12)")
    ap.add_argument("--aliquot", default=None,
                    help="also run our `cycles` method the same way (uniform and tuned "
                         "cycles per seed, against our own --reference-spp uniform render)")
    ap.add_argument("--ours-start-threshold", type=float, default=0.12,
                    help="our cycles' first threshold (our scale: ~0.12 gives 64 spp)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--bounces", type=int, default=6,
                    help="Cycles max bounces (6 = max depth 8, bench/cycles_cornell.py)")
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "build", "validation",
                                                      "cycles-adaptive"))
    args = ap.parse_args(argv)
    if min(args.spp, args.min_samples, args.reference_spp, args.threads) < 1:
        ap.error("--spp, --min-samples, --reference-spp and --threads must be positive")
    if args.max_samples <= args.spp:
        ap.error("--max-samples must exceed --spp, or adaptive cannot spend the budget")

    try:
        import bpy  # noqa: F401
    except ImportError:
        if os.path.exists(VENV_PY) and os.path.realpath(sys.executable) != os.path.realpath(
                VENV_PY):
            os.execv(VENV_PY, [VENV_PY, os.path.abspath(__file__)] + sys.argv[1:])
        raise SystemExit("cycles-adaptive: no bpy: run with the .venv made by "
                         "bench/peers_speed.py (bpy 5.0.1 wants Python 3.11)")
    import numpy as np

    os.makedirs(args.out_dir, exist_ok=True)
    w, h = args.resolution
    r = CyclesRenderer(args, args.out_dir)
    load_start = os.getloadavg()

    ref_name = f"reference-{w}x{h}-{args.reference_spp}spp-seed{args.reference_seed}"
    ref_npy = os.path.join(args.out_dir, ref_name + ".npy")
    if os.path.exists(ref_npy):
        ref = np.load(ref_npy)
        log(f"reusing reference {ref_npy}")
        ref_info = {"cached": True}
    else:
        log(f"reference: {args.reference_spp} spp, seed {args.reference_seed} "
            f"(load {os.getloadavg()[0]:.2f})")
        ref, _, secs = r.render(ref_name, args.reference_spp, args.reference_seed)
        np.save(ref_npy, ref)
        ref_info = {"cached": False, "seconds": secs}
        log(f"  {secs:.0f} s")

    # Where pixels can first stop: the adaptive render in which every pixel converges at
    # its first check (a threshold no pixel misses) is, sample for sample, the first that
    # many samples of the uniform render of as many samples as the adaptive cap (Cycles'
    # pattern depends on the sample count asked for) with the same seed.
    seed0 = args.seeds[0]
    stop_all, _, _ = r.render(f"first-check-seed{seed0}", args.max_samples, seed0,
                              threshold=1e9, min_samples=args.min_samples)
    first_check = None
    for n in range(args.min_samples, args.min_samples + 3 * ADAPTIVE_STEP + 1):
        uni_n, _, _ = r.render(f"first-check-uniform-{n}of{args.max_samples}spp-seed{seed0}",
                               args.max_samples, seed0, subset=n)
        if np.array_equal(uni_n, stop_all):
            first_check = n
            break
    if first_check is None:
        raise SystemExit("cycles-adaptive: the adaptive render that stops every pixel at "
                         "once matches no uniform render: cannot read sample counts")
    log(f"pixels first stop after {first_check} samples (min samples {args.min_samples})")

    def err(img):
        return float(np.mean(np.abs(img - ref)))

    rows = []
    for seed in args.seeds:
        load = os.getloadavg()[0]
        uni, uni_count, uni_s = r.render(f"uniform-{args.spp}spp-seed{seed}", args.spp, seed)
        uni_spp = float(uni_count.mean()) * args.spp  # all 1: every pixel ran the render
        log(f"seed {seed}: uniform {args.spp} spp: E {err(uni):.6f}, {uni_s:.1f} s "
            f"(load {load:.2f})")
        # The same samples as the adaptive render's first N: Cycles' pattern is laid out
        # for the sample count asked for, and adaptive asks for --max-samples.
        uni_cap, _, _ = r.render(f"uniform-{args.spp}of{args.max_samples}spp-seed{seed}",
                                 args.max_samples, seed, subset=args.spp)
        timing = {}

        def adaptive_at(t, seed=seed):
            img, count, secs = r.render(f"adaptive-seed{seed}-t{t:.6g}", args.max_samples,
                                        seed, threshold=t, min_samples=args.min_samples)
            timing[t] = secs
            return img, float(samples_per_pixel(count, first_check).mean())

        t, img, spp, tried = tune(adaptive_at, args.start_threshold, args.spp,
                                  args.spp_tolerance, args.max_tries, f"seed {seed}")
        secs = timing[t]
        e_a, e_u = err(img), err(uni)
        rows.append({"seed": seed, "threshold": t, "adaptive_mean_spp": spp,
                     "uniform_spp": uni_spp, "E_adaptive": e_a, "E_uniform": e_u,
                     "ratio": e_a / e_u,
                     "ratio_at_equal_samples": e_a / e_u * math.sqrt(spp / args.spp),
                     "E_uniform_in_max_pattern": err(uni_cap),
                     "seconds_adaptive": secs, "seconds_uniform": uni_s,
                     "tries": [[round(a, 6), round(b, 3)] for a, b in tried],
                     "within_tolerance": abs(spp / args.spp - 1) <= args.spp_tolerance})

    ratios = [x["ratio_at_equal_samples"] for x in rows]
    ours = ours_rows(args, os.path.abspath(args.aliquot)) if args.aliquot else []
    out = {"blender_version": r.version, "resolution": [w, h], "spp": args.spp,
           "min_samples": args.min_samples, "max_samples": args.max_samples,
           "first_check": first_check,
           "reference_spp": args.reference_spp, "reference_seed": args.reference_seed,
           "reference": ref_info, "reference_mean": float(ref.mean()),
           "threads": args.threads, "rows": rows,
           "mean_ratio_at_equal_samples": sum(ratios) / len(ratios),
           "ours_cycles_rows": ours,
           "settings": r.settings,
           "load_start": [round(x, 2) for x in load_start],
           "load_end": [round(x, 2) for x in os.getloadavg()],
           "measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    table = [f"Cycles {r.version}, Cornell box {w}x{h}, N = {args.spp}, min samples "
             f"{args.min_samples}, reference {args.reference_spp} spp:", "",
             "| seed | threshold | adaptive mean spp | E adaptive | E uniform | ratio | "
             "ratio at N | E uniform, first N of max |", "|---|---|---|---|---|---|---|---|"]
    for x in rows:
        table.append(f"| {x['seed']} | {x['threshold']:.4f} | {x['adaptive_mean_spp']:.2f} | "
                     f"{x['E_adaptive']:.6f} | {x['E_uniform']:.6f} | {x['ratio']:.3f} | "
                     f"{x['ratio_at_equal_samples']:.3f} | "
                     f"{x['E_uniform_in_max_pattern']:.6f} |")
    table.append(f"\nmean ratio at N: {out['mean_ratio_at_equal_samples']:.3f}")
    if ours:
        table += ["", "Ours (cycles method), same protocol:", "",
                  "| seed | threshold | mean spp | E cycles | E uniform | ratio at N |",
                  "|---|---|---|---|---|---|"]
        for x in ours:
            table.append(f"| {x['seed']} | {x['threshold']:.4f} | "
                         f"{x['adaptive_mean_spp']:.2f} | {x['E_adaptive']:.6f} | "
                         f"{x['E_uniform']:.6f} | {x['ratio_at_equal_samples']:.3f} |")
        mean = sum(x["ratio_at_equal_samples"] for x in ours) / len(ours)
        out["ours_mean_ratio_at_equal_samples"] = mean
        table.append(f"\nours: mean ratio at N: {mean:.3f}")
    print("\n".join(table), file=sys.stderr, flush=True)
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
