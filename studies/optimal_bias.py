"""The image mean of optimal and its variants against the reference, and their E.

docs/RESULTS.md, "Is `optimal` biased low": each variant renders cornell-box and
cornell-caustics at 128x128 for seeds 1..SEEDS at each budget; for each it prints the image
mean's difference from the 8192-spp reference's (mean over seeds, and the seeds' range) and
E (mean |image - reference| over pixels and RGB, as the study measures it). A render's mean
is the mean of 16384 pixels, so a bias of a per cent stands far outside one seed's noise on
the box; on caustics uniform's means spread by about ±1 % around the reference.

Usage (Mitsuba's Python reads the EXR files: scripts/install-deps.sh puts it in .venv):

    .venv/bin/python studies/optimal_bias.py build/bin/aliquot 6 16,64 \\
        uniform=uniform optimal=optimal "s0=optimal --steer-rounds 0" \\
        "r1=optimal --sigma-radius 1" oracle=oracle

A variant is LABEL=METHOD followed by any `aliquot render` options. The references come
from `aliquot reference` (cached, 8192 spp, seed 2^40); `oracle` is steered by a 2048-spp
render of seed 2^40 + 1, rendered once into the output directory.
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
SCENES = ["cornell-box", "cornell-caustics"]
SIZE = "128x128"


def aliquot_json(aliquot, *args):
    out = subprocess.run([aliquot, *args, "--json"], check=True, capture_output=True,
                         text=True).stdout
    return json.loads(out)


def rgb(path):
    return np.array(mi.Bitmap(path))[..., :3].astype(np.float64)


def main():
    aliquot, seeds = sys.argv[1], int(sys.argv[2])
    budgets = [int(s) for s in sys.argv[3].split(",")]
    variants = [v.split("=", 1) for v in sys.argv[4:]]
    work = tempfile.mkdtemp(prefix="optimal-bias-")
    for scene in SCENES:
        ref_path = os.path.join(work, f"{scene}-reference.exr")
        aliquot_json(aliquot, "reference", "--scene", scene, "--resolution", SIZE,
                     "--out", ref_path)
        ref = rgb(ref_path)
        sigma = os.path.join(work, f"{scene}-sigma.exr")
        if any(spec.split()[0] == "oracle" for _, spec in variants):
            aliquot_json(aliquot, "render", "--scene", scene, "--resolution", SIZE,
                         "--spp", "2048", "--seed", str(2**40 + 1), "--aovs", "--out",
                         sigma)
        for spp in budgets:
            rows = {label: [] for label, _ in variants}
            # Seed by seed, every variant in turn: a change of load falls on all alike.
            for seed in range(1, seeds + 1):
                for label, spec in variants:
                    method, *extra = spec.split()
                    out = os.path.join(work, "render.exr")
                    oracle = ["--sigma", sigma] if method == "oracle" else []
                    aliquot_json(aliquot, "render", "--scene", scene, "--resolution", SIZE,
                                 "--spp", str(spp), "--method", method, "--seed",
                                 str(seed), "--threads", "1", "--out", out, *oracle,
                                 *extra)
                    image = rgb(out)
                    rows[label].append(
                        (image.mean() / ref.mean() - 1, np.abs(image - ref).mean()))
            for label, r in rows.items():
                bias = [b for b, _ in r]
                e = [x for _, x in r]
                print(f"{scene:17s} {spp:4d} spp {label:10s} mean "
                      f"{100 * statistics.mean(bias):+6.2f} % (seeds "
                      f"{100 * min(bias):+.2f} .. {100 * max(bias):+.2f})  E "
                      f"{statistics.mean(e):.5f} ± {statistics.stdev(e):.5f}", flush=True)


if __name__ == "__main__":
    main()
