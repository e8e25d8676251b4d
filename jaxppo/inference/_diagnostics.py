"""Convergence diagnostics of MCMC draws: rank-normalised split R-hat and
bulk / tail effective sample sizes (Vehtari, Gelman, Simpson, Carpenter &
Buerkner 2021; equal to arviz's)."""

from __future__ import annotations

import numpy as np

__all__ = ["rank_diagnostics"]


def rank_diagnostics(x) -> dict:
    """Rank-normalised split R-hat and bulk / tail effective sample sizes of
    draws ``x`` [chain, draw] (Vehtari, Gelman, Simpson, Carpenter & Buerkner
    2021, the definitions arviz uses; equal to arviz's to rounding). Returns {"r_hat", "ess_bulk", "ess_tail", "n_eff"}."""
    from jax.scipy.special import ndtri
    x = np.asarray(x, float)
    n = x.shape[1] // 2
    if n < 2:
        nan = float("nan")
        return {"r_hat": nan, "ess_bulk": nan, "ess_tail": nan, "n_eff": nan}
    split = np.concatenate([x[:, :n], x[:, -n:]], axis=0)  # [2 chain, n]

    def z(v):
        # average ranks for ties (a chain repeats its draw when NUTS stays put)
        flat = v.reshape(-1)
        order = np.argsort(flat, kind="stable")
        srt = flat[order]
        first = np.r_[True, srt[1:] != srt[:-1]]
        group = np.cumsum(first) - 1
        starts = np.r_[np.nonzero(first)[0], flat.size]
        ranks = np.empty(flat.size)
        ranks[order] = 0.5 * (starts[group] + starts[group + 1] + 1)
        return np.asarray(ndtri((ranks.reshape(v.shape) - 0.375) / (v.size + 0.25)))

    def rhat(v):
        m, nn = v.shape
        w = np.mean(np.var(v, axis=1, ddof=1))
        b = nn * np.var(np.mean(v, axis=1), ddof=1)
        return float(np.sqrt(((nn - 1) / nn * w + b / nn) / w)) if w > 0 else float("nan")

    def ess(v):
        if np.ptp(v) == 0:
            return float("nan")
        return _geyer_ess(v)

    zs = z(split)
    folded = z(np.abs(split - np.median(split)))
    r_hat = max(rhat(zs), rhat(folded))
    bulk = ess(zs)
    # quantiles of every draw (a split drops the middle draw of an odd chain)
    q05, q95 = np.quantile(x, [0.05, 0.95])
    halves = lambda v: np.concatenate([v[:, :n], v[:, -n:]], axis=0)
    tail = min(ess(halves((x <= q05).astype(float))), ess(halves((x <= q95).astype(float))))
    return {"r_hat": r_hat, "ess_bulk": bulk, "ess_tail": tail, "n_eff": bulk}


def _geyer_ess(v: np.ndarray) -> float:
    """ESS of draws v [chain, draw] (Vehtari et al. 2021, Sect. 3.2; Stan's
    and arviz's estimator): autocorrelations pooled over chains with the
    between-chain variance, summed over Geyer's initial positive pairs made
    monotone, the last positive pair's first term added, and
    tau >= 1 / log10(N) (an unclamped sum turns negative on short
    anticorrelated chains)."""
    m, n = v.shape
    c = v - v.mean(axis=1, keepdims=True)
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.fft.rfft(c, size, axis=1)
    acov = np.fft.irfft(spec * np.conj(spec), size, axis=1)[:, :n] / n
    w = np.mean(acov[:, 0]) * n / (n - 1.0)
    var_plus = w * (n - 1.0) / n + (np.var(v.mean(axis=1), ddof=1) if m > 1 else 0.0)
    rho = 1.0 - (w - acov.mean(axis=0)) / var_plus
    rho[0] = 1.0
    kept = np.zeros(n)
    kept[:2] = rho[:2]
    t = 1
    even, odd = rho[0], rho[1]
    while t < n - 3 and even + odd > 0.0:
        even, odd = rho[t + 1], rho[t + 2]
        if even + odd >= 0.0:
            kept[t + 1], kept[t + 2] = even, odd
        t += 2
    last = t - 2
    if even > 0.0:
        kept[last + 1] = even
    for t in range(1, last - 1, 2):  # monotone pairs
        if kept[t + 1] + kept[t + 2] > kept[t - 1] + kept[t]:
            kept[t + 1] = kept[t + 2] = 0.5 * (kept[t - 1] + kept[t])
    tau = -1.0 + 2.0 * np.sum(kept[: last + 1]) + np.sum(kept[last + 1: last + 2])
    return float(m * n / max(tau, 1.0 / np.log10(m * n)))
