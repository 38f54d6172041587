#!/usr/bin/env python3
"""The equal-budget tables of docs/RESULTS.md from a speed-vs-accuracy study's database:
per scene, one row per budget, each method's E as mean ± standard deviation over the seeds
and its mean wall time.

    results_table.py --db OUT/data/aliquot.db --study speed-vs-accuracy@full
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from aliquot_report import Study, md_table  # noqa: E402

METHODS = ["uniform", "dammertz", "adaptive", "optimal", "optimal-time"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", required=True)
    ap.add_argument("--study", required=True)
    ap.add_argument("--scenes", default="box,caustics", help="group name prefixes")
    args = ap.parse_args()
    study = Study(args.db, args.study)
    for prefix in args.scenes.split(","):
        groups = {m: f"{prefix}-{m}" for m in METHODS}
        pts = {m: study.points(g) for m, g in groups.items()}
        scene = pts["dammertz"][0].first.scene
        w, h = pts["dammertz"][0].first.width, pts["dammertz"][0].first.height
        seeds = pts["dammertz"][0].n
        print(f"### {scene}, {w}x{h}, {seeds} seeds\n")
        head = ["budget (spp)"] + [f"{m} E" for m in METHODS] + ["wall s: " + " / ".join(m[:4] for m in METHODS)]
        rows = []
        for i, d in enumerate(pts["dammertz"]):
            spp = d.mean("samples") / d.first.pixels
            best = min(METHODS, key=lambda m: pts[m][i].mean("mean_abs"))
            cells = []
            for m in METHODS:
                p = pts[m][i]
                cell = f"{p.mean('mean_abs'):.5f} ± {p.sd('mean_abs'):.5f}"
                cells.append(f"**{cell}**" if m == best else cell)
            times = " / ".join(f"{pts[m][i].mean('seconds'):.2f}" for m in METHODS)
            rows.append([f"{spp:.1f}"] + cells + [times])
        print(md_table(head, rows))
        print()


if __name__ == "__main__":
    main()
