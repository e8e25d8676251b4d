"""The scan's chi^2 of a window light curve at a grid of tilts, its
ground level where no tilt gives a PPO, and what the grid says of a case
(one rule for the scan and its per-pair reports)."""

from __future__ import annotations

import numpy as np

from ..model._exposure import supersampled_times
from ..model._lightcurve import LightCurve
from ..model._overlap import ppo_table, quiet_model
from ..model._sweep import sweep
from ._stats import geometry_probabilities, jeffreys

__all__ = ["grid_chi2", "quiet_chi2", "analyse_case", "resolution_check", "RESOLUTION_TOLERANCE",
           "RESOLUTION_LOG10_K"]

# the largest move of a geometry probability between the alpha grid and one
# of half its step that ``resolution_check`` lets pass
RESOLUTION_TOLERANCE = 0.005
# ... and of log10 K (half a Jeffreys category: a 5-deg grid printed
# K = 10^7.45 where 1 deg gives 10^12.19, both "decisive")
RESOLUTION_LOG10_K = 0.5
_BARELY = jeffreys(1.0)  # the lowest Jeffreys category: no preference rated


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
    times = [supersampled_times(w.time, w.exposure)[0] for w in windows]
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


def resolution_check(system, data: LightCurve, alphas, chi2_by_case: dict, chi2_0: dict, block: int,
                     tolerance: float = RESOLUTION_TOLERANCE, windows=None) -> dict:
    """Does the alpha grid resolve the Delta chi^2 features? chi^2 at the
    midpoints of the grid (``grid_chi2`` in blocks of ``block`` alphas) and
    each case's geometry probabilities on the grid of half the step, beside
    the grid's own (``chi2_by_case``: case -> chi^2 [alpha]; ``chi2_0``:
    case -> its ground level). "ok" unless, in some case, a geometry's
    probability moves by more than ``tolerance``, log10 K by more than
    ``RESOLUTION_LOG10_K``, or the Jeffreys rating changes, or the
    favoured geometry of a rated preference changes (a PPO dip 1-3 deg
    wide falls between the points of a 10-deg grid: the geometries came
    out 49 / 51 %, "barely worth mentioning", where 1 deg gives K = 5e4,
    "decisive"). Where both grids say "barely worth mentioning", the side
    of 50 % a near-even split falls on is no finding (the real Kepler-20
    data: 50.04 / 49.96 % on a 5-deg grid, 49.95 / 50.05 % at 2.5 deg).
    Each case has its own "ok" and "reason" (its probabilities are its
    own); "ok" overall when every case's is. ``windows`` (the scan's): the
    midpoints without a PPO in any frame take the ground level, exactly
    the chi^2 there, and only the others are computed."""
    alphas = np.asarray(alphas, float)
    step = float(alphas[1] - alphas[0]) if alphas.size > 1 else 360.0
    mids = alphas + 0.5 * step
    fine = np.stack([alphas, mids], axis=1).reshape(-1)
    cases, moved = {}, []
    times = None if windows is None else [supersampled_times(w.time, w.exposure)[0] for w in windows]
    for case, chi2 in chi2_by_case.items():
        # where no frame of the windows has a PPO, chi^2 is the ground level exactly: computed only elsewhere
        todo = np.ones(mids.size, bool) if times is None else ppo_table(system, times, mids, case).any(1)
        at_mids = np.full(mids.size, chi2_0[case])
        sel = mids[todo]
        if sel.size:
            at_mids[todo] = np.concatenate([grid_chi2(system, data, sel[i:i + block], case)
                                            for i in range(0, sel.size, block)])
        both = np.stack([np.asarray(chi2, float), at_mids], axis=1).reshape(-1)
        coarse = geometry_probabilities(alphas, np.asarray(chi2, float) - chi2_0[case], case)
        half = geometry_probabilities(fine, both - chi2_0[case], case)
        names = [k for k, v in coarse.items() if isinstance(v, dict)]
        shift = max(abs(coarse[n]["probability"] - half[n]["probability"]) for n in names)
        dk = abs(coarse["log10_bayes_factor"] - half["log10_bayes_factor"])
        # the favoured geometry flipping matters where either grid rates the preference; below that
        # (K < 10^0.5) it is the side of 50 % a near-even split falls on, which the shift judges
        rated = _BARELY not in (coarse["jeffreys"], half["jeffreys"])
        ok = not (shift > tolerance or dk > RESOLUTION_LOG10_K or (rated and coarse["favoured"] != half["favoured"])
                  or coarse["jeffreys"] != half["jeffreys"])
        reason = None
        if not ok:
            fav = coarse["favoured"]
            rating = (f", {coarse['jeffreys']} -> {half['jeffreys']}" if coarse["jeffreys"] != half["jeffreys"] else
                      f" ({coarse['jeffreys']})")
            reason = (f"the alpha grid (step {step:g} deg) does not resolve the Delta chi^2 features of case {case}: "
                      f"at {0.5 * step:g} deg, {fav} {100 * coarse[fav]['probability']:.2f} % -> "
                      f"{100 * half[fav]['probability']:.2f} %{rating}, log10 K {coarse['log10_bayes_factor']:.3g} -> "
                      f"{half['log10_bayes_factor']:.3g}. Scan again with a finer step "
                      f"(alpha = [0, 360, {0.25 * step:g}] or finer)")
            moved.append(reason)
        # the two grids' numbers side by side, named for their grid: the answer itself is in "probabilities"
        # of the summary (withheld there where this check fails), never here
        cases[case] = {"favoured_on_grid": coarse["favoured"], "favoured_at_half_step": half["favoured"],
                       "probabilities_on_grid": {n: coarse[n]["probability"] for n in names},
                       "probabilities_at_half_step": {n: half[n]["probability"] for n in names},
                       "jeffreys_on_grid": coarse["jeffreys"], "jeffreys_at_half_step": half["jeffreys"],
                       "largest_shift": float(shift), "log10_bayes_factor_on_grid": coarse["log10_bayes_factor"],
                       "log10_bayes_factor_at_half_step": half["log10_bayes_factor"], "ok": ok, "reason": reason}
    return {"step": step, "half_step": 0.5 * step, "tolerance": tolerance, "cases": cases, "ok": not moved,
            "reason": "; ".join(moved) if moved else None}
