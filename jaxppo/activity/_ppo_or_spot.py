"""PPO or spot? (Mueller et al. 2021, Sect. 3.3.3 and Fig. 6: the negative
Delta chi^2 dips "are more likely caused by star spots".)

For each dip of the scan (a Table 5 feature with Delta chi^2 < 0) the same
detrended window data (the scan's ``ScanWindow``: its points, errors and
exposure) are fitted by two alternatives to the no-PPO model (each planet's
own transit, two untilted planets' overlap counted once: the scan's ground
level, ``no_ppo_model``):

* **PPO**: the system at the best alpha near the dip's, in its case (one
  extra parameter, alpha, fitted: the scan's grid angle refined within one
  grid step, ``refine_alpha``; at the grid angle itself a narrow PPO can be
  missed by its width: a PPO injected at 141 deg, seen from 138 deg, came
  out a "spot").
* **spot**: the no-PPO model plus a Gaussian bump in time,
  A exp(-(t - t_c)^2 / (2 w^2)), averaged over each exposure like every
  model of the scan. Three parameters per window, constrained to what a
  transiting planet crossing a dark spot can make: t_c inside one planet's
  transit (first to last contact; every planet of the window is tried and
  the best kept) and within the contacts of the dip's PPO (the feature a
  spot would explain instead: a bump elsewhere explains another feature,
  which every model leaves in its residuals alike), 0 <= A <= that planet's own transit depth (a black spot
  larger than the planet hides at most all the light the planet blocks),
  and w from a quarter of the time the planet takes to move by its own
  diameter (a spot smaller than the planet: the bump lasts about that long)
  to half the transit duration.

Why a Gaussian bump and not a spot on the rotating star (``Star.with_spots``):
at Kepler-20's signal-to-noise a bump during one transit measures only its
time, height and duration; a spot's latitude, longitude, radius and contrast
are four parameters that trade against each other exactly along the chord
(the planet sees only the spot's cut along its path), and the rotation over
a 3-h transit is a few degrees. The bump is the honest parametrisation of
what the data can say, with the same three numbers; its bounds come from the
geometry of a planet covering a spot. It fits any brightening inside a
transit, so it is a generous alternative: a PPO that still wins by BIC is
supported, one that loses is not.

Comparison: chi^2 on the dip's windows for the no-PPO, PPO and spot models,
Delta chi^2 against no-PPO, and BIC = chi^2 + k ln N (N: points in the
windows; k: 1 for the PPO, 3 per window for the spot; the no-PPO model has
no free parameter in the scan, whose system is fixed). Fit: optimistix
Levenberg-Marquardt on unconstrained parameters (logistic maps to the
bounds), from a grid of starting centres and widths; the lowest chi^2 kept.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from ..model._exposure import exposure_mean, supersampled_times
from ..model._processes import is_writer
from ..model._programs import stored

__all__ = ["ppo_or_spot", "plot_ppo_or_spot", "bump_model", "refine_alpha", "grid_step", "REFINE_POINTS",
           "REFINE_ROUNDS"]


def bump_model(t, amplitude, centre, width, xp=jnp):
    """A exp(-(t - t_c)^2 / (2 w^2)) [relative flux] at times t [d]
    (``xp``: jax.numpy, default, or numpy on the host)."""
    return amplitude * xp.exp(-0.5 * ((xp.asarray(t) - centre) / width) ** 2)


def _kass_raftery(delta_bic: float) -> str:
    """Kass & Raftery (1995) category of a BIC difference (~ 2 ln K) in
    favour of the preferred model: < 2 "not worth more than a bare
    mention", 2-6 "positive", 6-10 "strong", >= 10 "very strong"."""
    for limit, words in ((2.0, "not worth more than a bare mention"), (6.0, "positive"), (10.0, "strong")):
        if delta_bic < limit:
            return words
    return "very strong"


def _window_models(system, window, alpha, case):
    """Supersampled times and the no-PPO and PPO models (exposure-averaged)
    on one scan window. The no-PPO model is the scan's ground level
    (``no_ppo_model``: the tilted planet touches no disk, two untilted
    planets that overlap each other are counted once, as at every tilt)."""
    from ..model._sweep import sweep

    tm, nsub, null = _null_model(system, window, case)
    ppo = exposure_mean(sweep(system, tm, np.array([float(alpha)]), cases=(case,))[0, 0], nsub)
    return tm, nsub, null, np.asarray(ppo)


def _null_model(system, window, case):
    """(supersampled times, sub-exposures per point, the no-PPO model
    exposure-averaged) of one scan window."""
    from ..model._overlap import no_ppo_model

    tm, nsub = supersampled_times(window.time, window.exposure)
    return tm, nsub, np.asarray(exposure_mean(no_ppo_model(system, tm, case), nsub))


# alphas per round of the refinement, and its rounds: each narrows the interval
# by (REFINE_POINTS - 1) / 2, so three resolve a grid step to 1e-3 of itself
REFINE_POINTS = 21
REFINE_ROUNDS = 3


def grid_step(result, dip) -> float:
    """The scan's alpha step [deg] around ``dip``: ``summary["alpha"]["step"]``
    where the summary has it, else the nearer of the dip's widths (``lower``,
    ``upper``: each at least one step), else 0 (nothing to refine)."""
    summary = getattr(result, "summary", result)
    grid = summary.get("alpha") if hasattr(summary, "get") else None
    if isinstance(grid, dict) and grid.get("step"):
        return float(grid["step"])
    widths = [float(dip[k]) for k in ("lower", "upper") if dip.get(k)]
    return min(widths) if widths else 0.0


def refine_alpha(system, windows, alpha: float, case: str, step: float) -> float:
    """The alpha [deg, in [0, 360)] within ``step`` of ``alpha`` at which
    the PPO model fits ``windows`` best: the sum over the windows of
    chi^2(PPO at alpha) - chi^2(no PPO), on ``REFINE_POINTS`` angles across
    the interval, then again across the two grid intervals around the best,
    ``REFINE_ROUNDS`` times. Windows in which the tilted planet touches no
    disk at any of a round's angles add nothing (their PPO model is the
    no-PPO model). ``alpha`` itself where ``step`` is 0 or no angle does
    better."""
    from ..model._overlap import contact_frames
    from ..model._sweep import sweep

    if not step > 0:
        return float(alpha)
    parts = []
    for w in windows:
        tm, nsub, null = _null_model(system, w, case)
        y, sig = np.asarray(w.flux, float), np.asarray(w.flux_err, float)
        parts.append((tm, nsub, y, sig, np.sum(((y - null) / sig) ** 2)))
    centre, half, best = float(alpha), float(step), (0.0, float(alpha))
    for _ in range(REFINE_ROUNDS):
        alphas = centre + np.linspace(-half, half, REFINE_POINTS)
        total = np.zeros(REFINE_POINTS)
        for tm, nsub, y, sig, c2_null in parts:
            if not contact_frames(system, tm, alphas, (case,), tilted_only=True).any():
                continue
            ppo = exposure_mean(np.asarray(sweep(system, tm, alphas, cases=(case,))[0]), nsub)
            total += np.sum(((y - ppo) / sig) ** 2, axis=-1) - c2_null
        j = int(np.argmin(total))
        if total[j] < best[0]:
            best = (float(total[j]), float(alphas[j]))
        centre, half = float(alphas[j]), 2.0 * half / (REFINE_POINTS - 1)
    return float(np.mod(best[1], 360.0))


def _ppo_windows(system, windows, dip, alpha) -> list:
    """The numbers of the windows the verdict compares: the dip's PPO
    transits and those in which the tilted planet touches another disk at
    ``alpha`` (the refined angle may reach one more)."""
    from ..model._overlap import contact_frames

    extra = [w.number for w in windows
             if contact_frames(system, supersampled_times(w.time, w.exposure)[0], [alpha], (dip["case"],),
                               tilted_only=True).any()]
    return sorted(set(dip["transits"]) | set(extra))


@stored
def _own_depth(star, planet, t):
    """1 - the flux of ``planet`` alone in front of ``star`` at t[0] [d]
    (exact method; one stored program, not one per operation)."""
    from ..model._system import System

    return 1.0 - System(star, [planet]).flux(t, method="exact")[0]


def _surface_depth(star, planet, t):
    """The depth of ``planet`` alone in front of a star with spots or a
    surface map at t[0] [d]: the star's own flux then (a spotted star's
    varies with time) less the flux with the planet (the "auto" method,
    which rasterises such a star, eagerly: it is not traced)."""
    from ..model._flux import occultation_flux
    from ..model._system import System

    x, y, r = System(star, [planet]).positions(t)
    kw = {"times": jnp.asarray(t, float)} if getattr(star, "spots", None) is not None else {}
    with_planet = occultation_flux(star, x, y, r, method="auto", **kw)
    return (occultation_flux(star, x, y, jnp.zeros_like(r), method="auto", **kw) - with_planet)[0]


def _fine_panel(system, dip, window, params, chi2s):
    """One panel of the figure: the no-PPO, PPO and spot models on a fine
    grid of 300 times over the window (exposure-averaged as the fit)."""
    fine = SimpleNamespace(time=np.linspace(window.time.min(), window.time.max(), 300), flux=np.ones(300),
                           flux_err=np.ones(300), exposure=window.exposure)
    tf, nf, null_f, ppo_f = _window_models(system, fine, dip.get("alpha_ppo", dip["alpha"]), dip["case"])
    bump_f = exposure_mean(bump_model(tf, params["amplitude"], params["centre"], params["width"], np), nf)
    return (dip, window, fine.time, null_f, ppo_f, null_f + bump_f, *chi2s)


def _planet_transits(system, window):
    """(name, first contact, last contact, depth bound, diameter time) of
    each planet transiting during the window [d]."""
    t_lo, t_hi = float(window.time.min()), float(window.time.max())
    out = []
    for pl in system.planets:
        half = float(pl.half_duration())
        if half <= 0:
            continue
        period, t0 = float(pl.period), float(pl.t0)
        n = round((0.5 * (t_lo + t_hi) - t0) / period)
        mid = pl.mid_time(n)  # transit times (TTVs) included
        if mid + half < t_lo or mid - half > t_hi:
            continue
        p = float(pl.radius)
        speed = 2 * math.pi * float(pl.a) / period  # [R* / d]
        # the planet's own depth at mid-transit, limb-darkened: an upper bound of A
        depth = float((_own_depth if system.star.symmetric else _surface_depth)(system.star, pl,
                                                                                   np.array([float(mid)])))
        out.append((pl.name or "?", mid - half, mid + half, depth, 2 * p / speed))
    return out


def _unpack(th, bounds):
    """Bump parameters from unbounded coordinates: A in [0, a_max], t_c in
    [lo, hi], w in [w_min, w_max] (bounds = (a_max, lo, hi, w_min, w_max))."""
    a_max, lo, hi, w_min, w_max = bounds
    s = jax.nn.sigmoid(th)
    return a_max * s[0], lo + (hi - lo) * s[1], w_min + (w_max - w_min) * s[2]


@stored(static_argnames=("nsub",))
def _solve_bump(nsub, th0, tm, y, sig, base, bounds):
    """One Levenberg-Marquardt solve (compiled once per window size, not per
    dip: the scan runs it on every negative dip): the bump's (A, t_c, w),
    chi^2 and whether optimistix converged."""
    import optimistix as optx

    def resid(th, _):
        a, c, w = _unpack(th, bounds)
        bump = exposure_mean(bump_model(tm, a, c, w), nsub)
        return (y - base - bump) / sig

    sol = optx.least_squares(resid, optx.LevenbergMarquardt(rtol=1e-8, atol=1e-10), th0, max_steps=400, throw=False)
    r = resid(sol.value, None)
    return jnp.stack(_unpack(sol.value, bounds)), jnp.sum(r * r), sol.result == optx.RESULTS.successful


def _fit_bump(tm, nsub, y, sig, base, lo, hi, a_max, w_min, w_max, starts=7):
    """Least-squares bump (optimistix LM) with t_c in [lo, hi], A in
    [0, a_max], w in [w_min, w_max]; returns (params, chi2, converged)."""
    args = tuple(np.asarray(v, float) for v in (tm, y, sig, base))
    bounds = np.asarray([a_max, lo, hi, w_min, w_max], float)
    best = None
    logit = lambda q: math.log(q / (1 - q))
    for q_c in (np.arange(starts) + 0.5) / starts:
        for q_w in (0.1, 0.5):
            th0 = np.array([logit(0.3), logit(q_c), logit(q_w)])
            params, chi2, ok = _solve_bump(int(nsub), th0, *args, bounds)
            chi2 = float(chi2)
            if np.isfinite(chi2) and (best is None or chi2 < best[1]):
                best = (params, chi2, bool(ok))
    if best is None:
        raise ValueError("ppo_or_spot: no start of the bump fit gave a finite chi^2")
    params, chi2, ok = best
    a, c, w = (float(v) for v in np.asarray(params))
    return {"amplitude": a, "centre": c, "width": w}, chi2, ok


def _ppo_span(system, tm, alpha, case):
    """(first, last) time [d] of ``tm`` at which the tilted planet overlaps
    another disk at ``alpha`` in ``case`` (the PPO's contacts), or None."""
    from ..model._overlap import contact_frames

    hit = contact_frames(system, tm, [float(alpha)], (case,), tilted_only=True)[0, 0]
    return (float(tm[hit].min()), float(tm[hit].max())) if hit.any() else None


def _best_bump(system, window, dip, tm, nsub, y, sig, null):
    """The spot model of one window: the best bump over the planets that
    transit in it, (params, chi2, converged, planet). Its centre lies in
    the planet's transit and in the span of the dip's PPO (the feature the
    spot would explain instead; a bump elsewhere explains another one, which
    every model leaves alike); the whole transit where the PPO model has no
    contact in the window."""
    span = _ppo_span(system, tm, dip["alpha_ppo"], dip["case"])
    best = None
    for name, lo, hi, depth, t_diam in _planet_transits(system, window):
        c_lo, c_hi = (lo, hi) if span is None else (max(lo, span[0]), min(hi, span[1]))
        if c_lo > c_hi:
            continue
        params, c2, ok = _fit_bump(tm, nsub, y, sig, null, c_lo, c_hi, depth, 0.25 * t_diam, 0.5 * (hi - lo))
        if best is None or c2 < best[1]:
            best = (params, c2, ok, name)
    if best is None:
        raise ValueError(f"ppo_or_spot: no planet transits during the PPO of multi-transit {window.number}")
    return best


def ppo_or_spot(result, system, out=None, figure: bool = True) -> dict:
    """Compare a PPO and a spot crossing as the cause of every negative dip of a finished scan.

    For each dip (a Table 5 feature with Delta chi^2 < 0) the scan's window
    data are fitted by the no-PPO model plus a Gaussian bump
    A exp(-(t - t_c)^2 / (2 w^2)) (exposure-averaged; t_c inside a planet's
    transit and the PPO's contacts, 0 <= A <= its depth, w from 1/4 of its diameter-crossing time
    to half its duration; optimistix Levenberg-Marquardt from a grid of
    starts) and compared with the PPO model at its best alpha within one
    grid step of the dip's (``refine_alpha``; the step from the summary's
    ``alpha``, else the dip's ``lower``/``upper``) by
    BIC = chi^2 + k ln N (k = 1 for the PPO, 3 per window for the spot;
    Mueller et al. 2021, Sect. 3.3.3 and Fig. 6). The bump fits any
    brightening inside a transit, so it is a generous alternative: a PPO
    that still wins by BIC is supported, one that loses is not.

    Parameters
    ----------
    result : jaxppo.ScanResult
        A finished scan from this process: it carries ``windows`` (the
        detrended ``jaxppo.ScanWindow`` points) and ``table5`` (read
        from ``result.summary``). Any object with ``windows`` and a
        ``summary`` (or itself) holding ``table5`` will do.
    system : jaxppo.System
        The scan's system (``cfg.system``).
    out : str or os.PathLike, optional
        Folder for ``ppo_or_spot.png``; None (default): no figure.
    figure : bool, optional
        Draw the figure (paper Fig. 6 style) when ``out`` is given (default
        True).

    Returns
    -------
    dict
        Strict JSON: ``method`` (one line), ``dips``: per dip the case,
        alpha [deg] (the scan's grid angle), ``alpha_ppo`` [deg] (the PPO
        model's, refined), ``grid_step`` [deg] (0: not refined), the scan's
        Delta chi^2, the windows (the dip's PPO transits and any the PPO
        at ``alpha_ppo`` touches; number, points,
        chi2 of the no-PPO, PPO and spot models, the bump's parameters
        [relative flux, d, d] and the crossing planet), and the totals
        ``delta_chi2`` and ``delta_bic`` of both models against no-PPO,
        ``n_points``, ``k`` and ``preferred`` ("no PPO", "PPO" or "spot":
        the least BIC of the three), ``bic_margin`` (the runner-up's BIC
        less the preferred one's, ~ 2 ln K) and ``evidence`` (its Kass &
        Raftery 1995 category: below 2 the preference is
        "not worth more than a bare mention"); and ``figure`` (the PNG's
        absolute path, if drawn).

    Raises
    ------
    ValueError
        If no start of a bump fit gives a finite chi^2.

    Examples
    --------
    One planet (so the PPO model equals the no-PPO one) with a bump of
    8e-4 injected into its transit: the spot model wins and recovers it.
    The stand-in scan result holds one window and one dip of Table 5.

    >>> from types import SimpleNamespace
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> planet = jp.Planet(period=3.0, t0=0.0, a=8.0, inc=89.0, radius=0.08, name="b")
    >>> system = jp.System(jp.Star.quadratic(0.4, 0.26), [planet])
    >>> t = np.linspace(-0.1, 0.1, 60)
    >>> transit = np.asarray(jp.sweep(system, t, np.zeros(1), cases=("same",), no_overlap=True)[0, 0])
    >>> flux = transit + 8e-4 * np.exp(-0.5 * ((t - 0.01) / 0.006) ** 2)
    >>> window = SimpleNamespace(number=1, time=t, flux=flux, flux_err=np.full(t.size, 1e-5),
    ...                          exposure=None, event=SimpleNamespace(mid=0.0))
    >>> dip = {"kind": "dip", "case": "same", "alpha": 10.0, "delta_chi2": -1.0, "transits": [1]}
    >>> result = SimpleNamespace(windows=[window], summary={"table5": [dip]})
    >>> verdict = jp.activity.ppo_or_spot(result, system)["dips"][0]
    >>> verdict["preferred"]
    'spot'
    >>> bump = verdict["windows"][0]["bump"]
    >>> print(f"A = {bump['amplitude']:.1e}, t_c = {bump['centre']:.4f} d, w = {bump['width']:.4f} d")
    A = 8.0e-04, t_c = 0.0100 d, w = 0.0060 d
    """
    from ..model._system import require_keplerian

    require_keplerian(system, "ppo_or_spot")
    windows = {w.number: w for w in result.windows}
    dips = [r for r in getattr(result, "summary", result)["table5"] if r["kind"] == "dip" and r["delta_chi2"] < 0]
    rows, panels = [], []
    for d in dips:
        step = grid_step(result, d)
        d = {**d, "alpha_ppo": refine_alpha(system, result.windows, d["alpha"], d["case"], step)}
        entry = {"case": d["case"], "paper_case": d.get("paper_case"), "alpha": d["alpha"],
                 "alpha_ppo": d["alpha_ppo"], "grid_step": step, "scan_delta_chi2": d["delta_chi2"], "windows": []}
        chi = {"none": 0.0, "ppo": 0.0, "spot": 0.0}
        n_pts = 0
        for num in _ppo_windows(system, result.windows, d, d["alpha_ppo"]):
            w = windows[num]
            tm, nsub, null, ppo = _window_models(system, w, d["alpha_ppo"], d["case"])
            y, sig = np.asarray(w.flux), np.asarray(w.flux_err)
            params, c2_spot, ok, planet = _best_bump(system, w, d, tm, nsub, y, sig, null)
            c2_none = float(np.sum(((y - null) / sig) ** 2))
            c2_ppo = float(np.sum(((y - ppo) / sig) ** 2))
            entry["windows"].append({"number": num, "mid": float(w.event.mid), "points": int(y.size),
                                     "chi2_no_ppo": c2_none, "chi2_ppo": c2_ppo, "chi2_spot": c2_spot,
                                     "bump": params, "crossing_planet": planet, "converged": ok})
            chi["none"] += c2_none
            chi["ppo"] += c2_ppo
            chi["spot"] += c2_spot
            n_pts += int(y.size)
            if out is not None and figure:
                panels.append(_fine_panel(system, d, w, params, (c2_none, c2_ppo, c2_spot)))
        k_spot = 3 * len(entry["windows"])
        ln_n = math.log(max(n_pts, 1))
        entry.update(
            n_points=n_pts, k={"ppo": 1, "spot": k_spot},
            delta_chi2={"ppo": chi["ppo"] - chi["none"], "spot": chi["spot"] - chi["none"]},
            delta_bic={"ppo": chi["ppo"] - chi["none"] + ln_n, "spot": chi["spot"] - chi["none"] + k_spot * ln_n},
        )
        # the no-PPO model (Delta BIC 0) competes too: a dip that neither
        # extra model explains better than its parameters cost is noise
        bic = {"no PPO": 0.0, "PPO": entry["delta_bic"]["ppo"], "spot": entry["delta_bic"]["spot"]}
        entry["preferred"] = min(bic, key=bic.get)
        # how far ahead: Delta BIC to the runner-up, ~ 2 ln K (Kass & Raftery 1995)
        entry["bic_margin"] = sorted(bic.values())[1] - bic[entry["preferred"]]
        entry["evidence"] = _kass_raftery(entry["bic_margin"])
        entry["bic_spot_minus_ppo"] = entry["delta_bic"]["spot"] - entry["delta_bic"]["ppo"]
        rows.append(entry)
    summary = {
        "method": ("no-PPO model + Gaussian bump (A, t_c, w per window; t_c inside a planet's transit and "
                   "the PPO's contacts, 0 <= A <= its depth, w from 1/4 of its diameter-crossing time to half its duration), "
                   "optimistix Levenberg-Marquardt; PPO at the best alpha within one grid step of the dip's; "
                   "BIC = chi2 + k ln N with k = 1 (PPO: alpha), 3 per window (spot)"),
        "dips": rows,
    }
    if out is not None and figure and panels:
        summary["figure"] = str(plot_ppo_or_spot(panels, Path(out) / "ppo_or_spot.png").resolve())
    return summary


def plot_ppo_or_spot(panels, path):
    """Write a PNG with one panel per (dip, window), like the paper's Fig. 6.

    Each panel shows the detrended data with errors, the no-PPO model, the
    PPO model at the dip's alpha and the spot (bump) model, their chi^2 in
    the legend, against the time from the window's mid-time [h].

    Parameters
    ----------
    panels : list of tuple
        (dip, window, tf, null, ppo, spot, chi2_null, chi2_ppo, chi2_spot)
        per panel: the Table 5 row (a dict with ``case``, ``alpha`` [deg]
        and ``delta_chi2``), the ``jaxppo.ScanWindow`` (``time`` [d],
        ``flux``, ``flux_err``, ``number``, ``event.mid`` [d]), the model
        times [d], shape [n_fine], the three models' relative fluxes, shape
        [n_fine], and their chi^2. ``ppo_or_spot`` builds them.
    path : str or os.PathLike
        The PNG file to write.

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.linspace(-0.1, 0.1, 40)
    >>> window = SimpleNamespace(number=1, time=t, flux=1 - 5e-3 * (np.abs(t) < 0.06),
    ...                          flux_err=np.full(t.size, 2e-4), event=SimpleNamespace(mid=0.0))
    >>> dip = {"case": "same", "alpha": 10.0, "delta_chi2": -3.2}
    >>> null = 1 - 5e-3 * (np.abs(t) < 0.06)
    >>> spot = null + 3e-4 * np.exp(-0.5 * (t / 0.01) ** 2)
    >>> path = jp.activity.plot_ppo_or_spot([(dip, window, t, null, null, spot, 40.0, 40.0, 36.8)], "fig6.png")
    >>> print(path.name, path.exists())
    fig6.png True
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(panels)
    fig, axes = plt.subplots(n, 1, figsize=(7, 3.2 * n), squeeze=False)
    for ax, (d, w, tf, null, ppo, spot, c0, c1, c2) in zip(axes[:, 0], panels):
        ref = float(w.event.mid)
        x, xf = (np.asarray(w.time) - ref) * 24.0, (tf - ref) * 24.0
        ax.errorbar(x, w.flux, w.flux_err, fmt="o", ms=3, color="0.3", lw=0.8, label="data (detrended)")
        ax.plot(xf, null, color="k", lw=1.2, label=f"no PPO ($\\chi^2$ = {c0:.2f})")
        ax.plot(xf, ppo, color="C3", lw=1.2, label=f"PPO, $\\alpha$ = {d.get('alpha_ppo', d['alpha']):.4g} deg ({c1:.2f})")
        ax.plot(xf, spot, color="C0", lw=1.2, ls="--", label=f"spot crossing ({c2:.2f})")
        ax.set_title(f"case {d['case']}, dip at $\\alpha$ = {d['alpha']:g} deg "
                     f"($\\Delta\\chi^2$ = {d['delta_chi2']:.2f}), multi-transit {w.number} at BKJD {ref:.2f}",
                     fontsize=9)
        ax.set_xlabel(f"time - {ref:.3f} [h]")
        ax.set_ylabel("relative flux")
        ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    path = Path(path)
    if is_writer():  # process 0 of several JAX processes
        fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
