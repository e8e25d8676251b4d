"""Measuring transit times: every transit's mid-time fitted with the exact
model (other planets and overlapping transits included), its error, and
the linear ephemeris and O-C diagram of the measured times.

``measure_transit_times`` gives each planet a listed mid-time for every
epoch with data (``Planet(transit_times=, transit_epochs=)``), finds each
one's start on a grid of shifts (the chi^2 of the epoch's own points), then
fits all of them together, with the parameters named in ``free``, by
``jaxppo.fit`` (Levenberg-Marquardt). The errors are those of the fit's
linearised covariance (every mid-time's marginal error, the other
parameters free too).
"""

from __future__ import annotations

import math
import warnings

import jax.numpy as jnp
import numpy as np

from ..model._planet import Planet
from ..model._system import System, require_keplerian
from ..model._transits import planet_label
from ..model._units import from_quantity
from ._fit import FitResult, fit
from ._model import Model
from ._params import checked_lightcurve

__all__ = ["measure_transit_times", "linear_ephemeris", "TIMES_COLUMNS"]

TIMES_COLUMNS = ("planet", "epoch", "tc", "tc_err", "chi2", "n_points")
"""The columns of ``measure_transit_times``'s table."""


def _planet_indices(system: System, planets) -> list[int]:
    labels = [planet_label(system, i) for i in range(len(system.planets))]
    if planets is None:
        return list(range(len(system.planets)))
    if isinstance(planets, (str, int)):
        planets = [planets]
    out = []
    for p in planets:
        if isinstance(p, (int, np.integer)) and not isinstance(p, bool) and 0 <= p < len(labels):
            out.append(int(p))
        elif str(p) in labels:
            out.append(labels.index(str(p)))
        else:
            raise ValueError(f"planets: no planet {p!r}; the planets are {labels}")
    if len(set(out)) != len(out):
        raise ValueError(f"planets: {list(planets)!r} names a planet twice")
    return out


def _data_epochs(pl: Planet, time: np.ndarray, min_points: int) -> list[tuple[int, float]]:
    """(epoch, predicted mid-time) of the planet's transits with at least
    ``min_points`` data points between first and last contact."""
    t1, t4 = (float(v) for v in pl.contacts())
    if not t4 > t1:
        return []
    period, t0 = float(pl.period), float(pl.t0)
    out = []
    for n in range(math.floor((time.min() - t4 - t0) / period) - 1, math.ceil((time.max() - t1 - t0) / period) + 2):
        tc = pl.mid_time(n)
        if np.count_nonzero((time >= tc + t1) & (time <= tc + t4)) >= min_points:
            out.append((n, tc))
    return out


def _with_times(pl: Planet, new: dict) -> Planet:
    """The planet with its listed times plus ``new`` (epoch -> tc)."""
    times = {} if pl.transit_times is None else dict(zip(pl.transit_epochs, np.asarray(pl.transit_times, float)))
    times.update(new)
    epochs = sorted(times)
    # every other element kept as it is (lnode: two planets' overlap geometry)
    return pl.replace(transit_times=[times[e] for e in epochs], transit_epochs=epochs)


def _classes(windows) -> list[list[int]]:
    """The transits split into groups no two of which share a point
    (greedy colouring of the overlap graph of their windows)."""
    colour = []
    for i, w in enumerate(windows):
        taken = {colour[j] for j in range(i) if np.any(w & windows[j])}
        colour.append(next(c for c in range(len(windows) + 1) if c not in taken))
    return [[i for i, c in enumerate(colour) if c == k] for k in range(max(colour) + 1)]


def start_shifts(grid: int) -> np.ndarray:
    """The starting shifts in units of the search half-width: ``grid``
    evenly spaced in [-1, 1], and 0 (the start) whatever the parity of
    ``grid``, ordered by size, so that where shifts tie (every one moves
    the transit off the data) the first minimum is the unshifted start."""
    frac = np.unique(np.r_[np.linspace(-1.0, 1.0, grid), 0.0])
    return frac[np.argsort(np.abs(frac), kind="stable")]


def _grid_start(model: Model, slots, search: np.ndarray, grid: int, windows) -> jnp.ndarray:
    """Theta with each free mid-time moved to the shift (on a grid of
    ``grid`` shifts of up to +-search [d]) that minimises the chi^2 of
    its own points. The times of transits that share no point move at once
    (one model evaluation per shift); transits that share points (two
    planets on the star together) are searched in turn, each with the
    others at their best so far, twice over."""
    theta = model.to_theta(model.system)
    frac = start_shifts(grid)
    grid = frac.size
    n = model.y.size
    classes = _classes(windows)
    for _ in range(1 if len(classes) == 1 else 2):
        for members in classes:
            idx = np.array([slots[i] for i in members])
            shifts = jnp.asarray(frac[:, None] * search[members][None, :])
            thetas = jnp.tile(theta, (grid, 1)).at[:, idx].add(shifts)
            r2 = np.asarray(model.residuals_batch(thetas))[:, :n] ** 2
            best = [int(np.argmin(r2[:, windows[i]].sum(1))) if windows[i].any() else 0 for i in members]  # 0: the start
            theta = theta.at[idx].set(jnp.asarray(np.asarray(thetas)[np.array(best), idx]))
    return theta


def _groups(windows) -> list[list[int]]:
    """The connected groups (two or more) of transits whose windows share
    points."""
    n, seen, out = len(windows), set(), []
    for i in range(n):
        if i in seen:
            continue
        group, todo = [], [i]
        while todo:
            j = todo.pop()
            if j in seen:
                continue
            seen.add(j)
            group.append(j)
            todo += [k for k in range(n) if k not in seen and np.any(windows[j] & windows[k])]
        if len(group) > 1:
            out.append(sorted(group))
    return out


def _joint_grid(model: Model, theta, slots, names, search, grid: int, windows, lc, alpha, case):
    """Theta with the times of each group of two or three transits that
    share points (two planets on the star together) set to the best point
    of a joint grid over their shifts, on the group's points only: searched
    one at a time, each time can take the other's dip (a swapped pair is a
    deep local minimum of chi^2)."""
    for group in _groups(windows):
        if len(group) > 3:
            continue  # the passes of _grid_start only
        axis = start_shifts(grid if len(group) == 2 else min(grid, 21))
        mask = np.any([windows[i] for i in group], axis=0)
        sub = Model(model.to_system(theta), lc.select(mask), tuple(names[i] for i in group), alpha, case,
                    active_margin=2.5)
        start = np.asarray(sub.to_theta(sub.system))
        mesh = np.stack(np.meshgrid(*[axis * search[i] for i in group], indexing="ij"), -1).reshape(-1, len(group))
        chi2 = np.asarray(sub.chi2_batch(jnp.asarray(start + mesh)))
        best = start + mesh[int(np.nanargmin(chi2))]
        theta = theta.at[np.array([slots[i] for i in group])].set(jnp.asarray(best))
    return theta


def linear_ephemeris(epoch, tc, tc_err=None) -> tuple[float, float, np.ndarray]:
    """Fit a linear ephemeris tc = t0 + n P to measured mid-times.

    Weighted least squares (weights 1 / tc_err^2). Without errors the
    weights are equal and the covariance is scaled by the scatter about the
    line (chi^2 / (N - 2), with N - 2 taken as 1 for two epochs). The
    observed minus calculated (O-C) times are ``tc - t0 - epoch * P``.

    Parameters
    ----------
    epoch : array_like of int
        Transit epochs n [n_times] (at least two distinct ones).
    tc : array_like
        Measured mid-times [d], shape [n_times].
    tc_err : array_like or None, optional
        1-sigma errors of ``tc`` [d], shape [n_times], positive and finite; None
        (default): equal weights.

    Returns
    -------
    t0 : float
        Mid-time of epoch 0 [d].
    period : float
        Period P [d].
    covariance : numpy.ndarray
        Covariance of (t0, P) [d^2], shape [2, 2].

    Raises
    ------
    ValueError
        When ``epoch`` and ``tc`` differ in length or hold fewer than two
        distinct epochs, an epoch is not an integer, a time is not finite,
        ``tc_err`` is not one positive, finite error per time, or
        ``tc_err`` is None with fewer than three distinct epochs (the
        scatter about a line through two points measures nothing).

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> epoch, tc = [0, 1, 2, 4], [10.0012, 13.4987, 17.0003, 23.9996]
    >>> t0, period, cov = jp.linear_ephemeris(epoch, tc, [0.001, 0.001, 0.001, 0.002])
    >>> print(f"t0 = {t0:.4f} +- {np.sqrt(cov[0, 0]):.4f} d, P = {period:.5f} +- {np.sqrt(cov[1, 1]):.5f} d")
    t0 = 10.0004 +- 0.0008 d, P = 3.49970 +- 0.00050 d
    >>> oc = np.array(tc) - t0 - period * np.array(epoch)  # O-C [d]
    >>> print(np.round(oc * 1440, 2))  # [min]
    [ 1.15 -2.02  0.72  0.58]
    """
    n = np.asarray(epoch, float)
    t = np.asarray(tc, float)
    if n.size != t.size or n.size < 2 or np.unique(n).size < 2:
        raise ValueError(f"linear_ephemeris needs mid-times of at least two distinct epochs, got epochs {n.tolist()}")
    if not (np.all(np.isfinite(n)) and np.all(n == np.round(n))):
        raise ValueError(f"linear_ephemeris: epoch must be finite integers, got {n.tolist()}")
    if not np.all(np.isfinite(t)):
        raise ValueError(f"linear_ephemeris: tc must be finite [d], got {t.tolist()}")
    if tc_err is None and np.unique(n).size < 3:
        # two epochs and no errors: the line passes through both points and
        # its scatter says nothing about their errors (the covariance was 0)
        raise ValueError("linear_ephemeris: without tc_err the errors come from the scatter about the line, which "
                         f"needs at least three distinct epochs (got {np.unique(n).size}); give tc_err")
    if tc_err is None:
        w = np.ones_like(t)
    else:
        e = np.asarray(tc_err, float)
        if e.shape != t.shape or not np.all(np.isfinite(e) & (e > 0)):
            raise ValueError(f"linear_ephemeris: tc_err must be positive and finite, one per time, got {e.tolist()}")
        w = 1.0 / e**2
    A = np.stack([np.ones_like(n), n], axis=1)
    cov = np.linalg.inv(A.T @ (A * w[:, None]))
    t0, period = cov @ (A.T @ (w * t))
    if tc_err is None:
        dof = max(n.size - 2, 1)
        cov = cov * float(np.sum((t - t0 - period * n) ** 2)) / dof
    return float(t0), float(period), cov


def _window_stats(model: Model, result: FitResult, windows) -> tuple[np.ndarray, np.ndarray]:
    """(chi^2, number of points) of each epoch's points at the fit
    (``model``: built on the fitted system, so its computed frames are
    those of the measured times)."""
    theta_ref = model.to_theta(model.system)
    theta = model.theta_from(jnp.asarray(result.values), theta_ref)
    r = np.asarray(model.residuals(theta))[:model.y.size]
    return np.array([float(np.sum(r[w] ** 2)) for w in windows]), np.array([int(w.sum()) for w in windows])


def measure_transit_times(system: System, lightcurve, planets=None, *, free=(), search=None, grid: int = 41,
                          min_points: int = 3, alpha: float = 0.0, case: str = "same", return_fit: bool = False,
                          progress: bool = False):
    """Measure the mid-time of every transit in the data.

    Each chosen planet gets a listed mid-time for every epoch with data
    (``Planet(transit_times=, transit_epochs=)``); each time starts at the
    best of a grid of shifts (the chi^2 of that transit's own points), and
    then all of them are fitted together, with the parameters named in
    ``free``, by ``jaxppo.fit`` (Levenberg-Marquardt). Overlapping
    transits (two planets on the star at once, occulting each other or not)
    are fitted together with the exact model. The errors
    are those of the fit's linearised covariance (each mid-time's marginal
    error, the other free parameters free too). The times feed
    ``linear_ephemeris`` and an O-C diagram (``jaxppo ttv`` writes both).

    Parameters
    ----------
    system : System
        The model: its ephemerides give the starting times (a planet with
        ``transit_times`` starts from them).
    lightcurve : LightCurve or lightkurve.LightCurve
        The data (its ``exposure`` is integrated).
    planets : str or int or sequence of str or int, optional
        The names (or indices) of the planets whose times are measured
        (default None: all; the others keep their ephemerides).
    free : str or sequence of str, optional
        Other parameters fitted together with the times (names of
        ``jaxppo.parameter_names``, e.g. ``("b.radius", "b.a", "b.inc",
        "lc.baseline")``). Default none: the times alone, the rest fixed at
        ``system``.
    search : float or Quantity or None, optional
        Half-width of the grid of starting shifts per planet [d] (a time
        Quantity is converted; default
        None: the half-duration of its transit, first to last contact).
    grid : int, optional
        Number of starting shifts per transit (default 41), >= 3.
    min_points : int, optional
        A transit is measured when at least this many points lie between its
        first and last contact (default 3), >= 1.
    alpha : float, optional
        Tilt of the tilted planet's orbit [deg] (default 0).
    case : str or tuple of int, optional
        Hemisphere case (default "same"; see ``System.flux``).
    return_fit : bool, optional
        Also return the joint fit (default False).
    progress : bool, optional
        Print one line per stage (default False).

    Returns
    -------
    table : astropy.table.Table
        One row per transit, sorted by planet and epoch, with columns
        ``planet``, ``epoch`` (0: the transit at the planet's t0), ``tc``
        [d], ``tc_err`` [d] (1 sigma, from the fit's covariance), ``chi2``
        and ``n_points`` (the chi^2 and number of the points between first
        and last contact of that transit, padded by the exposure). ``meta``
        holds the fit's ``chi2``, ``n_points``, ``reduced_chi2``,
        ``success``, ``message``, ``free`` and ``parameters`` (name ->
        [value, 1-sigma error] of the free parameters other than the times).
    fit : FitResult
        Only with ``return_fit=True``, as ``(table, fit)``: the joint fit,
        whose ``system`` carries the measured times.

    Raises
    ------
    ValueError
        When the system has N-body orbits or moons, the light curve has no points;
        ``grid`` is not an integer >= 3
        or ``min_points`` not an integer >= 1; ``planets`` names an unknown
        planet or one planet twice; ``free`` names a transit time or the t0
        of a measured planet (those are measured here); ``search`` is not a
        positive number of days; or no transit of the chosen planets has
        ``min_points`` points between first and last contact.

    Warns
    -----
    UserWarning
        When the joint fit does not converge (``meta["success"]`` is then
        False), when a transit fits far worse than the median transit (a
        time in a wrong minimum, or a transit the model does not describe),
        or when a chosen planet has no transit with ``min_points`` points in
        the data (it gets no row); and when a transit's time is ambiguous:
        the chi^2 of its points over its time has another minimum within
        Delta chi^2 = 4 of the fitted one, more than 3 tc_err away (listed
        in ``meta["ambiguous"]``: planet, epoch, ``tc_other``, its
        ``delta_chi2``; tc_err, the curvature of one minimum, then
        understates the uncertainty).

    Examples
    --------
    Two simulated transits of one planet:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> b = jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")
    >>> system = jp.System(jp.Star.quadratic(0.4, 0.25), [b])
    >>> t = np.concatenate([np.linspace(-0.15, 0.15, 100), np.linspace(2.85, 3.15, 100)])
    >>> lc = jp.simulate(system, t, noise=1e-3, seed=1)
    >>> table = jp.measure_transit_times(system, lc)
    >>> table.colnames
    ['planet', 'epoch', 'tc', 'tc_err', 'chi2', 'n_points']
    >>> for row in table:
    ...     print(f"{row['planet']} {row['epoch']}: tc = {row['tc']:.4f} d +- {row['tc_err'] * 1440:.1f} min")
    b 0: tc = 0.0005 d +- 0.6 min
    b 1: tc = 2.9994 d +- 0.6 min
    >>> table.meta["success"]
    True
    """
    require_keplerian(system, "measure_transit_times")  # an N-body system makes its own times
    lc = checked_lightcurve(lightcurve, "measure_transit_times")
    time = np.asarray(lc.time, float)
    if time.size == 0:
        raise ValueError("lightcurve has no points")
    if int(grid) != grid or grid < 3:
        raise ValueError(f"grid must be an integer >= 3 (the starting shifts per transit), got {grid!r}")
    if int(min_points) != min_points or min_points < 1:
        raise ValueError(f"min_points must be an integer >= 1, got {min_points!r}")
    chosen = _planet_indices(system, planets)
    free = (free,) if isinstance(free, str) else tuple(free)
    for name in free:
        owner, _, par = str(name).partition(".")
        if par.startswith("tc") or (par == "t0" and owner in [planet_label(system, i) for i in chosen]):
            raise ValueError(f"free: {name!r} is measured here (every transit time of the chosen planets is free; "
                             "their t0 is then degenerate with them); name the other parameters only")
    search = None if search is None else from_quantity("search", search, "d")  # a time Quantity in days
    if search is not None and not (np.ndim(search) == 0 and np.isfinite(float(search)) and float(search) > 0):
        raise ValueError(f"search must be a positive half-width [d], got {search!r}")
    start, plan = _plan(system, lc, chosen, int(min_points), search)
    names = [p["name"] for p in plan]
    say = (lambda m: print(f"measure_transit_times: {m}", flush=True)) if progress else (lambda m: None)
    say(f"{len(names)} transits of {len(chosen)} planet(s); grid of {grid} starting shifts")
    # a shift of half a duration moves a disk by about 1 + p stellar radii
    model = Model(start, lc, tuple(names) + free, alpha, case, active_margin=2.5)
    slot_idx = [model.free.index(n) for n in names]
    search_of, windows = np.array([p["search"] for p in plan]), [p["window"] for p in plan]
    theta = _grid_start(model, slot_idx, search_of, int(grid), windows)
    theta = _joint_grid(model, theta, slot_idx, names, search_of, int(grid), windows, lc, alpha, case)
    say("joint fit of every time" + (f" and {list(free)}" if free else ""))
    with warnings.catch_warnings():  # chi^2 / (N - k): said once, below, in terms of tc_err
        warnings.filterwarnings("ignore", message=r"jaxppo\.fit: chi\^2 / \(N - k\)")
        result = fit(model.to_system(theta), lc, free=tuple(names) + free, alpha=alpha, case=case, progress=progress)
    if not result.success:
        warnings.warn(f"measure_transit_times: the fit did not converge ({result.message}); the times are where "
                      "it stopped and their errors may be wrong", UserWarning, stacklevel=2)
    final = Model(result.system, lc, tuple(names) + free, alpha, case, active_margin=1.0)
    table = _result_table(final, result, plan, lc)
    _warn_undetected(plan, _detection(final, result, plan, lc))
    _warn_ambiguous(table, plan, _second_minima(model, result, plan, slot_idx, int(grid)))
    _warn_misfits(table)
    _warn_understated_errors(result, lc)
    return (table, result) if return_fit else table


def _warn_understated_errors(result: FitResult, lc) -> None:
    """Warn where the fit's chi^2 / (N - k) says the flux errors understate
    the scatter (above 1.25 with a chi^2 p-value below 1e-3, as the scan's
    goodness-of-fit check) and no jitter is free: every tc_err is then too
    small by about sqrt(chi^2 / (N - k)) (a review: 2.8, pulls of rms 2)."""
    from scipy.special import chdtrc

    if "lc.jitter" in result.names or not np.isfinite(result.reduced_chi2):
        return
    dof = max(len(lc) - len(result.names), 1)
    if result.reduced_chi2 > 1.25 and chdtrc(dof, result.reduced_chi2 * dof) < 1e-3:
        warnings.warn(f"measure_transit_times: chi^2 / (N - k) = {result.reduced_chi2:.3g} for {len(lc)} points: the "
                      "flux errors understate the scatter, so every tc_err is too small by about "
                      f"{np.sqrt(result.reduced_chi2):.2g}x; free a jitter (free=('lc.jitter',), [ttv] free) or "
                      "check the errors", UserWarning, stacklevel=3)


def _plan(system: System, lc, chosen, min_points: int, search):
    """(the start: every chosen planet with a listed time for each of its
    transits in the data, [per transit: name "b.tc[n]", planet label,
    epoch, contacts (t1, t4) about mid-time, search half-width, the
    window of its points for the grid]) ."""
    time = np.asarray(lc.time, float)
    planets = list(system.planets)
    found = {}
    for i in chosen:
        found[i] = _data_epochs(system.planets[i], time, min_points)
        if found[i]:
            planets[i] = _with_times(system.planets[i], dict(found[i]))
    if not any(found.values()):
        labels = [planet_label(system, i) for i in chosen]
        raise ValueError(f"no transit of planet(s) {labels} has {min_points} or more points between first and last "
                         f"contact in the data (times {time.min():.3f}-{time.max():.3f} d); check t0, period and the "
                         "time system (BKJD for Kepler, BTJD for TESS)")
    if missing := [planet_label(system, i) for i in chosen if not found[i]]:
        # a chosen planet left out of the table without a word (a t0 on another time scale, a wrong period)
        warnings.warn(f"measure_transit_times: planet(s) {missing} have no transit with {min_points} or more points "
                      f"between first and last contact in the data (times {time.min():.3f}-{time.max():.3f} d), so "
                      "no time of theirs is measured; check t0, period and the time system if they should transit "
                      "there", UserWarning, stacklevel=3)
    start = System(system.star, planets, system.tilted)
    pad = float(lc.exposure or 0.0)
    plan = []
    for i in chosen:
        t1, t4 = (float(v) for v in system.planets[i].contacts())
        width = 0.5 * (t4 - t1) if search is None else float(search)
        label = planet_label(system, i)
        period = float(system.planets[i].period)
        if search is not None and width >= 0.5 * period:
            raise ValueError(f"search must be below half the period of planet {label} (P / 2 = {0.5 * period:g} d: "
                             f"a shift of half a period is the next transit), got {width:g} d (search is in days)")
        for n, _ in found[i]:
            tc = start.planets[i].mid_time(n)
            plan.append({"name": f"{label}.tc[{n}]", "planet": label, "epoch": n, "contacts": (t1, t4),
                         "search": width, "period": period,
                         "window": (time >= tc + t1 - pad - width) & (time <= tc + t4 + pad + width)})
    return start, plan


#: The least Delta chi^2 (3 sigma) by which a transit's points must prefer
#: the transit at its measured time to no transit, and the least squared
#: signal-to-noise ratio its dip may have in them, for its time to count as
#: measured (``_detection``).
DETECTION_CHI2 = 9.0


def _detection(model: Model, result: FitResult, plan, lc) -> tuple[np.ndarray, np.ndarray]:
    """Per transit, on its points (first to last contact about the measured
    time, padded by the exposure), with the transit moved off them (its time
    shifted by its duration and two exposures): (chi^2 without the transit
    minus chi^2 at the fit, the squared signal-to-noise ratio of the dip,
    sum of (model - model without it)^2 / variance). NaN where the shifted
    time would pass the neighbours' (a duration over a fifth of the period).
    A transit in the data gives about the squared S/N (+- 2 S/N); a time
    fitted to noise about minus it; the S/N says what the data can show."""
    time = np.asarray(lc.time, float)
    pad = float(lc.exposure or 0.0)
    theta = model.theta_from(jnp.asarray(result.values), model.to_theta(model.system))
    delta, snr2 = np.full(len(plan), np.nan), np.full(len(plan), np.nan)
    rows, thetas, points = [], [], []
    for i, p in enumerate(plan):
        t1, t4 = p["contacts"]
        shift = 1.01 * (t4 - t1) + 2.0 * pad
        if 2.0 * (t4 - t1 + 2.0 * pad) + shift >= p["period"]:
            continue
        tc = float(result.values[result.names.index(p["name"])])
        rows.append(i)
        thetas.append(theta.at[model.free.index(p["name"])].add(shift))
        points.append((time >= tc + t1 - pad) & (time <= tc + t4 + pad))
    if rows:
        r = np.asarray(model.residuals_batch(jnp.stack([theta] + thetas)))[:, :model.y.size]
        for j, (i, w) in enumerate(zip(rows, points)):
            delta[i] = float(np.sum(r[j + 1, w] ** 2) - np.sum(r[0, w] ** 2))
            snr2[i] = float(np.sum((r[j + 1, w] - r[0, w]) ** 2))
    return delta, snr2


#: A transit's time is ambiguous where the chi^2 of its points, over its
#: time alone (the others and the shape at the fit), has another local
#: minimum less than this above the fitted one (2 sigma), more than
#: ``DISTINCT_ERRORS`` tc_err away (``_second_minima``).
AMBIGUOUS_CHI2 = 4.0
DISTINCT_ERRORS = 3.0


def _second_minima(model: Model, result: FitResult, plan, slots, grid: int) -> list:
    """Per transit: (time of the lowest other local minimum of the chi^2 of
    its points over its time [d], that chi^2 less the fitted one), or None
    where no other minimum lies within ``AMBIGUOUS_CHI2`` of it. The time
    runs over the start's search range (the grid of ``_grid_start``, whose
    program and frames serve here), every other parameter at the fit;
    transits that share no point at once. A local minimum of that coarse
    profile (the fitted time among its points) that could lie within
    ``AMBIGUOUS_CHI2`` of the fit at the bottom of its well (its chi^2 less
    (half the step / tc_err)^2) is measured on a grid of the same size
    across two steps about it. A long-cadence transit of 9 points measured
    29 min off at +- 7.6 min (3.8 sigma) where its chi^2 at the true time
    was 1.5 higher."""
    start = np.asarray(model.to_theta(model.system))
    theta = np.asarray(model.theta_from(jnp.asarray(result.values), jnp.asarray(start)))
    err = np.array([float(result.errors[result.names.index(p["name"])]) for p in plan])
    search = np.array([p["search"] for p in plan])
    windows = [p["window"] for p in plan]
    size = start_shifts(grid).size
    frac = np.linspace(-1.0, 1.0, size - 1)
    out = [None] * len(plan)
    for members in _classes(windows):
        idx = np.array([slots[i] for i in members])
        coarse = start[idx][None, :] + frac[:, None] * search[members][None, :]
        prof = _profiles(model, theta, idx, coarse, windows, members)
        step = 2.0 * search[members] / (size - 2)
        centres = np.full(len(members), np.nan)
        for col, i in enumerate(members):
            j = _other_minimum(coarse[:, col], prof[1:, col], theta[slots[i]], prof[0, col], err[i])
            if j is not None and prof[1 + j, col] - prof[0, col] < AMBIGUOUS_CHI2 + (0.5 * step[col] / err[i]) ** 2:
                centres[col] = coarse[j, col]
        if not np.any(np.isfinite(centres)):
            continue
        fine = np.where(np.isfinite(centres), centres, theta[idx])[None, :] + np.linspace(-1.0, 1.0, size - 1)[
            :, None] * np.where(np.isfinite(centres), step, 0.0)[None, :]
        prof = _profiles(model, theta, idx, fine, windows, members)
        for col, i in enumerate(members):
            if np.isfinite(centres[col]):
                j = int(np.argmin(prof[1:, col]))
                dchi2 = float(prof[1 + j, col] - prof[0, col])
                if dchi2 < AMBIGUOUS_CHI2 and abs(fine[j, col] - theta[slots[i]]) > DISTINCT_ERRORS * err[i]:
                    tc = float(result.values[result.names.index(plan[i]["name"])])
                    out[i] = (tc + float(fine[j, col] - theta[slots[i]]), dchi2)
    return out


def _profiles(model: Model, theta, idx, times, windows, members) -> np.ndarray:
    """chi^2 of each member transit's window at the fit (row 0) and with
    the times ``idx`` of theta set to each row of ``times`` [rows, members]
    (one batch of the grid's size)."""
    thetas = np.tile(theta, (times.shape[0] + 1, 1))
    thetas[1:, idx] = times
    r2 = np.asarray(model.residuals_batch(jnp.asarray(thetas)))[:, :model.y.size] ** 2
    return np.stack([r2[:, windows[i]].sum(1) for i in members], 1)


def _other_minimum(t, f, t_fit: float, f_fit: float, err: float):
    """Index of the lowest local minimum of the profile f(t) (the fit
    (t_fit, f_fit) among its points, so that the fit's own well has none
    but the fit) more than ``DISTINCT_ERRORS`` err from the fit, or None."""
    if not np.isfinite(err) or err <= 0:
        return None
    tt, ff = np.append(t, t_fit), np.append(f, f_fit)
    order = np.argsort(tt, kind="stable")
    tt, ff = tt[order], ff[order]
    local = np.nonzero((ff[1:-1] < ff[:-2]) & (ff[1:-1] <= ff[2:]))[0] + 1
    local = [order[j] for j in local if order[j] < t.size and abs(tt[j] - t_fit) > DISTINCT_ERRORS * err]
    return min(local, key=lambda j: f[j]) if local else None


def _warn_ambiguous(table, plan, second) -> None:
    """Warn about (and list in ``table.meta["ambiguous"]``) the transits
    whose time ``_second_minima`` finds ambiguous: their tc_err, the
    curvature of one minimum, understates the uncertainty."""
    rows = [{"planet": p["planet"], "epoch": int(p["epoch"]), "tc_other": t, "delta_chi2": d}
            for p, found in zip(plan, second) if found is not None for t, d in [found]]
    table.meta["ambiguous"] = rows
    if rows:
        tc = {(str(r["planet"]), int(r["epoch"])): float(r["tc"]) for r in table}
        which = ", ".join(f"{r['planet']} epoch {r['epoch']} ({1440.0 * (r['tc_other'] - tc[(r['planet'], r['epoch'])]):+.1f}"
                          f" min, Delta chi^2 {r['delta_chi2']:+.2f}" + (", below the fitted time's: the fit ended in "
                                                                        "the higher of two minima" if r["delta_chi2"] < 0
                                                                        else "") + ")" for r in rows)
        warnings.warn(f"measure_transit_times: {which}: the chi^2 of the transit's points has another minimum "
                      f"within Delta chi^2 = {AMBIGUOUS_CHI2:g} of the fitted time, more than {DISTINCT_ERRORS:g} "
                      "tc_err away (the offset from the fitted time given): the time is ambiguous and tc_err, the "
                      "curvature of one minimum, understates its uncertainty (table.meta['ambiguous'])", UserWarning,
                      stacklevel=3)


def _warn_undetected(plan, detection) -> None:
    """Warn about transits whose dip the data cannot show (squared S/N
    below ``DETECTION_CHI2``) or whose points do not prefer the transit at
    its measured time to no transit by ``DETECTION_CHI2`` (``_detection``):
    their times and errors are fitted to noise."""
    bad = [(p["planet"], p["epoch"], d, s) for p, d, s in zip(plan, *detection)
           if np.isfinite(d) and min(d, s) < DETECTION_CHI2]
    if bad:
        which = ", ".join(f"{p} epoch {e} (Delta chi^2 {d:.1f}, S/N {np.sqrt(s):.1f})" for p, e, d, s in bad)
        warnings.warn(f"measure_transit_times: {which}: the data do not show the transit (its points prefer it to "
                      f"no transit by less than Delta chi^2 = {DETECTION_CHI2:g}, or its dip has S/N below 3 in "
                      "them), so its time and tc_err are fitted to noise; check the ephemeris and the time system "
                      "(BKJD for Kepler, BTJD for TESS: LightCurve.to_time_zero)", UserWarning, stacklevel=3)


def _warn_misfits(table) -> None:
    """Warn about transits whose chi^2 per point lies far (5 sigma of a
    chi^2 of that many points) above the median transit's: a time in a
    wrong minimum (or a transit the model does not describe)."""
    n = np.asarray(table["n_points"], float)
    chi2 = np.asarray(table["chi2"], float)
    ok = n > 0
    if ok.sum() < 3:
        return
    level = float(np.median(chi2[ok] / n[ok]))
    bad = ok & (chi2 > level * (n + 5.0 * np.sqrt(2.0 * np.maximum(n, 1.0))))
    if bad.any():
        which = ", ".join(f"{p} epoch {e} (chi^2 {c:.0f} for {k:.0f} points)" for p, e, c, k in
                          zip(table["planet"][bad], table["epoch"][bad], chi2[bad], n[bad]))
        warnings.warn(f"measure_transit_times: {which} fit far worse than the median transit (chi^2 per point "
                      f"{level:.2f}): a time in a wrong minimum, or a transit the model does not describe; check "
                      "it (e.g. another start or search)", UserWarning, stacklevel=3)


def _result_table(model: Model, result: FitResult, plan, lc):
    """The table of ``measure_transit_times`` from the joint fit."""
    from astropy.table import Table

    time = np.asarray(lc.time, float)
    pad = float(lc.exposure or 0.0)
    k = [result.names.index(p["name"]) for p in plan]
    tc = np.array([float(result.values[j]) for j in k])
    # the points of each transit at its measured time: first to last contact, padded by the exposure
    points = [(time >= t + p["contacts"][0] - pad) & (time <= t + p["contacts"][1] + pad) for t, p in zip(tc, plan)]
    chi2, npts = _window_stats(model, result, points)
    table = Table()
    table["planet"] = [p["planet"] for p in plan]
    table["epoch"] = np.array([p["epoch"] for p in plan], int)
    table["tc"] = tc
    table["tc"].unit = "d"
    table["tc_err"] = np.array([float(result.errors[j]) for j in k])
    table["tc_err"].unit = "d"
    table["chi2"] = chi2
    table["n_points"] = npts
    table = table[np.lexsort((table["epoch"], table["planet"]))]
    table.meta.update({"chi2": float(result.chi2), "n_points": int(time.size),
                       "reduced_chi2": float(result.reduced_chi2), "success": bool(result.success),
                       "message": str(result.message), "free": list(result.names),
                       "parameters": {n: [float(v), float(e)] for n, v, e in zip(result.names, result.values,
                                                                                 result.errors) if ".tc[" not in n}})
    return table
