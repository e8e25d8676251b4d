"""Least-squares fits: optimistix Levenberg-Marquardt over the named free
parameters of ``._params`` in the coordinates of ``Model``, with a
check that the solution is a minimum (Hessian and Newton step) and the
linearised covariance there.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np

from ..model._lightcurve import LightCurve
from ..model._programs import stored
from ..model._system import System
from ._model import Model, scaled_residuals
from ._params import as_lightcurve, planet_value, star_value
from ._serialise import from_jsonable, system_from_dict, system_to_dict, to_jsonable

__all__ = ["fit", "FitResult", "CONDITION_WARN"]

# fit warns when the condition number of the scaled Fisher matrix exceeds
# this: some combination of the free parameters is 1e3 times less determined
# than the parameters one by one, and the linearised errors mislead
CONDITION_WARN = 1e6


@dataclasses.dataclass
class FitResult:
    """Result of ``jaxppo.fit``: the best-fit system, chi^2 and the covariance of the free parameters.

    The covariance is the linearised one at the solution, in physical units
    (days, degrees, R*, relative flux), in ``names`` order ("lc.baseline"
    expanded per window and power). With ``"lc.jitter"`` free, ``chi2`` is
    the minimised objective -2 ln L - sum ln(2 pi sigma_i^2) (chi^2 with the
    inflated errors plus sum ln(1 + s^2 / sigma_i^2)), ``reduced_chi2`` its
    chi^2 part / (N - k), and the covariance is twice the inverse Hessian of
    the objective (the Gauss-Newton form misses the jitter's curvature).
    When ``condition`` exceeds ``CONDITION_WARN`` (1e6) fit warns: the
    linearised errors are unreliable, use ``jaxppo.sample``.
    ``save`` and ``load`` write and read it as JSON.

    Attributes
    ----------
    system : System
        The best-fit system (the start where the fit could not begin).
    chi2 : float
        chi^2 at the solution (with a free jitter: the objective above).
    covariance : numpy.ndarray
        Covariance of the free parameters in physical units [k, k] (NaN
        when it could not be computed).
    success : bool
        Whether the fit converged to a minimum (see ``jaxppo.fit``).
    message : str
        "converged: ..." or "failed: " and why.
    names : tuple of str
        The free parameters, k of them.
    values : numpy.ndarray
        Best-fit values of the free parameters [k] (physical units).
    errors : numpy.ndarray
        Their 1-sigma errors [k], the square roots of the diagonal of
        ``covariance``.
    reduced_chi2 : float
        chi^2 / (N - k), N data points.
    steps : int
        Levenberg-Marquardt steps taken in all passes (0 when the fit could
        not begin).
    union_frames : numpy.ndarray
        Indices of the model frames integrated by the exact union integral
        (overlapping disks at the start or at the solution, with a margin).
    derived : dict
        Name -> (value, 1-sigma error) of implied quantities: "star.u1",
        "star.u2" when Kipping's q1 or q2 is free.
    condition : float
        Condition number of the Fisher matrix scaled to unit diagonal (inf
        when a parameter does not move the model).

    Examples
    --------
    Fit the mid-time and radius of a simulated transit, starting off both:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> star = jp.Star.quadratic(0.4, 0.25)
    >>> truth = jp.System(star, [jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")])
    >>> lc = jp.simulate(truth, np.linspace(-0.15, 0.15, 200), noise=1e-3, seed=1)
    >>> start = jp.System(star, [jp.Planet(period=3.0, t0=0.003, a=10.0, inc=89.0, radius=0.09, name="b")])
    >>> result = jp.fit(start, lc, free=("b.t0", "b.radius"))
    >>> print(result.table())
    b.t0                 0.000146... +- 3.01e-04
    b.radius             0.100244... +- 5.91e-04
    chi2 = 171.61, reduced 0.867, converged: Newton step would lower chi^2 by ...
    >>> print(f"{float(result.system.planets[0].radius):.4f}")  # the best-fit system
    0.1002
    >>> print(np.round(result.covariance / np.outer(result.errors, result.errors), 3))  # correlations
    [[ 1.    -0.001]
     [-0.001  1.   ]]
    >>> same = jp.FitResult.load(result.save("fit.json"))
    >>> same.names, bool(np.array_equal(same.covariance, result.covariance))
    (('b.t0', 'b.radius'), True)
    """

    system: System
    chi2: float
    covariance: np.ndarray
    success: bool
    message: str
    names: tuple
    values: np.ndarray
    errors: np.ndarray
    reduced_chi2: float
    steps: int
    union_frames: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    derived: dict = dataclasses.field(default_factory=dict)
    condition: float = float("nan")

    def table(self) -> str:
        """Format the result as text.

        Returns
        -------
        str
            One line per free parameter (name, value, 1-sigma error), one
            per derived quantity (marked "(derived)"), and a last line with
            chi^2, the reduced chi^2 and ``message``.

        Examples
        --------
        See ``FitResult``.
        """
        rows = [f"{n:14s} {v:16.8f} +- {e:.2e}" for n, v, e in zip(self.names, self.values, self.errors)]
        rows += [f"{n:14s} {v:16.8f} +- {e:.2e} (derived)" for n, (v, e) in self.derived.items()]
        return "\n".join(rows + [f"chi2 = {self.chi2:.2f}, reduced {self.reduced_chi2:.3f}, {self.message}"])

    def save(self, path) -> str:
        """Write the result as JSON.

        The file holds the format tag "jaxppo.FitResult", the jaxppo
        version, every field (free names, values, errors, covariance, chi^2,
        ...) and the fitted system; ``load`` reads it back exactly
        (floats are written with 17 significant digits; NaN as null).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (overwritten).

        Returns
        -------
        str
            ``path``.
        """
        from .._version import __version__

        out = {"format": "jaxppo.FitResult", "version": __version__, "names": list(self.names),
               "values": to_jsonable(self.values), "errors": to_jsonable(self.errors),
               "covariance": to_jsonable(self.covariance), "chi2": to_jsonable(self.chi2),
               "reduced_chi2": to_jsonable(self.reduced_chi2), "success": bool(self.success),
               "message": self.message, "steps": int(self.steps),
               "union_frames": [int(i) for i in np.asarray(self.union_frames)],
               "derived": {k: to_jsonable(list(v)) for k, v in self.derived.items()},
               "condition": to_jsonable(self.condition), "system": system_to_dict(self.system)}
        with open(path, "w") as fh:
            json.dump(out, fh, indent=1, allow_nan=False)
        return str(path)

    @classmethod
    def load(cls, path) -> "FitResult":
        """Read a result written by ``save`` (or ``jaxppo fit --out``).

        Parameters
        ----------
        path : str or os.PathLike
            The JSON file.

        Returns
        -------
        FitResult
            The result as saved.

        Raises
        ------
        ValueError
            When the file is not JSON, or not a file written by ``save``.
        """
        try:
            with open(path) as fh:
                d = json.load(fh)
        except json.JSONDecodeError as err:
            raise ValueError(f"{path}: not a JSON file written by FitResult.save ({err})") from None
        if not isinstance(d, dict) or d.get("format") != "jaxppo.FitResult":
            raise ValueError(f"{path}: not a FitResult file (format {d.get('format') if isinstance(d, dict) else None!r})")
        arr = lambda v: np.asarray(from_jsonable(v), float)  # noqa: E731
        return cls(system_from_dict(d["system"]), float(from_jsonable(d["chi2"])), arr(d["covariance"]).reshape(
            len(d["names"]), len(d["names"])), bool(d["success"]), d["message"], tuple(d["names"]), arr(d["values"]),
            arr(d["errors"]), float(from_jsonable(d["reduced_chi2"])), int(d["steps"]),
            np.asarray(d["union_frames"], int), {k: tuple(from_jsonable(v)) for k, v in d["derived"].items()},
            float(from_jsonable(d["condition"])))


def fit(system: System, lightcurve: LightCurve, free=("b.t0", "b.radius"), alpha: float = 0.0, case: str = "same",
        max_steps: int = 200, rtol: float = 1e-6, atol: float = 1e-6, progress: bool = False,
        fold_inc: bool = True) -> FitResult:
    """Fit the named free parameters to a light curve by least squares.

    optimistix's Levenberg-Marquardt over the free parameters, in
    coordinates that keep the physics valid (a > 1, radius > 0, a transiting
    impact parameter; ``jaxppo.inference._params``); everything else
    stays at ``system``'s values. Limb darkening stays fixed unless named
    (``"star.u1"``, or Kipping's ``"star.q1"``, ``"star.q2"``); the
    light-curve nuisance parameters ``"lc.offset"``, ``"lc.jitter"``,
    ``"lc.baseline"`` / ``"lc.baseline2"`` are described in
    ``jaxppo.inference._params``; ``jaxppo.parameter_names`` lists
    every name. Never raises for a failed fit: ``success`` is False and
    ``message`` says why.

    ``success`` means more points than free parameters, a start and a
    solution at which every planet with a free parameter transits in the
    data, a finite chi^2, and a solution that is a minimum: the Hessian of
    chi^2 there is positive definite and a Newton step from it would lower
    chi^2 by less than 0.01. When optimistix stops elsewhere (its step
    criteria are met where chi^2 is flat, e.g. from a start with a tiny
    radius), the fit restarts from there in coordinates scaled by the
    Jacobian's columns before it reports failure.

    Parameters
    ----------
    system : System
        The start: the free parameters' starting values and every fixed one.
    lightcurve : LightCurve or lightkurve.LightCurve
        The data (its ``exposure`` is integrated).
    free : sequence of str, optional
        Names of the free parameters (default ``("b.t0", "b.radius")``).
    alpha : float, optional
        Tilt of the tilted planet's orbit [deg] (default 0).
    case : str or tuple of int, optional
        Hemisphere case (default "same"; see ``System.flux``).
    max_steps : int, optional
        Most Levenberg-Marquardt steps per pass (default 200). Each pass
        ends with the minimum check: a pass that used them all at a point
        the check accepts is a minimum; otherwise the fit takes another
        pass (four on the same frames at most, ten in all).
    rtol : float, optional
        optimistix's relative tolerance (default 1e-6).
    atol : float, optional
        optimistix's absolute tolerance (default 1e-6).
    progress : bool, optional
        Print one line per stage on stderr (default False).
    fold_inc : bool, optional
        The light curve depends on |cos i| only (the sign of cos i cannot be
        measured, docs/conventions.md), so a fitted inclination is reported
        folded into [0, 90] deg (the same chi^2 and errors; the correlations
        of inc change sign). False keeps the side of 90 deg the fit ended on.
        Default True.

    Returns
    -------
    FitResult
        The best-fit system, chi^2, values, errors and covariance of the free
        parameters, ``success`` and ``message``.

    Raises
    ------
    ValueError
        When a name in ``free`` is unknown or names a parameter twice (or
        names degenerate pairs, such as "lc.offset" with "lc.baseline", or
        u1/u2 with q1/q2), or ``lightcurve`` is neither a jaxppo nor a
        lightkurve LightCurve.

    Warns
    -----
    UserWarning
        When the linearised covariance is degenerate or ill-conditioned (not
        a failure): ``FitResult.condition`` > ``CONDITION_WARN``, or chi^2 at
        1 sigma along a principal axis of the covariance differs from
        chi^2_min + 1 by more than a factor 4 (e.g. a and inc of a grazing or
        single transit): the posterior is then far from Gaussian and
        ``jaxppo.sample`` gives the errors.

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> star = jp.Star.quadratic(0.4, 0.25)
    >>> truth = jp.System(star, [jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")])
    >>> lc = jp.simulate(truth, np.linspace(-0.15, 0.15, 200), noise=1e-3, seed=1)
    >>> start = jp.System(star, [jp.Planet(period=3.0, t0=0.003, a=10.0, inc=89.0, radius=0.09, name="b")])
    >>> result = jp.fit(start, lc, free=("b.t0", "b.radius"))
    >>> result.success
    True
    >>> for name, value, error in zip(result.names, result.values, result.errors):
    ...     print(f"{name} = {value:.4f} +- {error:.4f}")
    b.t0 = 0.0001 +- 0.0003
    b.radius = 0.1002 +- 0.0006
    """
    clock = time.perf_counter()

    def say(text):
        if progress:
            print(f"fit: {text} ({time.perf_counter() - clock:.1f} s)", file=sys.stderr, flush=True)

    lightcurve = as_lightcurve(lightcurve)
    model = Model(system, lightcurve, free, alpha, case, union_floor=128)
    theta = model.to_theta(system)
    n, k = lightcurve.time.size, len(model.free)
    problems = _start_problems(model, system, n, k)
    say(f"{n} points, {k} free parameters; compiling the model")
    # from the Jacobian's program, which the minimum check compiles anyway
    # (a separate residual program would cost a compilation of its own)
    chi2_start = float(np.sum(np.asarray(model.jacobian(theta)[1]) ** 2))
    if not np.isfinite(chi2_start):
        problems.append(f"chi^2 at the start is {chi2_start} (flux_err as small as {np.min(lightcurve.flux_err):.3g} "
                        "makes the residuals overflow float64, or the model is not finite)")
    if problems:
        return _failed_start(model, system, theta, chi2_start, n, problems)
    say(f"chi^2 at the start {chi2_start:.6g}")
    model, theta, optx_problem, steps, verdict = _solve(model, theta, max_steps, rtol, atol, say)
    if fold_inc:
        theta, verdict["cov_theta"] = _fold_inc(model, theta, verdict["cov_theta"])
    problems = ([optx_problem] if optx_problem else []) + verdict["problems"]
    solved = model.to_system(theta)
    problems += [p.replace("at the start", "at the solution") for p in _transit_problems(model, solved)]
    ok = not problems
    message = ("converged: " + verdict["summary"]) if ok else "failed: " + "; ".join(problems)
    cov, derived, values = _physical_covariance(model, theta, verdict["cov_theta"])
    errors = np.sqrt(np.clip(np.diag(cov), 0, None))
    if ok and not np.all(np.isfinite(errors)):
        ok = False
        message = "failed: covariance not finite"
    _warn_if_degenerate(model.free, verdict)
    chi2_data = float(np.sum(verdict["residuals"][:n] ** 2)) if verdict["residuals"] is not None else np.nan
    say("done")
    return FitResult(model.result_system(theta, solved), verdict["chi2"], cov, ok, message, tuple(model.free),
                     values, errors, chi2_data / (n - k), steps, model.union_idx, derived,
                     verdict["condition"])


def _failed_start(model: Model, system: System, theta, chi2_start: float, n: int, problems) -> FitResult:
    """The FitResult of a start that cannot be fitted (no steps taken)."""
    k = len(model.free)
    nan = np.full((k, k), np.nan)
    # the start as given (the coordinates would clip an impossible inclination)
    ph = np.asarray(model.physical(theta), float)
    start = np.array([ph[i] if owner == "lc" or par in ("q1", "q2") else float(
        star_value(system, par) if owner == "star" else planet_value(system.planets[owner], par))
        for i, (owner, par) in enumerate(model.slots)])
    return FitResult(system, chi2_start, nan, False, "failed: " + "; ".join(problems), tuple(model.free),
                     start, np.full(k, np.nan), chi2_start / max(n - k, 1) if n > k else np.nan,
                     0, model.union_idx)


@stored(filtered=True)
def least_squares_pass(theta, scale, data, rtol: float, atol: float, max_steps: int):
    """One Levenberg-Marquardt pass (optimistix) in z = (theta' - theta) *
    scale from z = 0: (z at its end, the leaves of optimistix's result, its
    steps). A stored program (outputs of arrays only): a new process loads
    it instead of tracing the solver."""
    import optimistix as optx

    sol = optx.least_squares(scaled_residuals, optx.LevenbergMarquardt(rtol=rtol, atol=atol), jnp.zeros_like(theta),
                             args=(theta, scale, data), max_steps=max_steps, throw=False)
    return sol.value, tuple(jax.tree_util.tree_leaves(sol.result)), sol.stats["num_steps"]


def _solve(model: Model, theta, max_steps: int, rtol: float, atol: float, say):
    """Levenberg-Marquardt passes until the solution is a minimum of a model
    whose frame sets cover it. Returns (model, theta, optimistix's failure
    message or None, steps, the ``_assess`` verdict).

    The frames that take the union integral are fixed from the starting
    parameters (with a margin). If the solution brings disks together in
    other frames, those frames are added (a new Model with the same
    programs while the frame counts stay in their buckets), the solution is
    checked on it and refitted unless it is a minimum there. Each pass ends
    with the check (``_assess``), whatever optimistix's verdict: a pass that
    used its ``max_steps`` at a point the check accepts is a minimum, and
    one that met its tolerances at a point the check refuses is refitted.
    Levenberg-Marquardt damps with the
    identity, so where chi^2 is nearly flat in theta (a radius of 1e-6 R*)
    its steps are tiny and its step criteria are met far from the minimum;
    then restart in theta scaled by the Jacobian's columns (same residual
    function, so no recompilation)."""
    import optimistix as optx

    steps, restarts = 0, 0
    scale = jnp.ones_like(theta)
    verdict = None
    for stage in range(10):
        value, result, num_steps = least_squares_pass(theta, scale, model.data(), float(rtol), float(atol),
                                                      int(max_steps))
        result = jax.tree_util.tree_unflatten(jax.tree_util.tree_structure(optx.RESULTS.successful), result)
        theta = theta + value / scale
        steps += int(num_steps)
        say(f"Levenberg-Marquardt pass {stage + 1}: {steps} steps in all")
        wider = model.widened([model.to_system(theta)])
        if wider is not None:
            model = wider
            say(f"the solution brings disks together or onto the star in new frames: checking it with "
                f"{model.union_idx.size} union and {model.active_idx.size} computed frames")
        verdict = _assess(model, theta)
        say(f"checked the minimum: chi^2 {verdict['chi2']:.6g}"
            + ("" if verdict["optimum"] else "; not a minimum yet" if verdict["scale"] is not None else ""))
        if verdict["optimum"] or verdict["scale"] is None or restarts == 3:
            break
        scale, restarts = verdict["scale"], restarts + (wider is None)
    failure = None  # a pass that ran out of steps ends at a minimum all the same where the check says so
    if not verdict["optimum"] and not bool(result == optx.RESULTS.successful):
        failure = str(optx.RESULTS[result]) if hasattr(optx.RESULTS, "__getitem__") else str(result)
    return model, theta, failure, steps, verdict


def _fold_inc(model: Model, theta, cov_theta):
    """(theta, cov_theta) with every inclination's coordinate (b = (1 + p)
    tanh theta) made >= 0: i -> 180 deg - i, the identical light curve."""
    flip = np.array([-1.0 if par == "inc" and float(theta[k]) < 0 else 1.0 for k, (_, par) in enumerate(model.slots)])
    if cov_theta is not None:
        cov_theta = cov_theta * np.outer(flip, flip)
    return jnp.asarray(theta) * jnp.asarray(flip), cov_theta


def _physical_covariance(model: Model, theta, cov_theta):
    """(covariance of the free parameters in physical units, derived: name
    -> (value, 1-sigma error), the free parameters' values) from the
    covariance in theta: cov_q = D cov_theta D^T with D = dq / dtheta; NaN
    without ``cov_theta``."""
    k = len(model.free)
    jac, q = (np.asarray(v) for v in model.physical_jacobian(jnp.asarray(theta)))
    cov = np.full((q.size, q.size), np.nan) if cov_theta is None else jac @ cov_theta @ jac.T
    derived = {nm: (float(q[k + i]), float(np.sqrt(max(cov[k + i, k + i], 0.0))) if cov_theta is not None else np.nan)
               for i, nm in enumerate(model.derived_names())}
    return cov[:k, :k], derived, q[:k]


def _warn_if_degenerate(free, verdict) -> None:
    """The UserWarning of ``fit`` when the linearised covariance is
    ill-conditioned or chi^2 at its 1 sigma is far from chi^2_min + 1."""
    condition, dchi2 = verdict["condition"], verdict["dchi2_1sigma"]
    why = []
    if condition > CONDITION_WARN:
        why.append(f"condition number {condition:.3g} of the scaled Fisher matrix, most degenerate combination "
                   f"{verdict['weakest']}")
    # Delta chi^2 at the linearised 1 sigma outside [1/4, 4]: the error along
    # that axis is off by more than a factor 2 (a milder mismatch is common:
    # chi^2(t0) of 1-min data has kinks where samples cross contact points)
    if dchi2 is not None and not np.all((dchi2 > 0.25) & (dchi2 < 4.0)):
        worst = dchi2[np.argmax(np.abs(np.log(np.where(dchi2 > 0, dchi2, 1e-300))))]
        why.append(f"chi^2 rises by {worst:.3g} instead of 1 at 1 sigma along a principal axis of the covariance")
    if why:
        warnings.warn(
            f"jaxppo.fit: the linearised covariance of {list(free)} is degenerate or ill-conditioned ("
            + "; ".join(why) + "): the errors and correlations from the curvature are not reliable (e.g. a and inc "
            "of a grazing or single transit); jaxppo.sample gives the posterior", UserWarning, stacklevel=3)


def _transit_problems(model: Model, system: System) -> list:
    """Planets with a free parameter that do not transit in any model frame."""
    x, y, r = system.positions(np.asarray(model.t_model), model.alpha, model.case, xp=np)
    owners = sorted({o for o, _ in model.slots if o not in ("star", "lc")})
    if not owners:
        owners = list(range(len(system.planets)))
        need_all = False
    else:
        need_all = True
    missing = []
    for i in owners:
        on = (r[:, i] > 0) & (np.hypot(x[:, i], y[:, i]) < 1.0 + r[:, i])
        if not np.any(on):
            pl = system.planets[i]
            b = float(pl.impact)
            missing.append(f"planet {pl.name or i} does not transit in the data at the start "
                           f"(impact parameter {b:.3g}, t0 {float(pl.t0):.6f} d, radius {float(pl.radius):.3g} R*)")
    if not need_all and len(missing) < len(owners):
        return []
    return missing


def _start_problems(model: Model, system: System, n: int, k: int) -> list:
    out = []
    if n <= k:
        out.append(f"{n} data points for {k} free parameters {model.free}: a fit needs more points than free parameters")
    return out + _transit_problems(model, system)



def _assess(model: Model, theta) -> dict:
    """Is theta a minimum of chi^2? From the residuals' Jacobian J and the
    full Hessian H of chi^2, both with theta scaled by J's column norms (so
    the verdict does not depend on units): H positive definite and the
    Newton decrement g^T H^-1 g / 2 (the chi^2 a Newton step would gain)
    below 0.01. Also the covariance (J^T J)^-1 in theta."""
    jac, r = (np.asarray(v) for v in model.jacobian(theta))
    chi2 = float(np.sum(r**2))
    out = {"chi2": chi2, "problems": [], "optimum": False, "scale": None, "cov_theta": None, "summary": "",
           "condition": np.nan, "weakest": "", "dchi2_1sigma": None, "residuals": r}
    if not np.isfinite(chi2):
        out["problems"].append(f"chi^2 at the solution is {chi2}")
        return out
    c = np.sqrt(np.sum(jac**2, axis=0))
    flat = [n for n, ci in zip(model.free, c) if not ci > 0]
    if flat or not np.all(np.isfinite(jac)):
        out["problems"].append(f"the data do not constrain {flat} (zero or non-finite derivative at the solution)")
        out["condition"], out["weakest"] = np.inf, f"{flat} alone"
        return out
    out["scale"] = jnp.asarray(c)
    grad = 2.0 * (jac.T @ r) / c
    jtj = (jac / c).T @ (jac / c)
    jitter = any(par == "jitter" for _, par in model.slots)
    try:
        cov_gn = np.linalg.inv(jtj) / np.outer(c, c)
    except np.linalg.LinAlgError:
        cov_gn = None
    # the centre and +-h along each axis: residual vectors, which say which
    # parameters share data points (the others have no cross term)
    axis_pts = np.asarray(_hessian_points(c.size, []))
    res = np.asarray(model.residuals_batch(jnp.asarray(theta) + jnp.asarray(axis_pts) / c))
    pairs = _coupled_pairs(res)
    pts = _hessian_points(c.size, pairs)[len(axis_pts):]
    # the same batch also evaluates chi^2 at +-1 sigma along the principal
    # axes of the linearised covariance (see _axis_steps)
    axes = None if jitter else _axis_steps(cov_gn)
    if axes is not None:
        pts += list(axes * c)
    n_hess = len(axis_pts) + 4 * len(pairs)
    f_pairs = _chi2_at(model, np.asarray(theta) + np.array(pts).reshape(-1, c.size) / c, len(axis_pts))
    f = np.concatenate([np.sum(res**2, axis=1), f_pairs])
    hess = _second_differences(f, pairs, c.size)
    if not np.all(np.isfinite(hess)):
        out["problems"].append("the Hessian of chi^2 at the solution is not finite")
        return out
    _judge_minimum(out, hess, grad)
    _conditioning(out, jtj, model.free)
    if not jitter:
        out["cov_theta"] = cov_gn
        if axes is not None:
            out["dchi2_1sigma"] = f[n_hess:] - chi2
        return out
    return _laplace_with_jitter(out, model, theta, hess, c, len(axis_pts))


def _chi2_at(model: Model, thetas, rows: int) -> np.ndarray:
    """chi^2 at each row of ``thetas``: the residuals program of the
    Hessian's axis points (``rows`` rows, the last batch padded with its first
    row) run batch by batch, summed here. One program for every point of
    ``_assess``: a chi^2 program of its own cost a second compilation (1.3 s
    on the Kepler-20 b + c benchmark), and each batch size another."""
    out = []
    for lo in range(0, len(thetas), rows):
        batch = thetas[lo:lo + rows]
        batch = np.concatenate([batch, np.repeat(batch[:1], rows - len(batch), axis=0)])
        out.append(np.sum(np.asarray(model.residuals_batch(jnp.asarray(batch))) ** 2, axis=1)[:len(thetas) - lo])
    return np.concatenate(out) if out else np.zeros(0)


# Hessian of chi^2 in the scaled coordinates by second differences of chi^2
# itself (2 k^2 forward evaluations in one program; a traced jax.hessian
# costs ~8 s of compilation here). The step is a fraction of the scale on
# which chi^2 changes by 1: the light curve's second derivative jumps at
# contact points, and differences of the gradient over tiny steps read a
# 10-parameter Kepler-20 minimum as a saddle.
_HESSIAN_STEP = 0.3


def _hessian_points(k: int, pairs) -> list:
    """Points in the scaled coordinates: the centre, +-h along each axis,
    (+-h, +-h) in each of the ``pairs`` of axes (i, j), i < j."""
    h = _HESSIAN_STEP
    eye = np.eye(k) * h
    pts = [np.zeros(k)] + [s * eye[i] for i in range(k) for s in (1.0, -1.0)]
    pts += [si * eye[i] + sj * eye[j] for i, j in pairs for si in (1.0, -1.0) for sj in (1.0, -1.0)]
    return pts


def _coupled_pairs(res) -> list:
    """The pairs (i, j), i < j, of parameters that move a common residual
    (``res``: the residuals at the centre and at +-h along each axis, the
    rows of ``_hessian_points`` without pairs). Parameters that move
    disjoint sets of points (the transit times of different transits, the
    baselines of different windows) add separately to chi^2: their cross
    derivative is zero, and skipping those pairs turns the 2 k^2 chi^2
    evaluations of a fit of many transit times into a few per transit."""
    moved = np.abs(res[1:] - res[0]) > 0
    moved = moved[0::2] | moved[1::2]  # [k, n]: the points parameter i moves
    share = (moved.astype(np.int32) @ moved.T.astype(np.int32)) > 0
    k = share.shape[0]
    return [(i, j) for i in range(k) for j in range(i + 1, k) if share[i, j]]


def _second_differences(f, pairs, k: int) -> np.ndarray:
    """The Hessian from chi^2 ``f`` at the points of ``_hessian_points``
    (zero for the pairs not listed)."""
    h = _HESSIAN_STEP
    hess = np.zeros((k, k))
    for i in range(k):
        hess[i, i] = (f[1 + 2 * i] - 2 * f[0] + f[2 + 2 * i]) / h**2
    base = 1 + 2 * k
    for n, (i, j) in enumerate(pairs):
        fpp, fpm, fmp, fmm = f[base + 4 * n: base + 4 * n + 4]
        hess[i, j] = hess[j, i] = (fpp - fpm - fmp + fmm) / (4 * h**2)
    return hess


def _judge_minimum(out: dict, hess, grad) -> None:
    """Positive definite Hessian and a Newton decrement below 0.01: sets
    ``out["optimum"]``, ``"summary"`` or adds to ``"problems"``."""
    w = np.linalg.eigvalsh(0.5 * (hess + hess.T))
    # scaled so that the Gauss-Newton part has unit diagonal: eigenvalues
    # near 2 for well-determined parameters; 1e-9 of that is degenerate
    if w[0] <= 2e-9 * max(w[-1], 1.0):
        out["problems"].append(f"not a minimum: the Hessian of chi^2 is not positive definite (scaled eigenvalues "
                               f"{w[0]:.3g} .. {w[-1]:.3g}, gradient norm {np.linalg.norm(grad):.3g}); the free parameters are "
                               "degenerate, or the fit stopped on a slope or a saddle")
        return
    decrement = 0.5 * float(grad @ np.linalg.solve(hess, grad))
    out["summary"] = f"Newton step would lower chi^2 by {decrement:.2g}"
    if decrement > 0.01:
        out["problems"].append(f"not a minimum: a Newton step would lower chi^2 by {decrement:.3g}")
    else:
        out["optimum"] = True


def _conditioning(out: dict, jtj, free) -> None:
    """Condition number of the scaled Fisher matrix (unit diagonal) and its
    most degenerate combination: its smallest eigenvalue is 1 / (the
    variance inflation of the worst-determined combination of parameters
    over the parameters one at a time)."""
    wj, vj = np.linalg.eigh(jtj)
    out["condition"] = float(wj[-1] / wj[0]) if wj[0] > 0 else np.inf
    v0 = vj[:, 0]
    top = np.argsort(-np.abs(v0))[:3]
    out["weakest"] = " ".join(f"{v0[i]:+.2f} {free[i]}" for i in top if abs(v0[i]) > 0.1)


def _laplace_with_jitter(out: dict, model: Model, theta, hess, c, n_batch: int) -> dict:
    """With a free jitter, the Laplace covariance: -2 ln L ~ const +
    dtheta^T H dtheta, cov = 2 H^-1 (in scaled coordinates, back to theta
    by the column scales ``c``); the Gauss-Newton form of the augmented
    residuals misses the jitter's curvature. Then chi^2 at its 1 sigma
    (``_chi2_at`` in batches of ``n_batch``)."""
    try:
        out["cov_theta"] = 2.0 * np.linalg.inv(0.5 * (hess + hess.T)) / np.outer(c, c)
    except np.linalg.LinAlgError:
        return out
    axes = _axis_steps(out["cov_theta"])
    if axes is not None:
        out["dchi2_1sigma"] = _chi2_at(model, np.asarray(theta) + axes, n_batch) - out["chi2"]
    return out


def _axis_steps(cov_theta):
    """Steps in theta to +-1 sigma along each principal axis of the
    linearised covariance, where chi^2 - chi^2_min is exactly 1 if the
    Laplace approximation holds; None without a finite, positive-definite
    covariance."""
    if cov_theta is None or not np.all(np.isfinite(cov_theta)):
        return None
    w, v = np.linalg.eigh(0.5 * (cov_theta + cov_theta.T))
    if w[0] <= 0:
        return None
    return np.array([s * np.sqrt(w[i]) * v[:, i] for i in range(w.size) for s in (1.0, -1.0)])
