"""Statistics of a Delta chi^2 curve: the posterior integrated over the
paper's Table 6 geometry ranges, the Bayes factor and its Jeffreys (1961)
rating."""

from __future__ import annotations

import numpy as np

__all__ = ["jeffreys", "geometry_names", "logsumexp", "geometry_probabilities", "withheld", "goodness_of_fit", "reach_check",
           "guard_cases", "case_ruled_out", "ruled_out_margin", "withhold_cases", "bayes_factor_text", "full_circle", "plot_range", "MISFIT_REDUCED_CHI2", "MISFIT_P_VALUE"]

# the best chi^2 of a scan above both (per point, and in probability for N
# points): the model does not describe the data, and exp(-Delta chi^2 / 2)
# is no posterior (errors 20 % too small already raise every ln K by 44 %;
# an injected PPO of K ~ 5.5, "substantial", read 99 %, "decisive", at
# chi^2 / N = 1.47 and 97 % at 1.36). Below 1.25 with p < 1e-3 the numbers
# stay, with a caution.
MISFIT_REDUCED_CHI2 = 1.25
MISFIT_P_VALUE = 1e-3


def full_circle(alpha) -> bool:
    """Whether the increasing tilt grid ``alpha`` [deg] goes round the
    circle: its gap from the last angle round to the first is no wider
    than its widest step (0 .. 359 by 1; 0 .. 357 by 7, whose last gap is
    3 deg)."""
    a = np.asarray(alpha, float)
    return a.size > 1 and bool(a[0] + 360.0 - a[-1] <= float(np.max(np.diff(a))) * (1 + 1e-9))


def plot_range(alpha) -> tuple[float, float]:
    """The x limits of a plot over the tilt grid ``alpha`` [deg]: a grid
    around the whole circle from its first angle to that + 360 (-180 ..
    180 for ``--alpha -180 180 1``; a fixed 0 .. 360 cut half of it away),
    a partial grid its own span."""
    a = np.asarray(alpha, float)
    if a.size < 2:
        return (0.0, 360.0) if a.size == 0 else (float(a[0]) - 180.0, float(a[0]) + 180.0)
    if full_circle(a):
        return float(a[0]), float(a[0]) + 360.0
    return float(a[0]), float(a[-1])


def jeffreys(k: float) -> str:
    """Jeffreys (1961) rating of a Bayes factor K >= 1."""
    if k < 10**0.5:
        return "barely worth mentioning"
    if k < 10:
        return "substantial"
    if k < 10**1.5:
        return "strong"
    if k < 100:
        return "very strong"
    return "decisive"


def geometry_names(case: str) -> tuple[str, str]:
    """Names of the prograde and retrograde ranges of a case. With one
    untilted planet, a retrograde tilt puts the tilted planet in the other
    hemisphere (paper Table 6). With more, a mixed case ("+-": the untilted
    planets' hemispheres relative to the tilted planet's before its tilt) is
    named by its signs."""
    if case == "same":
        return "prograde, same hemisphere", "retrograde, different hemispheres"
    if case == "opposite":
        return "prograde, different hemispheres", "retrograde, same hemisphere"
    return f"prograde, hemispheres {case}", f"retrograde, hemispheres {case}"


def logsumexp(v: np.ndarray) -> float:
    """log(sum(exp(v))) without overflow; -inf for an empty v."""
    if v.size == 0:
        return -np.inf
    m = float(np.max(v))
    return m + float(np.log(np.sum(np.exp(v - m))))


def geometry_probabilities(alpha, delta_chi2, case) -> dict:
    """Integrate the posterior p(alpha | D) ~ exp(-Delta chi^2 / 2) (uniform
    prior on [0, 360), Eq. 1) over the paper's Table 6 ranges: prograde
    [0, 90] and (270, 360), retrograde (90, 270]; with the sum of positive
    Delta chi^2 in each range and the Bayes factor K = p_favoured / p_other
    (computed in log space: ``log10_bayes_factor`` is always finite;
    ``bayes_factor`` is None where K overflows a float)."""
    alpha = np.mod(np.asarray(alpha, float), 360.0)
    dchi2 = np.asarray(delta_chi2, float)
    pro = (alpha <= 90.0) | (alpha > 270.0)
    names = geometry_names(case)
    logw = -0.5 * dchi2
    log_pro, log_ret = logsumexp(logw[pro]), logsumexp(logw[~pro])
    log_tot = np.logaddexp(log_pro, log_ret)
    p_pro, p_ret = float(np.exp(log_pro - log_tot)), float(np.exp(log_ret - log_tot))
    pos = np.clip(dchi2, 0.0, None)
    favoured = names[0] if log_pro >= log_ret else names[1]
    log10_k = abs(log_pro - log_ret) / np.log(10.0)
    if not np.isfinite(log10_k):
        raise ValueError(f"alpha: the grid leaves the {'retrograde' if np.isinf(log_ret) else 'prograde'} range "
                         "empty; the geometry probabilities need angles in both")
    kk = float(10.0**log10_k) if log10_k < 300 else None
    return {
        names[0]: {"probability": p_pro, "sum_positive_delta_chi2": float(pos[pro].sum()), "alpha_range": "[0, 90] and (270, 360)"},
        names[1]: {"probability": p_ret, "sum_positive_delta_chi2": float(pos[~pro].sum()), "alpha_range": "(90, 270]"},
        "bayes_factor": kk, "log10_bayes_factor": float(log10_k), "favoured": favoured,
        "jeffreys": jeffreys(10.0**min(log10_k, 300.0)),
    }


def withheld(geo: dict, names, reason: str) -> dict:
    """The geometry block of a case whose probabilities cannot be trusted:
    every probability, the Bayes factor and the rating withheld (None), the
    reason in their place."""
    out = {k: v for k, v in geo.items()}
    for nm in names:
        out[nm] = dict(geo[nm], probability=None)
    out.update(bayes_factor=None, log10_bayes_factor=None, favoured=None, jeffreys="not rated", withheld=reason)
    return out


def goodness_of_fit(chi2_best: float, points: int, where: str = "at the best tilt") -> dict:
    """Does the scan's best model describe the data? chi^2 at the best
    tilt and case (``where`` says where the caller took it) for ``points``
    points: "reduced" (chi^2 / N), "p_value" (chi^2 distribution with N
    degrees of freedom), "ok" (False when the reduced chi^2 exceeds
    ``MISFIT_REDUCED_CHI2`` and the p-value is below ``MISFIT_P_VALUE``,
    and for a chi^2 that is not finite), "reason" (None when ok) and
    "caution" (where p < ``MISFIT_P_VALUE`` but chi^2 / N is within the
    limit). Every number is finite or None (strict JSON)."""
    from scipy.special import chdtrc  # chi^2 survival function; scipy.stats costs 0.5 s to import

    chi2_best = float(chi2_best)
    if not np.isfinite(chi2_best) or not points:
        return {"chi2_best": None, "points": int(points), "reduced": None, "p_value": None, "ok": False,
                "reason": f"the model's chi^2 {where} is {chi2_best} for {points} points: nothing can be rated "
                          "(a model that gives NaN, or no points)", "caution": None}
    reduced = chi2_best / points
    p = float(chdtrc(points, chi2_best))
    ok = not (reduced > MISFIT_REDUCED_CHI2 and p < MISFIT_P_VALUE)
    caution = None if not (ok and p < MISFIT_P_VALUE) else (
        f"chi^2 = {chi2_best:.6g} for {points} points {where} (chi^2 / N = {reduced:.3g}, p = {p:.2g}): "
        f"errors too small or parameters off by this much raise every ln K by about {100 * (reduced - 1):.0f} %; "
        "read the rating with that in mind")
    reason = None if ok else (
        f"the model does not fit the data: chi^2 = {chi2_best:.6g} for {points} points {where} "
        f"(chi^2 / N = {reduced:.3g}, p = {p:.2g}); the geometry probabilities assume that it does. Check the "
        "flux normalisation (the out-of-transit level must be 1), the errors and the transit parameters "
        "(jaxppo fit, or the marginal scan: --marginalize N)")
    return {"chi2_best": chi2_best, "points": int(points), "reduced": float(reduced), "p_value": p,
            "ok": bool(ok), "reason": reason, "caution": caution}


def reach_check(fit: dict, fixed_fit: dict, k: int, what: str) -> dict:
    """Did the sampled model reach the fit of the configuration's own
    parameters? ``fit``: ``goodness_of_fit`` of the least chi^2 the
    sampler's draws or particles reached (over tilts and cases);
    ``fixed_fit``: that of the fixed-parameter scan of the same data (its
    best tilt and case); ``k`` free parameters. The sampled model holds the
    configuration's parameters (unless it ties them, e.g. every a/R* to
    one stellar density), so the chi^2 of its draws exceeds its best by
    about a chi^2 of k degrees of freedom (mean k, sd sqrt(2 k); the least
    of many draws by less), and its best is at most the fixed scan's: a
    least chi^2 more than k + 3 sqrt(2 k) above the fixed scan's means the sampler's model cannot
    describe the data as well as the fixed parameters do (injected data
    whose a/R* imply two stellar densities, tied to one), or the sampler
    missed the solution; its geometry probabilities are then those of the
    wrong model. Returns {"ok", "reason" (None when ok or unchecked),
    "excess", "limit", "fixed_chi2_best", "checked"}; unchecked where
    either chi^2 is missing or the point counts differ."""
    least, best, n = fit.get("chi2_best"), fixed_fit.get("chi2_best"), fixed_fit.get("points")
    limit = float(k + 3.0 * np.sqrt(2.0 * k))
    out = {"ok": True, "reason": None, "excess": None, "limit": limit, "fixed_chi2_best": best, "checked": False}
    if least is None or best is None or n != fit.get("points"):
        return out
    excess = float(least) - float(best)
    out.update(excess=excess, checked=True)
    if excess > limit:
        out.update(ok=False, reason=(
            f"the least chi^2 the {what} reached ({float(least):.6g}) is {excess:.1f} above the fixed scan's best "
            f"({float(best):.6g}, the configuration's own parameters), more than {k} free parameters allow "
            f"({limit:.1f}): the sampled model cannot fit these data as well as the fixed parameters do (every a/R* "
            "tied to one stellar density where the configuration's a/R* imply different ones, e.g. data made by "
            "jaxppo simulate from the paper's a/R*; give stellar_density or free fewer a/R*), or the sampler missed "
            "the solution; its geometry probabilities would be those of the wrong model"))
    return out


def guard_cases(cases: dict, chi2_best: dict, points: int) -> dict:
    """``goodness_of_fit`` of the best chi^2 over ``cases`` (case -> its
    summary, with "geometries"; ``chi2_best``: case -> its least chi^2 over
    the tilts); where the model does not fit, every case's geometries are
    ``withheld`` (in place). Where it fits, a case whose own least chi^2
    fails the same test is ruled out by the data (``case_ruled_out``): its
    geometries, conditional on a hemisphere case that fits at no tilt, are
    withheld (a true "opposite" scanned as "same" too: chi^2 / N = 145 at
    that case's best tilt, and "prograde, decisive" printed for it). Returns
    the check, with "ruled_out" (case -> reason)."""
    finite = [v for v in chi2_best.values() if np.isfinite(v)]
    check = goodness_of_fit(min(finite) if finite else float("nan"), points)
    check["ruled_out"] = {}
    if not check["ok"]:
        withhold_cases(cases, check["reason"])
        return check
    for case, chi2 in chi2_best.items():
        why = case_ruled_out(case, chi2, chi2_best, points)
        if why is not None:
            check["ruled_out"][case] = why
            withhold_cases({case: cases[case]}, why)
    return check


def ruled_out_margin(points: int) -> float:
    """The least Delta chi^2 above the best case's by which a case that
    fails ``goodness_of_fit`` counts as ruled out: 3 sqrt(2 N), three
    standard deviations of a chi^2 of N points (at least 25). Two cases
    whose least chi^2 straddle the goodness-of-fit limit 0.008 apart fit
    alike (a review: the one above the limit was withheld as ruled out)."""
    return float(max(25.0, 3.0 * np.sqrt(2.0 * points)))


def case_ruled_out(case: str, chi2: float, chi2_best: dict, points: int, where: str = "tilt") -> "str | None":
    """Why case ``case``'s probabilities are not rated on its own account,
    or None: its least chi^2 (``chi2``, over the tilts; ``chi2_best``:
    every case's) is not finite (``goodness_of_fit``'s reason), or fails
    ``goodness_of_fit`` where the best case's passes, by more than
    ``ruled_out_margin`` above it: the data rule the case out, and its
    probabilities, which assume it, are not rated."""
    own = goodness_of_fit(chi2, points, f"at case {case}'s best {where}")
    if own["ok"]:
        return None
    finite = {c: v for c, v in chi2_best.items() if np.isfinite(v)}
    top = min(finite, key=finite.get) if finite else None
    if top is None or top == case or not goodness_of_fit(finite[top], points)["ok"]:
        return None  # the best case itself, or none fits: goodness_of_fit's own reason withholds them all
    if own["chi2_best"] is None:
        return own["reason"]  # a model that gives NaN: nothing to rate, nothing ruled out by the data
    gap = own["chi2_best"] - finite[top]
    if gap <= ruled_out_margin(points):
        return None  # as good as the best case: both are rated (with its caution, where it has one)
    return (f"the data rule case {case} out: it fits at no {where}: its least chi^2 is {own['chi2_best']:.6g} for "
            f"{points} points (chi^2 / N = {own['reduced']:.3g}, p = {own['p_value']:.2g}), {gap:.6g} above case "
            f"{top}'s ({finite[top]:.6g}); its probabilities assume this hemisphere case and are not rated")


def withhold_cases(cases: dict, reason: str) -> None:
    """Every case's geometries (case -> its summary, with "geometries")
    ``withheld`` for ``reason``, in place; those withheld already keep
    their first reason."""
    for c in cases.values():
        geo = c["geometries"]
        if not geo.get("withheld"):
            c["geometries"] = withheld(geo, [k for k, v in geo.items() if isinstance(v, dict)], reason)


def bayes_factor_text(geo: dict) -> str:
    """The Bayes factor of a geometry block as printed: three decimals up
    to 1e6, then 10^x (a decisive K ran to 110 digits)."""
    k = geo.get("bayes_factor")
    return f"{k:.3f}" if k is not None and k < 1e6 else f"10^{geo['log10_bayes_factor']:.1f}"
