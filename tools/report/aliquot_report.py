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
import re
import sqlite3
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
from bias_table import BIAS, DENOISED_BIAS, bias_cells, bias_note, fmt_bias, measured, point_bias  # noqa: E402

METRICS = ["mean_abs", "rmse", "relative_mse", "max_bucket", "p99_bucket"]
# After Open Image Denoise, for a study with "denoise" (NaN for any other).
DENOISED = ["denoised_mean_abs", "denoised_rmse", "denoised_relative_mse"]
COLORS = {
    "uniform": "#4c72b0",
    "dammertz": "#dd8452",
    "adaptive": "#55a868",
    "optimal": "#c44e52",
    "optimal-time": "#8172b3",
    "oracle": "#222222",
    "cycles": "#937860",
}


# ---------------------------------------------------------------------------- data


def safe_name(key):
    """The file name the study command gives a render's maps (same rule as in C++)."""
    return re.sub(r"[^A-Za-z0-9.\-]", "_", key)


class Render:
    """One study render (one key): its spec and what it measured."""

    def __init__(self, row):
        self.key = row["render_key"]
        self.group, index, seed = self.key.rsplit("/", 2)
        self.index, self.seed = int(index), int(seed)
        spec = json.loads(row["spec_json"])
        self.scene, self.width, self.height = spec["scene"], spec["width"], spec["height"]
        self.strategy = spec["strategy"]
        self.method = self.strategy["method"]
        self.samples, self.rays = row["samples"], row["rays"]
        self.seconds, self.sps = row["seconds"], row["samples_per_second"]
        for m in METRICS:
            v = row[m]
            setattr(self, m, float("nan") if v is None else v)
        for m in DENOISED + BIAS + DENOISED_BIAS:  # older databases lack these columns
            v = row[m] if m in row.keys() else None
            setattr(self, m, float("nan") if v is None else v)
        self.outcome = json.loads(row["outcome_json"] or "{}")
        self.render_id = row["render_id"]
        self.origin = row["origin"]

    @property
    def pixels(self):
        return self.width * self.height


class Point:
    """The renders of one group at one sweep position, over their seeds."""

    def __init__(self, renders):
        self.renders = sorted(renders, key=lambda r: r.seed)
        self.first = self.renders[0]
        self.n = len(self.renders)

    def mean(self, attr):
        return float(np.mean([getattr(r, attr) for r in self.renders]))

    def sd(self, attr):
        vals = [getattr(r, attr) for r in self.renders]
        return float(np.std(vals, ddof=1)) if len(vals) > 1 else 0.0

    def param(self, name):
        if name == "method":
            return self.first.method
        if name == "seed":
            return ",".join(str(r.seed) for r in self.renders)
        return self.first.strategy.get(name)


class Study:
    def __init__(self, db, study_id):
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
        con.row_factory = sqlite3.Row
        row = con.execute("SELECT * FROM studies WHERE id = ?", (study_id,)).fetchone()
        if row is None:
            raise SystemExit(f"aliquot report: no study {study_id!r} in {db}")
        stored = json.loads(row["definition_json"])
        self.id = study_id
        self.definition = stored["definition"]
        self.scale = stored["scale"]
        self.study_file = stored.get("study_file", "")
        rows = con.execute(
            "SELECT * FROM study_results WHERE study_id = ? AND state = 'done' ORDER BY rowid",
            (study_id,),
        ).fetchall()
        self.renders = [Render(r) for r in rows]
        self.groups = {}
        for r in self.renders:
            self.groups.setdefault(r.group, {}).setdefault(r.index, []).append(r)
        con.close()
        self.group_defs = {g["name"]: g for g in self.definition["renders"]}

    def points(self, group):
        """The group's sweep positions in order, each over its seeds."""
        by_index = self.groups.get(group, {})
        return [Point(by_index[i]) for i in sorted(by_index)]

    def method(self, group):
        pts = self.points(group)
        return pts[0].first.method if pts else self.group_defs[group]["method"]

    def label(self, group, groups):
        """The method name, or the group name where two groups share a method."""
        m = self.method(group)
        if sum(1 for g in groups if self.method(g) == m) > 1:
            return group
        return m


# ---------------------------------------------------------------------------- formatting


def fmt(v, digits=4):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, int):
        return f"{v:,}"
    if v == 0:
        return "0"
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    if abs(v) >= 100:
        return f"{v:.1f}"
    return f"{v:.{digits}g}"


def fmt_err(p, attr="mean_abs"):
    m = p.mean(attr)
    if p.n > 1:
        return f"{m:.6f} ± {p.sd(attr):.6f}"
    return f"{m:.9f}" if attr == "mean_abs" else f"{m:.6g}"


def md_table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for r in rows:
        out.append("| " + " | ".join(r) + " |")
    return "\n".join(out)


# ---------------------------------------------------------------------------- tables


def sweep_table(study, t):
    pts = study.points(t["group"])
    cols = t.get("columns", [])
    seeds = pts[0].n if pts else 1
    err_head = "avg error per pixel (E)" + (f", mean ± sd of {seeds} seeds" if seeds > 1 else "")
    header = cols + [err_head, "mean bias", "RMSE", "p99 bucket E", "max bucket E", "time (s)", "budget",
                     "samples/s"]
    rows = []
    for p in pts:
        rows.append(
            [fmt(p.param(c)) for c in cols]
            + [
                fmt_err(p),
                fmt_bias(point_bias(p)),
                fmt(p.mean("rmse")),
                fmt(p.mean("p99_bucket")),
                fmt(p.mean("max_bucket")),
                f"{p.mean('seconds'):.2f}",
                fmt(int(round(p.mean("samples")))),
                fmt(p.mean("sps")),
            ]
        )
    return md_table(header, rows)


def compare_table(study, t):
    groups = t["compare"]
    series = {g: study.points(g) for g in groups}
    n = min(len(v) for v in series.values()) if series else 0
    labels = [study.label(g, groups) for g in groups]
    header = ["budget"] + labels
    rows, detail = [], []
    for i in range(n):
        budget = np.mean([series[g][i].mean("samples") for g in groups])
        rows.append([fmt(int(round(budget)))] + [fmt_err(series[g][i]) for g in groups])
        for g, lab in zip(groups, labels):
            p = series[g][i]
            detail.append(
                [
                    fmt(int(round(budget))),
                    lab,
                    fmt_err(p),
                    fmt_bias(point_bias(p)),
                    fmt(p.mean("rmse")),
                    fmt(p.mean("p99_bucket")),
                    fmt(p.mean("max_bucket")),
                    f"{p.mean('seconds'):.2f}",
                    fmt(int(round(p.mean("samples")))),
                    fmt(p.mean("sps")),
                ]
            )
    dh = ["budget", "method", "E", "mean bias", "RMSE", "p99 bucket E", "max bucket E", "time (s)", "samples",
          "samples/s"]
    out = md_table(header, rows)
    if measured(series, groups, n):
        out += "\n\n" + bias_note() + "\n\n" + md_table(header, [[rows[i][0]] + bias_cells(series, groups, i)
                                                                 for i in range(n)])
    if n and all(not np.isnan(series[g][i].mean("denoised_mean_abs")) for g in groups for i in range(n)):
        out += "\n\n" + denoised_tables(series, groups, labels, header, n)
    oracle = [g for g in groups if study.method(g) == "oracle"]
    if oracle and n:
        out += "\n\nE ÷ oracle E at the same budget and seed (mean over seeds; worst seed):\n\n"
        ratio_rows = []
        for i in range(n):
            budget = np.mean([series[g][i].mean("samples") for g in groups])
            ratio_rows.append(
                [fmt(int(round(budget)))]
                + [fmt_ratio(oracle_ratios(series[g][i], series[oracle[0]][i])) for g in groups]
            )
        out += md_table(header, ratio_rows)
    return out + "\n\nAll metrics:\n\n" + md_table(dh, detail)


def denoised_tables(series, groups, labels, header, n):
    """A study that denoises: E after denoising as the raw table has it, each group's E
    over the first group's (raw and denoised, mean over seeds of the per-seed ratio), and
    every metric raw and denoised."""
    base = groups[0]
    rows, ratio_rows, detail = [], [], []
    for i in range(n):
        budget = fmt(int(round(np.mean([series[g][i].mean("samples") for g in groups]))))
        rows.append([budget] + [fmt_err(series[g][i], "denoised_mean_abs") for g in groups])
        cells = [budget]
        for g in groups:
            raw = same_seed_ratios(series[g][i], series[base][i], "mean_abs")
            den = same_seed_ratios(series[g][i], series[base][i], "denoised_mean_abs")
            cells.append(f"{np.mean(raw):.3f} / {np.mean(den):.3f}" if raw and den else "–")
        ratio_rows.append(cells)
        for g, lab in zip(groups, labels):
            p = series[g][i]
            detail.append(
                [budget, lab]
                + [fmt(p.mean(m)) for m in ["mean_abs", "rmse", "relative_mse"] + DENOISED]
            )
    out = "E after denoising (Open Image Denoise, colour + albedo + normal):\n\n" + md_table(header, rows)
    if measured(series, groups, n, "denoised_mean_bias"):
        out += "\n\n" + bias_note("the denoised image") + "\n\n" + md_table(
            header, [[rows[i][0]] + bias_cells(series, groups, i, "denoised_mean_bias") for i in range(n)])
    out += (
        f"\n\nE ÷ {labels[0]}'s E at the same budget and seed, raw / denoised (mean over seeds):\n\n"
        + md_table(header, ratio_rows)
    )
    dh = ["budget", "method", "E", "RMSE", "relMSE", "E denoised", "RMSE denoised", "relMSE denoised"]
    return out + "\n\nRaw and denoised:\n\n" + md_table(dh, detail)


def same_seed_ratios(point, base, attr):
    """attr of each seed's render over base's for the same seed."""
    by_seed = {r.seed: getattr(r, attr) for r in base.renders}
    return [getattr(r, attr) / by_seed[r.seed] for r in point.renders if by_seed.get(r.seed, 0) > 0]


def oracle_ratios(point, bound):
    """E of each seed's render over the bound's (oracle's) E for the same seed."""
    by_seed = {r.seed: r.mean_abs for r in bound.renders}
    return [r.mean_abs / by_seed[r.seed] for r in point.renders if by_seed.get(r.seed, 0) > 0]


def fmt_ratio(ratios):
    if not ratios:
        return "–"
    return f"{np.mean(ratios):.3f} ({max(ratios):.3f})" if len(ratios) > 1 else f"{ratios[0]:.3f}"


# ---------------------------------------------------------------------------- charts


def save(fig, out, name):
    os.makedirs(os.path.join(out, "charts"), exist_ok=True)
    paths = []
    for ext in ("svg", "png"):
        path = os.path.join(out, "charts", f"{name}.{ext}")
        # No timestamps in the SVG: the same data gives the same file.
        fig.savefig(path, dpi=110, bbox_inches="tight", metadata={"Date": None} if ext == "svg" else None)
        paths.append(path)
    plt.close(fig)
    return f"charts/{name}.svg"


def color(study, group, groups, i):
    # One colour per method; two groups of one method differ by line style (equal time
    # dashed) or, failing that, by a colour of their own.
    m = study.method(group)
    same = [g for g in groups if study.method(g) == m]
    if m in COLORS and len({style(study, g) for g in same}) == len(same):
        return COLORS[m]
    return plt.get_cmap("tab10")(i % 10)


def style(study, group):
    # Equal-time groups dashed, so they stand apart from the same method at equal budget.
    src = study.group_defs[group].get("budget_from")
    return "--" if isinstance(src, dict) and src.get("match") == "seconds" else "-"


def chart_error_vs_budget(study, c, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    groups = c["groups"]
    anchor = None
    for i, g in enumerate(groups):
        pts = study.points(g)
        if not pts:
            continue
        x = [p.mean("samples") for p in pts]
        y = [p.mean("mean_abs") for p in pts]
        order = np.argsort(x)
        x, y = np.array(x)[order], np.array(y)[order]
        ax.plot(x, y, style(study, g), marker="o", ms=4, color=color(study, g, groups, i), label=study.label(g, groups))
        if anchor is None:
            anchor = (x[0], y[0])
    if anchor:
        allx = [p.mean("samples") for g in groups for p in study.points(g)]
        xs = np.geomspace(min(allx), max(allx), 20)
        ax.plot(xs, anchor[1] * np.sqrt(anchor[0] / xs), ":", color="gray", label="1/√N slope")
    ax.set_xscale("log")
    return finish_chart(fig, ax, c, out, "samples (budget)", "E: mean |image − reference| per pixel",
                        "Error against budget")


def pareto(points):
    """Indices of the points no other point beats in both time and error."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], float("inf")
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def chart_error_vs_time(study, c, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    groups = c["groups"]
    every = []
    for i, g in enumerate(groups):
        pts = study.points(g)
        if not pts:
            continue
        x = np.array([p.mean("seconds") for p in pts])
        y = np.array([p.mean("mean_abs") for p in pts])
        order = np.argsort(x)
        ax.plot(x[order], y[order], style(study, g), marker="o", ms=4, color=color(study, g, groups, i), label=study.label(g, groups))
        every += list(zip(x, y))
    if every:
        front = pareto(every)
        fx = [every[i][0] for i in front]
        fy = [every[i][1] for i in front]
        ax.step(fx, fy, where="post", color="black", lw=1, alpha=0.6, label="Pareto front")
        ax.scatter(fx, fy, s=90, facecolors="none", edgecolors="black", zorder=5)
    ax.set_xscale("log")
    return finish_chart(fig, ax, c, out, "wall time (s)", "E", "Speed against accuracy")


def finish_chart(fig, ax, c, out, xlabel, ylabel, default_title):
    """The end every error chart shares: log error axis, labels, grid, legend, files."""
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(c.get("title", default_title))
    ax.grid(True, which="both", alpha=0.3)
    legend(ax)
    return save(fig, out, c["name"])


def legend(ax):
    # Beside the plot when it would cover the data.
    if len(ax.get_legend_handles_labels()[0]) > 5:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    else:
        ax.legend(fontsize=8)


def tonemap(rgb):
    return np.clip(rgb / (1.0 + rgb), 0, 1) ** (1 / 2.2)


def chart_maps(study, c, out, data_dir):
    groups = c["groups"]
    rows = []
    for g in groups:
        pts = study.points(g)
        if c["index"] >= len(pts):
            continue
        r = pts[c["index"]].first
        path = os.path.join(data_dir, "maps", safe_name(r.key) + ".npy")
        if os.path.exists(path):
            rows.append((g, r, np.load(path)))
    if not rows:
        return None
    spp_max = max(float(m[..., 3].max()) for _, _, m in rows) or 1.0
    spp_min = max(1.0, min(float(m[..., 3][m[..., 3] > 0].min()) if (m[..., 3] > 0).any() else 1.0 for _, _, m in rows))
    err_max = max(float(np.percentile(m[..., 4], 99.5)) for _, _, m in rows) or 1.0
    fig, axes = plt.subplots(len(rows), 3, figsize=(9.6, 3.2 * len(rows)), squeeze=False)
    for (g, r, m), ax in zip(rows, axes):
        ax[0].imshow(tonemap(m[..., :3]), interpolation="nearest")
        ax[0].set_ylabel(f"{study.label(g, groups)}\n{r.samples:,} samples", fontsize=9)
        # Log colours only where the counts span a range worth it.
        norm = (matplotlib.colors.LogNorm(vmin=spp_min, vmax=spp_max) if spp_max > 4 * spp_min
                else matplotlib.colors.Normalize(vmin=0, vmax=max(spp_max, 1.0)))
        im1 = ax[1].imshow(np.maximum(m[..., 3], spp_min), cmap="viridis", norm=norm,
                           interpolation="nearest")
        im2 = ax[2].imshow(m[..., 4], cmap="inferno", vmin=0, vmax=err_max, interpolation="nearest")
        fig.colorbar(im1, ax=ax[1], fraction=0.046, pad=0.04)
        fig.colorbar(im2, ax=ax[2], fraction=0.046, pad=0.04)
        ax[1].set_title(f"samples per pixel (max {int(m[..., 3].max()):,})", fontsize=9)
        ax[2].set_title(f"|image − reference|, E = {r.mean_abs:.5f}", fontsize=9)
        for a in ax:
            a.set_xticks([])
            a.set_yticks([])
    fig.suptitle(c.get("title", "Where the samples went"))
    return save(fig, out, c["name"])


def chart_seed_spread(study, c, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    groups = c["groups"]
    for i, g in enumerate(groups):
        pts = study.points(g)
        if not pts:
            continue
        shift = 1.0 + 0.03 * (i - (len(groups) - 1) / 2)  # side by side on a log axis
        x = np.array([p.mean("samples") for p in pts]) * shift
        y = np.array([p.mean("mean_abs") for p in pts])
        e = np.array([p.sd("mean_abs") for p in pts])
        ax.errorbar(x, y, yerr=e, fmt=style(study, g) + "o", ms=4, capsize=3, color=color(study, g, groups, i),
                    label=f"{study.label(g, groups)} ({pts[0].n} seeds)")
    ax.set_xscale("log")
    return finish_chart(fig, ax, c, out, "samples (budget)", "E, mean ± standard deviation over seeds",
                        "Spread of the error over seeds")


def chart_sweep(study, c, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    groups, param = c["groups"], c["param"]
    for i, g in enumerate(groups):
        pts = study.points(g)
        if not pts:
            continue
        x = np.array([float(p.param(param)) for p in pts])
        y = np.array([p.mean("mean_abs") for p in pts])
        ax.plot(x, y, "-o", ms=4, color=color(study, g, groups, i), label=study.label(g, groups))
        if x.min() > 0 and x.max() / x.min() > 10:
            ax.set_xscale("log")
    return finish_chart(fig, ax, c, out, param, "E", f"Error against {param}")


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
