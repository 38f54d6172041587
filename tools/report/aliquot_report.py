#!/usr/bin/env python3
"""The report of an `aliquot study`: reads the study's SQLite database and writes
OUT/report.md, OUT/results.csv and OUT/charts/*.svg|png (see docs/STUDIES.md).

    aliquot_report.py --db OUT/data/aliquot.db --study NAME@SCALE --out OUT

Exit status 3 when numpy or matplotlib is missing (the study command runs it with the first
python3 that has both, and otherwise names scripts/install-deps.sh).
"""
import argparse
import csv
import json
import math
import os
import sys

try:
    import numpy as np
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError as e:  # the study command turns status 3 into an install hint
    print(f"aliquot report: {e.name} is not installed for {sys.executable}", file=sys.stderr)
    sys.exit(3)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bias_table import BIAS, DENOISED_BIAS  # noqa: E402
# Study and md_table are also results_table.py's; plt, COLORS and save bench/equal_time.py's.
from study_charts import (COLORS, chart_error_vs_budget, chart_error_vs_time, chart_maps,  # noqa: E402,F401
                          chart_seed_spread, chart_sweep, save)
from study_data import DENOISED, METRICS, Study  # noqa: E402
from study_tables import compare_table, fmt, fmt_ratio, md_table, oracle_ratios, sweep_table  # noqa: E402,F401


# ---------------------------------------------------------------------------- conclusions


def conclude_uniform_slope(study, c):
    pts = study.points(c["group"])
    if len(pts) < 3:
        return "not enough points to fit", None
    # Points a scale rounded to the same spp are one point.
    seen = {}
    for p in pts:
        seen.setdefault(p.mean("samples") / p.first.pixels, p.mean("mean_abs"))
    spp = np.array(sorted(seen))
    e = np.array([seen[x] for x in spp])
    ref_spp = study.scale.get("reference_spp", 8192)
    # The fit leaves out points within 4x of the reference's spp: there the reference's own
    # noise is a large part of the measured difference.
    keep = spp * 4 <= ref_spp
    slope = float(np.polyfit(np.log(spp[keep]), np.log(e[keep]), 1)[0]) if keep.sum() >= 2 else float("nan")
    local = [float(np.log(e[i + 1] / e[i]) / np.log(spp[i + 1] / spp[i])) for i in range(len(spp) - 1)]
    holds = -0.6 <= slope <= -0.4
    # Against a reference of R spp, an n-spp image's measured E is about c*sqrt(1/n + 1/R):
    # the floor the curve bends towards.
    cfit = float(np.exp(np.mean(np.log(e[keep]) + 0.5 * np.log(spp[keep])))) if keep.any() else float("nan")
    floor = cfit * math.sqrt(2.0 / ref_spp)
    text = (
        f"Fitted slope of log E against log spp (spp ≤ {ref_spp // 4}): **{slope:.3f}** (1/√N is −0.5). "
        f"Local slopes between successive spp: {', '.join(f'{s:.2f}' for s in local)}. "
        f"E from {fmt(e[0])} at {fmt(spp[0])} spp to {fmt(e[-1])} at {fmt(spp[-1])} spp; "
        f"each 4× more samples divides E by {4 ** -slope:.2f} on the fitted line (1/√N: 2). "
    )
    if local and local[-1] > -0.4:
        text += (
            f"The last step flattens because the reference is itself a {ref_spp}-spp render: "
            f"a render at the reference's spp measures about √2 times the reference noise "
            f"(predicted floor {floor:.2g}, measured {fmt(e[-1])}); the seed reported 0 there only "
            f"because its 8192-spp point *was* its reference. "
        )
    return text, holds


def conclude_beats(study, c):
    w, l = study.points(c["winner"]), study.points(c["loser"])
    n = min(len(w), len(l))
    wins, parts, why = 0, [], []
    for i in range(n):
        ew, el = w[i].mean("mean_abs"), l[i].mean("mean_abs")
        budget = int(round(l[i].mean("samples")))
        if ew < el:
            wins += 1
        parts.append(f"{fmt(budget)}: {ew:.6f} vs {el:.6f} ({(ew / el - 1) * 100:+.1f} %)")
        s = w[i].first.strategy
        if s.get("method") == "adaptive" and s.get("initial_spp", 0) * w[i].first.pixels >= budget:
            why.append(fmt(budget))
    holds = wins == n and n > 0
    text = (
        f"{study.label(c['winner'], [c['winner']])} has the lower E at **{wins} of {n}** budgets "
        f"(E {c['winner']} vs {c['loser']}, change): " + "; ".join(parts) + ". "
    )
    if why:
        text += (
            f"At budget {', '.join(why)} the initial uniform pass already spends the whole budget, "
            "so adaptive *is* uniform there and any difference is only noise. "
        )
    if n and w[0].n > 1:
        sd = np.mean([w[i].sd("mean_abs") / max(w[i].mean("mean_abs"), 1e-30) for i in range(n)])
        text += f"Seed-to-seed spread of E is about {sd * 100:.1f} % (relative sd), so smaller differences are noise. "
    return text, holds


def conclude_near_bound(study, c):
    """`group` within `within` (a fraction) of the `bound` group's E at every budget, seed by seed."""
    g, b = study.points(c["group"]), study.points(c["bound"])
    within = float(c.get("within", 0.05))
    n = min(len(g), len(b))
    ok, parts = 0, []
    for i in range(n):
        ratios = oracle_ratios(g[i], b[i])
        worst = max(ratios) if ratios else float("inf")
        ok += worst <= 1 + within
        parts.append(f"{fmt(int(round(b[i].mean('samples'))))}: {fmt_ratio(ratios)}")
    # The check is one-sided, and "within 0 %" (never above the bound) read as a typo.
    text = (
        f"E ÷ {c['bound']} E at most {1 + within:g} for every seed at **{ok} of {n}** budgets "
        "(mean over seeds, worst seed in brackets): " + "; ".join(parts) + ". "
    )
    return text, ok == n and n > 0


def conclude_beats_every_seed(study, c):
    w, l = study.points(c["winner"]), study.points(c["loser"])
    n = min(len(w), len(l))
    wins = total = 0
    for i in range(n):
        ratios = oracle_ratios(w[i], l[i])
        wins += sum(1 for r in ratios if r < 1)
        total += len(ratios)
    return (
        f"{c['winner']} has the lower E in **{wins} of {total}** (budget, seed) pairs. ",
        wins == total and total > 0,
    )


def conclude_loses_bounds(study, c):
    d = study.points(c["group"])
    others = c["groups"]
    loses, pairs, bounds, ties, parts = 0, 0, 0, 0, []
    for i, p in enumerate(d):
        ed, md = p.mean("mean_abs"), p.mean("max_bucket")
        row = [f"{fmt(int(round(p.mean('samples'))))}: E {ed:.6f}, max bucket {md:.4f}"]
        for g in others:
            q = study.points(g)
            if i >= len(q):
                continue
            eo, mo = q[i].mean("mean_abs"), q[i].mean("max_bucket")
            if abs(ed - eo) <= 1e-12 * max(ed, eo):
                ties += 1  # the same image: e.g. Dammertz converged in its first, uniform round
                continue
            pairs += 1
            loses += ed > eo
            bounds += md <= mo
            row.append(f"{study.label(g, others)} E {eo:.6f}, max {mo:.4f}")
        parts.append(" / ".join(row))
    capped = [p for p in d if p.first.outcome.get("stopped_by") not in (None, "converged")]
    text = (
        f"Dammertz has the higher E in **{loses} of {pairs}** equal-budget pairs and the lower (or equal) "
        f"worst-bucket error in **{bounds} of {pairs}**"
        + (f" ({ties} pairs left out: the same image, where Dammertz stopped after its first, uniform round)" if ties else "")
        + ". Per budget: " + "; ".join(parts) + ". "
    )
    if capped:
        fr = [f"{p.first.outcome.get('stopped_by')} at {fmt(int(round(p.mean('samples'))))} "
              f"({p.first.outcome.get('converged_fraction', 0) * 100:.1f} % of pixels converged)" for p in capped]
        text += "Runs stopped by a cap rather than by E ≤ V: " + "; ".join(fr) + ". "
    text += (
        "Why it loses the mean: it stops sampling a bucket once its E ≤ V and pours samples into "
        "the few buckets that are hardest to converge (light edges, caustics), where each extra "
        "sample buys little mean error; uniform and adaptive spend those samples where they lower E most. "
    )
    first = loses / pairs if pairs else 0.0
    second = bounds / pairs if pairs else 0.0
    holds = True if first == 1 and second == 1 else (False if first < 0.5 and second < 0.5 else "partly")
    if holds == "partly":
        text += (
            f"So the claim holds in part: it loses at equal budget "
            f"{'everywhere' if first == 1 else f'in {loses} of {pairs} pairs'}, and its worst "
            f"bucket is {'no worse than the others everywhere' if second == 1 else f'no worse in {bounds} of {pairs} pairs'}. "
        )
    return text, holds


def monotone(values):
    """Spearman-like trend in [-1, 1] of a sequence against its position."""
    if len(values) < 2:
        return 0.0
    ranks = np.argsort(np.argsort(values))
    pos = np.arange(len(values))
    return float(np.corrcoef(ranks, pos)[0, 1])


def conclude_sweep(study, c):
    pts = study.points(c["group"])
    param = c["param"]
    xs = [p.param(param) for p in pts]
    es = [p.mean("mean_abs") for p in pts]
    if not pts:
        return "no renders", None
    best = int(np.argmin(es))
    spread = max(es) / min(es)
    trend = monotone(es)
    expect = c.get("expect", "")
    if expect == "increasing":
        holds = trend > 0.5 and es[-1] > es[0]
    elif expect == "decreasing":
        holds = trend < -0.5 and es[-1] < es[0]
    elif expect == "minimum_inside":
        holds = 0 < best < len(es) - 1
    elif expect == "flat":
        holds = spread < 1.1
    else:
        holds = None
    seeds = pts[0].n
    noise = ""
    if seeds > 1:
        rel = np.mean([p.sd("mean_abs") / p.mean("mean_abs") for p in pts])
        noise = f" Seed-to-seed sd is {rel * 100:.1f} % of E."
    text = (
        f"E against {param}: " + ", ".join(f"{fmt(x)} → {e:.6f}" for x, e in zip(xs, es))
        + f". Lowest at {param} = {fmt(xs[best])}; largest/smallest E = {spread:.2f}; trend {trend:+.2f}.{noise} "
    )
    return text, holds


def conclude_ranking(study, c):
    groups = c["groups"]
    series = {g: study.points(g) for g in groups}
    n = min((len(v) for v in series.values()), default=0)
    winners, parts = [], []
    for i in range(n):
        es = {g: series[g][i].mean("mean_abs") for g in groups}
        order = sorted(groups, key=lambda g: es[g])
        winners.append(order[0])
        parts.append(
            f"index {i}: " + " < ".join(f"{study.label(g, groups)} {es[g]:.6f}" for g in order)
        )
    expect = c.get("expect_winner")
    holds = None if not expect else all(w == expect for w in winners)
    text = "Ranking by E (lowest first) — " + "; ".join(parts) + ". "
    return text, holds


VERDICT = {True: "**holds**", False: "**does not hold**", None: "**not decided**"}


def conclusions(study):
    out = []
    for c in study.definition.get("conclusions", []):
        kind = c["kind"]
        if kind == "uniform_slope":
            text, holds = conclude_uniform_slope(study, c)
        elif kind == "beats_everywhere" and c.get("per_seed"):
            text, holds = conclude_beats_every_seed(study, c)
        elif kind == "beats_everywhere":
            text, holds = conclude_beats(study, c)
        elif kind == "near_bound":
            text, holds = conclude_near_bound(study, c)
        elif kind == "loses_but_bounds_worst":
            text, holds = conclude_loses_bounds(study, c)
        elif kind == "sweep_effect":
            text, holds = conclude_sweep(study, c)
        elif kind == "ranking":
            text, holds = conclude_ranking(study, c)
        else:
            continue
        verdict = "**partly holds**" if holds == "partly" else VERDICT[holds]
        note = c.get("why", {})
        branch = "partly" if holds == "partly" else ("holds" if holds else "fails")
        why = note.get(branch, "") if isinstance(note, dict) else str(note)
        out.append(f"- *{c['claim']}* — {verdict}. {text}{why}".rstrip())
    return out


# ---------------------------------------------------------------------------- main


def write_csv(study, path):
    metrics = METRICS + BIAS + (DENOISED + DENOISED_BIAS if study.definition.get("denoise") else [])
    fields = ["study", "key", "group", "index", "seed", "scene", "width", "height", "method",
              "strategy", "samples", "rays", "seconds", "samples_per_second"] + metrics + ["outcome", "render_id"]
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(fields)
        for r in study.renders:
            w.writerow([study.id, r.key, r.group, r.index, r.seed, r.scene, r.width, r.height, r.method,
                        json.dumps(r.strategy, sort_keys=True), r.samples, r.rays, f"{r.seconds:.4f}",
                        f"{r.sps:.1f}"] + [repr(getattr(r, m)) for m in metrics]
                       + [json.dumps(r.outcome, sort_keys=True), r.render_id])


def nbuckets(study):
    b = study.scale.get("metric_bucket", 16)
    r = study.renders[0]
    return math.ceil(r.width / b) * math.ceil(r.height / b)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", required=True)
    ap.add_argument("--study", required=True)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    plt.rcParams["svg.hashsalt"] = "aliquot"  # stable ids in the SVGs
    study = Study(args.db, args.study)
    os.makedirs(args.out, exist_ok=True)
    data_dir = os.path.dirname(os.path.abspath(args.db))
    write_csv(study, os.path.join(args.out, "results.csv"))

    d = study.definition
    sc = study.scale
    res = sorted({f"{r.scene} {r.width}x{r.height}" for r in study.renders})
    distinct = {r.render_id: r for r in study.renders}.values()  # shared renders once
    total_samples = sum(r.samples for r in distinct)
    total_seconds = sum(r.seconds for r in distinct)
    farm = any(r.origin.startswith("farm") for r in study.renders)
    side_text = f"longest side ≤ {sc['max_side']}" if sc["max_side"] else "resolution as written"
    md = [f"# Study `{d['name']}` at scale `{sc['name']}`", ""]
    if d.get("description"):
        md += [d["description"], ""]
    md += [
        f"- Study file: `{study.study_file}`; run: `aliquot study {study.study_file} --scale {sc['name']}`.",
        f"- Scale `{sc['name']}`: {side_text}, per-pixel sample counts × "
        f"{sc['spp_factor']:g} (Dammertz V × {1 / math.sqrt(sc['spp_factor']):.3g}), budgets × pixel ratio × {sc['spp_factor']:g}; "
        f"references: uniform {sc['reference_spp']} spp (own seed), cached.",
        f"- Scenes: {', '.join(res)}. Renders: {len(study.renders)} ({len({r.render_id for r in study.renders})} distinct), "
        f"{total_samples:,} samples, {total_seconds:.1f} s of render wall time (shared renders counted once).",
        "- E is the seed's error: mean |image − reference| per pixel, averaged over RGB. RMSE is over pixels and "
        f"channels; bucket errors are E over {sc.get('metric_bucket', 16)}×{sc.get('metric_bucket', 16)}-pixel buckets "
        "(16×16 at the written resolution, scaled with it; p99 = 99th percentile, max = worst bucket). "
        "The mean bias is the image's mean against the reference's, ± its standard error (from the spread of "
        "16×16-pixel blocks' means, so a denoiser's spread error is not taken for signal); E rewards an image too dark, so a method **biased** beyond 3 standard errors wins "
        "some of its E by it. "
        + ("Wall times are the farm's: renders ran in parallel and shared its workers. " if farm else
           "Wall times are each render's own (embedded renders run one at a time), measured on a machine "
           "shared with other work: read them as ±30 %.")
        + (f" At {study.renders[0].width}x{study.renders[0].height} there are only "
           f"{nbuckets(study)} buckets, so p99 is the max." if study.renders and nbuckets(study) < 100 else ""),
        "",
    ]
    for t in d.get("tables", []):
        md += [f"## {t['title']}", ""]
        if t.get("note"):
            md += [t["note"], ""]
        md += [sweep_table(study, t) if "group" in t else compare_table(study, t), ""]

    charts = []
    for c in d.get("charts", []):
        kind = c["kind"]
        if kind == "error_vs_budget":
            path = chart_error_vs_budget(study, c, args.out)
        elif kind == "error_vs_time":
            path = chart_error_vs_time(study, c, args.out)
        elif kind == "maps":
            path = chart_maps(study, c, args.out, data_dir)
        elif kind == "seed_spread":
            path = chart_seed_spread(study, c, args.out)
        elif kind == "sweep":
            path = chart_sweep(study, c, args.out)
        else:
            continue
        if path:
            charts.append((c.get("title", c["name"]), path))
    if charts:
        md += ["## Charts", ""]
        for title, path in charts:
            png = path[:-4] + ".png"
            md += [f"### {title}", "", f"![{title}]({path})", "", f"(PNG: [{png}]({png}))", ""]

    concl = conclusions(study)
    if concl:
        md += ["## The seed's conclusions against ours", ""] + concl + [""]
    with open(os.path.join(args.out, "report.md"), "w") as f:
        f.write("\n".join(md))


if __name__ == "__main__":
    main()
