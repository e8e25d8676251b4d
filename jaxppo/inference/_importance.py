"""When an importance-sampling average can be trusted.

The marginalised scan estimates p(alpha | D) as an average of importance
weights over posterior draws. When the weights span many nats, one draw
carries the average and the answer is that draw's: the estimate is then
wrong without any error. Two standard diagnostics decide whether a number
may be reported:

* the Kish effective sample size, (sum w)^2 / sum w^2;
* the Pareto k-hat of the weights' upper tail, from ``KHAT_MIN_DRAWS``
  draws on and where the weights are not near-equal (``NEAR_EQUAL``), (Vehtari, Simpson, Gelman,
  Yao & Gabry 2024, "Pareto smoothed importance sampling", JMLR 25, 72):
  the shape of a generalised Pareto distribution fitted to the M =
  ceil(min(S / 5, 3 sqrt(S))) largest of S weights by the method of Zhang &
  Stephens (2009, Technometrics 51, 316) with the weakly informative prior
  of Vehtari et al. An estimate is reliable when k-hat <= min(0.7, 1 -
  1 / log10 S) (their Sect. 3.2.2).

``importance_reliability`` applies both to the weight of every geometry
(the per-draw weight summed over the geometry's alphas) and to the case's
total: a geometry probability or a Bayes factor is their ratio, so every
one of them must be sound.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["MIN_IMPORTANCE_ESS", "kish_ess", "pareto_khat", "khat_threshold", "importance_reliability"]

MIN_IMPORTANCE_ESS = 25.0
"""Fewest effective draws behind a reported probability or rating."""

KHAT_MIN_DRAWS = 100
"""Fewest draws at which k-hat is applied: its tail then holds >= 20 weights.
With fewer, the estimate is mostly its prior (a tail of 7 of 32 draws gives
(7 xi + 5) / 17 >= 0.29 for any thin tail xi >= 0, against a threshold of
0.34), so below it the Kish ESS alone decides."""

NEAR_EQUAL = 0.9
"""Weights with a Kish ESS of at least this fraction of the draws are
near-equal (rms spread under 1/3 of their mean): their tail holds nothing to
judge, and a k-hat fitted to a few near-equal tail weights is noise (it sat
at 0.76 for 32 draws with ESS 31.5 of a flat posterior), so k-hat is applied
only below it."""


def kish_ess(logw, axis: int = 0) -> np.ndarray:
    """Kish's effective sample size (sum w)^2 / sum w^2 of the weights
    exp(logw) along ``axis`` (scale-free: computed from logw - max). A weight
    of exactly 0 (logw = -inf) counts as a draw with no weight; a NaN or
    infinite weight, or none above 0, gives an ESS of 0: nothing can be
    trusted."""
    logw = np.asarray(logw, float)
    broken = np.any(np.isnan(logw) | (logw == np.inf), axis=axis)
    clean = np.where(np.isnan(logw) | (logw == np.inf), -np.inf, logw)
    top = np.max(clean, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    w = np.exp(clean - top)
    with np.errstate(invalid="ignore", divide="ignore"):
        ess = np.sum(w, axis=axis) ** 2 / np.sum(w**2, axis=axis)
    return np.where(broken | ~np.isfinite(ess), 0.0, ess)


def khat_threshold(n: int) -> float:
    """The largest Pareto k-hat at which an importance average over ``n``
    draws is reliable: min(0.7, 1 - 1 / log10 n) (Vehtari et al. 2024)."""
    if n < 2:
        return -math.inf
    return min(0.7, 1.0 - 1.0 / math.log10(n))


def _gpd_shape(x: np.ndarray) -> float:
    """Shape xi of a generalised Pareto distribution fitted to the
    exceedances x >= 0 (Zhang & Stephens 2009: the profile likelihood in
    theta = -xi / sigma averaged over a grid of theta with its
    likelihood as weight), shrunk towards 0.5 by the prior of Vehtari et al.
    (2024): (n xi + 10 * 0.5) / (n + 10)."""
    x = np.sort(np.asarray(x, float))
    n = x.size
    # the grid of theta spans values where log1p(-theta x) is undefined for
    # some x; those get zero weight (their profile likelihood is NaN)
    with np.errstate(invalid="ignore", divide="ignore"):
        return _gpd_shape_of(x, n)


def _gpd_shape_of(x: np.ndarray, n: int) -> float:
    m = 30 + int(math.sqrt(n))
    j = np.arange(1, m + 1)
    quart = x[max(int(n / 4.0 + 0.5) - 1, 0)]
    theta = 1.0 / x[-1] + (1.0 - np.sqrt(m / (j - 0.5))) / (3.0 * quart)
    xi = np.mean(np.log1p(-theta[:, None] * x[None, :]), axis=1)
    prof = n * (np.log(-theta / xi) - xi - 1.0)
    weights = 1.0 / np.sum(np.exp(prof[None, :] - prof[:, None]), axis=1)
    weights = np.where(np.isfinite(weights), weights, 0.0)
    theta_hat = float(np.sum(theta * weights) / np.sum(weights))
    xi_hat = float(np.mean(np.log1p(-theta_hat * x)))
    return (n * xi_hat + 10 * 0.5) / (n + 10)


def pareto_khat(logw) -> float:
    """Pareto k-hat of the importance weights exp(logw) [draws]: the GPD
    shape of the M largest weights' exceedances over the next one. -inf
    when those weights are all equal (nothing in the tail); +inf when the
    tail is shorter than 5 draws (fewer than 25 draws: no estimate)."""
    logw = np.asarray(logw, float).ravel()
    s = logw.size
    if np.any(np.isnan(logw) | (logw == np.inf)) or not np.any(np.isfinite(logw)):
        return math.inf
    m = int(math.ceil(min(0.2 * s, 3.0 * math.sqrt(s))))
    if m < 5:
        return math.inf
    lw = np.sort(logw - np.max(logw))
    cutoff = lw[-m - 1]
    tail = np.exp(lw[-m:]) - np.exp(cutoff)
    if not tail.max() > 0:
        return -math.inf
    # exceedances scaled to a maximum of 1: the shape does not depend on scale
    return _gpd_shape(tail / tail.max())


def importance_reliability(logw, groups: dict, min_ess: float = MIN_IMPORTANCE_ESS) -> dict:
    """Can the group masses of an importance average be reported?

    Args:
        logw: log importance weights [draw, alpha].
        groups: name -> boolean mask over alpha (e.g. the two geometries).
        min_ess: fewest effective draws (Kish) behind each mass; the
            Pareto k-hat must also be <= ``khat_threshold`` from
            ``KHAT_MIN_DRAWS`` draws on, unless the weights are near-equal
            (Kish ESS >= ``NEAR_EQUAL`` x draws).

    Returns:
        {"reliable": bool, "min_ess", "khat_threshold", "draws",
        "groups": name -> {"ess", "khat"}, "reason": text or None}; the
        "total" group (all alphas) is always included: a probability is a
        ratio of masses and needs both.
    """
    logw = np.asarray(logw, float)
    n = logw.shape[0]
    kmax = khat_threshold(n)
    out, bad = {}, []
    for name, mask in {**groups, "total": np.ones(logw.shape[1], bool)}.items():
        mask = np.asarray(mask, bool)
        if not mask.any():
            continue
        lw = logw[:, mask]
        with np.errstate(invalid="ignore", divide="ignore"):
            top = np.max(np.where(np.isnan(lw), -np.inf, lw), axis=1, keepdims=True)
            safe = np.where(np.isfinite(top), top, 0.0)
            # log sum over the group's alphas (NaN stays NaN: kish_ess then gives 0)
            lw_draw = np.squeeze(safe, 1) + np.log(np.sum(np.exp(lw - safe), axis=1))
        ess, khat = float(kish_ess(lw_draw)), pareto_khat(lw_draw)
        out[name] = {"ess": ess, "khat": None if not math.isfinite(khat) else float(khat)}
        if not ess >= min_ess:
            bad.append(f"{name}: ESS {ess:.1f} < {min_ess:g}")
        elif n >= KHAT_MIN_DRAWS and ess < NEAR_EQUAL * n and not khat <= kmax:
            bad.append(f"{name}: Pareto k-hat {khat:.2f} > {kmax:.2f}")
    reason = None
    if bad:
        reason = (f"importance weights over {n} draws are unreliable ({'; '.join(bad)}): a few draws carry the "
                  "average, so no probability, peak or rating is given (the joint sampler, jaxppo.joint_scan, carries "
                  "such cases)")
    return {"reliable": not bad, "min_ess": float(min_ess), "khat_threshold": kmax if math.isfinite(kmax) else None,
            "draws": n, "groups": out,
            "reason": reason}
