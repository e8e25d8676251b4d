"""The scan's chi^2 of a window light curve at a grid of tilts, its
ground level where no tilt gives a PPO, and what the grid says of a case
(one rule for the scan and its per-pair reports)."""

from __future__ import annotations

import numpy as np

from ..model._lightcurve import LightCurve
from ..model._overlap import ppo_table, quiet_model
from ..model._sweep import sweep
from ._stats import geometry_probabilities

__all__ = ["grid_chi2", "quiet_chi2", "analyse_case"]


def grid_chi2(system, data: LightCurve, alphas, case) -> np.ndarray:
    """chi^2 [alpha] of ``data`` (exposure-averaged model, the sweep's) at
    each tilt of ``alphas`` [deg] in ``case``."""
    tm, nsub = data.supersampled_times()
    alphas = np.asarray(alphas, float)
    model = sweep(system, tm, alphas, cases=(case,))[0].reshape(alphas.size, -1, nsub).mean(-1)
    return np.sum(((data.flux[None, :] - model) / data.flux_err[None, :]) ** 2, axis=1)


def quiet_chi2(system, data: LightCurve, case) -> float:
    """chi^2 of ``quiet_model`` (exposure-averaged) on ``data``: the tilted
    planet's own transit beside the untilted planets with their overlaps in
    this case (the ground level where every tilt of the grid has a PPO)."""
    tm, nsub = data.supersampled_times()
    model = quiet_model(system, tm, case).reshape(-1, nsub).mean(-1)
    return float(np.sum(((data.flux - model) / data.flux_err) ** 2))


def analyse_case(system, windows, data: LightCurve, alphas, chi2, case, step: float, names_case=None):
    """What the chi^2 grid ``chi2`` [alpha] of ``windows`` (their points:
    ``data``) says in ``case``: (summary, Delta chi^2 [alpha], posterior
    [alpha] in 1/deg). The ground level chi^2_0 is the median over the tilts
    with no PPO in any frame of the windows; when the grid has none,
    ``quiet_chi2`` (the sum of one-disk terms left out overlaps of two
    untilted planets: 2e6 off for such a triple). ``names_case``: the case
    whose names the geometries take (default ``case``)."""
    alphas = np.asarray(alphas, float)
    times = [LightCurve(w.time, w.flux, w.flux_err, w.exposure).supersampled_times()[0] for w in windows]
    ppo = ppo_table(system, times, alphas, case)
    quiet = ~ppo.any(1)
    chi2_0 = float(np.median(chi2[quiet])) if quiet.any() else quiet_chi2(system, data, case)
    dchi2 = chi2 - chi2_0
    w = np.exp(-0.5 * (dchi2 - dchi2.min()))
    post = w / (np.sum(w) * step)
    transits = [[int(windows[i].number) for i in np.nonzero(ppo[ai])[0]] for ai in range(alphas.size)]
    summary = {
        "chi2_0": chi2_0, "alphas_without_ppo": int(quiet.sum()),
        "geometries": geometry_probabilities(alphas, dchi2, case if names_case is None else names_case),
        "min_delta_chi2": {"alpha": float(alphas[np.argmin(dchi2)]), "value": float(dchi2.min())},
        "max_delta_chi2": {"alpha": float(alphas[np.argmax(dchi2)]), "value": float(dchi2.max())},
        "ppo_transits": {f"{a:g}": tr for a, tr in zip(alphas, transits) if tr},
    }
    return summary, dchi2, post
