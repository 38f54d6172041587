"""The tables of a study report (markdown): a sweep's points, methods compared at equal
budget or time, their ratios to the oracle's E. Part of aliquot_report.py; the mean bias
tables are bias_table.py's.
"""
import math

import numpy as np

from bias_table import bias_cells, bias_note, fmt_bias, measured, point_bias
from study_data import DENOISED


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
            + metric_cells(p)
        )
    return md_table(header, rows)


def metric_cells(p):
    """A point's cells after its parameters, in the column order of sweep and detail tables:
    E, mean bias, RMSE, p99 and max bucket E, time, budget, samples/s."""
    return [
        fmt_err(p),
        fmt_bias(point_bias(p)),
        fmt(p.mean("rmse")),
        fmt(p.mean("p99_bucket")),
        fmt(p.mean("max_bucket")),
        f"{p.mean('seconds'):.2f}",
        fmt(int(round(p.mean("samples")))),
        fmt(p.mean("sps")),
    ]


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
                [fmt(int(round(budget))), lab] + metric_cells(p)
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
