"""The charts of a study report (SVG and PNG, matplotlib): error against budget and time,
the error maps, the seeds' spread, a sweep. Part of aliquot_report.py, which sets
matplotlib's backend before it is imported.
"""
import os
import re

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

COLORS = {
    "uniform": "#4c72b0",
    "dammertz": "#dd8452",
    "adaptive": "#55a868",
    "optimal": "#c44e52",
    "optimal-time": "#8172b3",
    "oracle": "#222222",
    "cycles": "#937860",
}


def safe_name(key):
    """The file name the study command gives a render's maps (same rule as in C++)."""
    return re.sub(r"[^A-Za-z0-9.\-]", "_", key)


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
