#!/usr/bin/env python3
"""Render Mitsuba 3's Cornell box (or our caustics variant of it) as a reference for Aliquot.

The scene (--scene, see mitsuba_scenes.py) is `mi.cornell_box()` for cornell-box, and
for cornell-caustics cornell_box() with analytic glass and mirror spheres in place of
the boxes and a smaller, brighter light; unchanged except for:
  * the film's reconstruction filter, overridden to a box filter (a pixel is the
    plain average of its samples, as in Aliquot and the seed study);
  * the film resolution, taken from --resolution;
  * the integrator: `path`, max_depth 8 and rr_depth 5 (Mitsuba's default, written
    out explicitly so a change of default upstream cannot change our reference).

Output: a float32 RGB OpenEXR (--out), row 0 at the top, red wall on the left
(Mitsuba's own image convention, which is also ours), and one JSON line on stdout:

  {"samples": ..., "seconds": ..., "samples_per_second": ..., ...}

`seconds` covers only the mi.render() calls (and forcing their result), never the
import, the variant set-up, the scene loading or the --warmup-spp render (an untimed
render first, in the same process, that takes the JIT compilation out of the timing).

Passes: with --passes K (or automatically for the LLVM variant, which otherwise
traces every sample of the image in one wavefront and runs out of memory at high
spp) the render is split into K independent renders of spp/K samples each, with
seeds seed, seed+1, ..., seed+K-1, averaged. With a box filter this is exactly the
average of all spp samples per pixel. Mitsuba's scalar variant seeds pixel p of a
W*H render with seed*W*H + p, so renders with different seeds never share a random
stream; choose seeds of different renders so that their ranges do not overlap.

Variants: scalar_rgb (the default; multi-threaded C++, no JIT) and llvm_rgb (an
alias for whichever of llvm_rgb / llvm_ad_rgb the installed wheel ships; vectorised
JIT, needs a system libLLVM: versions 14 and 15 abort inside code generation with
Mitsuba 3.9, 19 works). When DRJIT_LIBLLVM_PATH is unset this script picks the
newest libLLVM that the dynamic linker knows about (`ldconfig -p`).
"""

import argparse
import json
import os
import re
import subprocess
import sys
import time

from mitsuba_scenes import SCENES, scene_dict


def parse_resolution(text):
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"expected WxH (e.g. 256x256), got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise argparse.ArgumentTypeError(f"resolution {w}x{h} out of range 1..16384")
    return w, h


def positive_int(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def find_libllvm():
    """Newest libLLVM known to the dynamic linker, or None."""
    try:
        out = subprocess.run(["ldconfig", "-p"], capture_output=True, text=True,
                             check=False).stdout
    except OSError:
        return None
    best = None
    for line in out.splitlines():
        m = re.search(r"(libLLVM(?:-(\d+)(?:\.\d+)*)?\.so(?:\.(\d+))?[\w.]*)\s.*=>\s*(\S+)",
                      line)
        if not m:
            continue
        major = m.group(2) or m.group(3)
        if not major:
            continue
        cand = (int(major), m.group(4))
        if best is None or cand[0] > best[0]:
            best = cand
    return best[1] if best else None


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", choices=SCENES, default="cornell-box",
                    help="which of our scenes (default cornell-box)")
    ap.add_argument("--resolution", type=parse_resolution, default=(256, 256),
                    help="WxH (default 256x256)")
    ap.add_argument("--spp", type=positive_int, required=True, help="samples per pixel")
    ap.add_argument("--seed", type=int, default=0,
                    help="first seed (passes use seed..seed+passes-1); default 0")
    ap.add_argument("--variant", default="scalar_rgb",
                    choices=["scalar_rgb", "llvm_rgb"],
                    help="Mitsuba variant (default scalar_rgb)")
    ap.add_argument("--threads", type=positive_int, default=None,
                    help="worker threads (default: all cores)")
    ap.add_argument("--passes", type=positive_int, default=None,
                    help="split into this many equal passes (must divide spp); "
                         "default 1 for scalar, automatic for llvm")
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--rr-depth", type=int, default=5)
    ap.add_argument("--out", required=True, help="output .exr path")
    ap.add_argument("--max-seconds", type=float, default=None,
                    help="stop after the pass that takes the render time past this; the "
                         "image then has fewer spp than asked (reported as spp)")
    ap.add_argument("--warmup-spp", type=int, default=0,
                    help="render once at this spp first, untimed and discarded (for the "
                         "LLVM variant: JIT compilation out of the timing); default 0: none")
    ap.add_argument("--progress", action="store_true",
                    help="print per-pass progress to stderr")
    args = ap.parse_args(argv)

    w, h = args.resolution
    if not (0 <= args.seed < 2**32):
        ap.error("--seed must be in [0, 2^32)")

    passes = args.passes
    if passes is None:
        passes = 1
        if args.variant != "scalar_rgb":
            # Keep one wavefront at <= 2^23 samples (about 2-3 GiB of JIT state).
            budget = 1 << 23
            while w * h * (args.spp // passes) > budget and args.spp % (passes * 2) == 0:
                passes *= 2
    if args.spp % passes != 0:
        ap.error(f"--passes {passes} does not divide --spp {args.spp}")
    spp_per_pass = args.spp // passes
    if args.variant == "scalar_rgb" and (args.seed + passes + (args.warmup_spp > 0)) * w * h >= 2**32:
        ap.error("seed too large: Mitsuba's scalar variant seeds pixels with seed*W*H+p "
                 "in 32 bits, so (seed+passes)*W*H must stay below 2^32")

    if args.variant != "scalar_rgb" and not os.environ.get("DRJIT_LIBLLVM_PATH"):
        lib = find_libllvm()
        if lib:
            os.environ["DRJIT_LIBLLVM_PATH"] = lib

    import numpy as np
    import drjit as dr
    import mitsuba as mi

    variant = args.variant
    if variant == "llvm_rgb" and "llvm_rgb" not in mi.variants():
        variant = "llvm_ad_rgb"
    if variant not in mi.variants():
        print(f"error: Mitsuba variant {variant} is not available "
              f"(have: {', '.join(mi.variants())})", file=sys.stderr)
        return 2
    mi.set_variant(variant)
    threads = args.threads or os.cpu_count() or 1
    dr.set_thread_count(threads)

    scene_desc = scene_dict(mi, args.scene)
    film = scene_desc["sensor"]["film"]
    film["rfilter"] = {"type": "box"}
    film["width"], film["height"] = w, h
    scene_desc["sensor"]["sampler"] = {"type": "independent", "sample_count": spp_per_pass}
    scene_desc["integrator"] = {"type": "path", "max_depth": args.max_depth,
                                "rr_depth": args.rr_depth}
    scene = mi.load_dict(scene_desc)

    warmup_seconds = None
    if args.warmup_spp > 0:
        # Same process, same scene: Dr.Jit compiles (or loads from its kernel cache) the
        # path tracer here; a seed outside every timed pass's, and the image is dropped.
        seed_arg = args.seed + passes
        if not variant.startswith("scalar"):
            seed_arg = dr.opaque(mi.UInt32, seed_arg)
        t0 = time.perf_counter()
        img = mi.render(scene, spp=args.warmup_spp, seed=seed_arg)
        dr.eval(img)
        dr.sync_thread()
        warmup_seconds = time.perf_counter() - t0
        del img

    accum = np.zeros((h, w, 3), dtype=np.float64)
    seconds = 0.0
    passes_done = 0
    for i in range(passes):
        seed = args.seed + i
        if variant.startswith("scalar"):
            seed_arg = seed
        else:
            # Opaque, so every pass reuses the first pass's compiled kernel.
            seed_arg = dr.opaque(mi.UInt32, seed)
        t0 = time.perf_counter()
        img = mi.render(scene, spp=spp_per_pass, seed=seed_arg)
        dr.eval(img)
        dr.sync_thread()
        seconds += time.perf_counter() - t0
        arr = np.array(img, dtype=np.float64)
        if arr.shape != (h, w, 3):
            print(f"error: unexpected image shape {arr.shape}", file=sys.stderr)
            return 2
        accum += arr
        passes_done += 1
        if args.progress:
            print(f"pass {i + 1}/{passes} seed {seed}: {seconds:.1f} s so far",
                  file=sys.stderr, flush=True)
        if args.max_seconds is not None and seconds >= args.max_seconds:
            break
    image = (accum / passes_done).astype(np.float32)
    spp_done = passes_done * spp_per_pass

    out_dir = os.path.dirname(os.path.abspath(args.out))
    os.makedirs(out_dir, exist_ok=True)
    # Mitsuba's EXR writer hangs when the thread pool has a single thread
    # (seen with Mitsuba 3.9.1), so writing always gets at least two.
    dr.set_thread_count(max(threads, 2))
    bmp = mi.Bitmap(np.ascontiguousarray(image), mi.Bitmap.PixelFormat.RGB)
    bmp.write(args.out)

    samples = w * h * spp_done
    print(json.dumps({
        "samples": samples,
        "seconds": seconds,
        "samples_per_second": samples / seconds if seconds > 0 else None,
        "renderer": "mitsuba",
        "scene": args.scene,
        "mitsuba_version": mi.__version__,
        "variant": variant,
        "resolution": [w, h],
        "spp": spp_done,
        "spp_requested": args.spp,
        "seed": args.seed,
        "passes": passes_done,
        "spp_per_pass": spp_per_pass,
        "threads": threads,
        "max_depth": args.max_depth,
        "rr_depth": args.rr_depth,
        "warmup_spp": args.warmup_spp,
        "warmup_seconds": warmup_seconds,
        "output": args.out,
    }), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
