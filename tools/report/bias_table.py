"""The image's mean bias in a study report: each method's (mean of image − mean of
reference) ÷ mean of reference beside its E, flagged where the noise does not explain it.

E (mean |image − reference|) is least at a pixel's median, and a heavy-tailed pixel's median
lies below its mean: a method that darkens such pixels wins on E with an image too dark
(docs/RESULTS.md, "Is `optimal` biased low?"). A table of E alone hides that; this one
shows it.
"""
import math

# Columns of a study row (migration 7); absent from databases of earlier runs.
BIAS = ["mean_bias", "mean_bias_se"]
DENOISED_BIAS = ["denoised_mean_bias", "denoised_mean_bias_se"]

# A bias beyond this many standard errors is more than the image's noise explains (the
# same rule as bias_beyond_noise in coordinator/image/error_metric.h).
FLAG_SE = 3.0


def point_bias(point, attr="mean_bias"):
    """The mean bias over a point's seeds and its standard error, or None when a seed
    lacks it. Each seed's error is its own (the spread of its image's blocks' mean
    differences, which holds the reference's noise too); propagated as from independent
    seeds, the mean's is their root sum of squares over the count. With two seeds or more
    it is the larger of that and the seeds' own spread (the standard deviation of their
    biases over √seeds): the seeds' spread is measured, so a seed's error that runs low
    (fireflies rarer than its blocks show) is caught. Neither counts the reference's noise
    in full: the seeds share one reference, so its error moves every seed's bias alike and
    the mean keeps it whole, where the propagation divides it by √seeds and the spread
    does not see it. Small against a reference of many times a render's samples; a bias
    near 3 standard errors with a reference of few samples is not proof."""
    values = [getattr(r, attr) for r in point.renders]
    errors = [getattr(r, attr + "_se") for r in point.renders]
    if not values or any(v is None or math.isnan(v) for v in values + errors):
        return None
    n = len(values)
    mean = sum(values) / n
    se = math.sqrt(sum(e * e for e in errors)) / n
    if n >= 2:
        spread = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1))
        se = max(se, spread / math.sqrt(n))
    return mean, se


def flagged(bias):
    return bias is not None and abs(bias[0]) > FLAG_SE * bias[1]


def fmt_bias(bias):
    """The cell: "−1.68 % ± 0.03 % **biased**", "+0.10 % ± 0.20 %", or "–" unmeasured."""
    if bias is None:
        return "–"
    text = f"{100 * bias[0]:+.2f} % ± {100 * bias[1]:.2f} %".replace("-", "−")
    return text + (" **biased**" if flagged(bias) else "")


def measured(series, groups, n, attr="mean_bias"):
    return n > 0 and all(point_bias(series[g][i], attr) is not None for g in groups for i in range(n))


def bias_cells(series, groups, i, attr="mean_bias"):
    """One row of the bias table at sweep position i: each group's bias, as fmt_bias."""
    return [fmt_bias(point_bias(series[g][i], attr)) for g in groups]


def bias_note(what="the image"):
    return (
        f"Mean bias of {what}: (its mean − the reference's) ÷ the reference's, over pixels and RGB, "
        f"mean over seeds ± its standard error; **biased** where it lies beyond {FLAG_SE:g} standard "
        "errors, more than the noise explains. E rewards an image too dark, so read E beside it:"
    )
