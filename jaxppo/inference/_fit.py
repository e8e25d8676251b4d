"""Least-squares fits: Levenberg-Marquardt (``._lm``) over the named free
parameters of ``._params`` in the coordinates of ``Model``, with a check
that the solution is a minimum (``._minimum``: Hessian and Newton step),
trust-region steps of that Hessian (carried between checks by secant
updates) where it is not, and the linearised covariance at the solution.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
import warnings

import jax.numpy as jnp
import numpy as np

from ..model._lightcurve import LightCurve
from ..model._system import System
from ._lm import LM_STATUS, check_settings, lm_pass, secant_update, trust_region_steps
from ._minimum import DECREMENT, assess, chi2_at, newton_decrement, precompile
from ._model import Model
from ._ecc import off_circular
from ._params import PERTURBER_PARAMS, checked_lightcurve, inc_sign_matters, planet_value, star_value
from ._serialise import from_jsonable, system_from_dict, system_to_dict, to_jsonable

__all__ = ["fit", "FitResult", "CONDITION_WARN", "misfit_note"]

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
        if "lc.jitter" in self.names:  # chi2 is the objective; the reduced chi^2 is of the inflated errors
            last = (f"-2 ln L - sum ln(2 pi sigma^2) = {self.chi2:.2f} (the objective with a free jitter), "
                    f"chi^2 with the jitter's errors / (N - k) = {self.reduced_chi2:.3f}, {self.message}")
        else:
            last = f"chi2 = {self.chi2:.2f}, reduced {self.reduced_chi2:.3f}, {self.message}"
        return "\n".join(rows + [last])

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

    Levenberg-Marquardt (Marquardt's scaling, Nielsen's damping; one
    compiled program, ``jaxppo.inference._lm``) over the free parameters, in
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
    chi^2 by less than 0.01 (the Hessian by second differences, along the
    parameters and along the combinations of them that the data determine
    10 times or more worse than the parameters one by one; the lowest
    curvatures measured along their own directions). Where a pass ends at a
    point that is not yet a minimum, the fit takes the best of 21
    trust-region steps of the Hessian (the way along a bending valley or
    off a saddle) and another pass. Between checks it carries the last
    check's Hessian along by secant updates (as NL2SOL does), and checks
    again where that Hessian sees a minimum or its steps go nowhere: 20
    passes and 10 checks at most. Like any local optimiser it ends in the local minimum its path
    leads to.
    Errors from the linearised covariance are linearised: where the check
    warns, ``jaxppo.sample`` gives the posterior.

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
        Most Levenberg-Marquardt steps per pass (default 200). A pass
        that used them all at a point the minimum check accepts is a
        minimum; otherwise the fit goes on (20 passes at most).
    rtol : float, optional
        A pass ends where a step near Gauss-Newton's gained, and the next
        one promises, less than atol + rtol chi^2 (default 1e-6), or where
        10 steps in a row gained less than that together.
    atol : float, optional
        See ``rtol`` (default 1e-6).
    progress : bool, optional
        Print one line per stage on stderr (default False).
    fold_inc : bool, optional
        The light curve depends on |cos i| only (the sign of cos i cannot be
        measured, docs/conventions.md), so a fitted inclination is reported
        folded into [0, 90] deg (the same chi^2 and errors; the correlations
        of inc change sign). False keeps the side of 90 deg the fit ended on.
        Default True. N-body planets and planets with moons are never
        folded: for them the sign of cos i changes the light curve (mutual
        inclinations; moons' orbits given on the sky), and i and 180 - i
        are two minima: a fit can stay in the one on its start's side of
        90 deg, so where that side is not known, fit from both and compare
        chi^2.

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
        u1/u2 with q1/q2), ``lightcurve`` is neither a jaxppo nor a
        lightkurve LightCurve, its flux's median is outside (0.5, 2) (not
        relative flux: ppt, electrons, deviations from 1), ``alpha`` is not
        one finite angle, ``max_steps`` is
        not a whole number >= 0, or ``rtol`` or ``atol`` is not finite and
        >= 0.

    Warns
    -----
    UserWarning
        When the linearised covariance is degenerate or ill-conditioned (not
        a failure): ``FitResult.condition`` > ``CONDITION_WARN``, or chi^2 at
        1 sigma along a principal axis of the covariance differs from
        chi^2_min + 1 by more than a factor 4 (e.g. a and inc of a grazing or
        single transit): the posterior is then far from Gaussian and
        ``jaxppo.sample`` gives the errors. Also, without a free
        "lc.jitter", when chi^2 / (N - k) is above 1.25 with a chi^2
        p-value below 1e-3, or below 0.2 as unlikely: the errors, which
        take flux_err as given, are then off by about its square root.

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

    check_settings(max_steps, rtol, atol)
    lightcurve = checked_lightcurve(lightcurve, "jaxppo.fit")
    model = Model(system, lightcurve, free, alpha, case, union_floor=128)
    system = off_circular(system, model.slots)  # a free (secosw, sesinw) never starts at e = 0
    theta = model.to_theta(system)
    n, k = lightcurve.time.size, len(model.free)
    problems = _start_problems(model, system, n, k)
    say(f"{n} points, {k} free parameters; compiling the model")
    if not problems:
        precompile(model, theta)
    # from the Jacobian's program, which the minimum check compiles anyway
    # (a separate residual program would cost a compilation of its own)
    chi2_start = float(np.sum(np.asarray(lm_pass(theta, model.data())[2]) ** 2))
    if not np.isfinite(chi2_start):
        problems.append(f"chi^2 at the start is {chi2_start} (flux_err as small as {np.min(lightcurve.flux_err):.3g} "
                        "makes the residuals overflow float64, or the model is not finite)")
    if problems:
        return _failed_start(model, system, theta, chi2_start, n, problems)
    say(f"chi^2 at the start {chi2_start:.6g}")
    model, theta, lm_problem, steps, verdict = _solve(model, theta, chi2_start, max_steps, rtol, atol, say)
    if fold_inc:
        theta, verdict["cov_theta"] = _fold_inc(model, theta, verdict["cov_theta"])
    problems = ([lm_problem] if lm_problem else []) + verdict["problems"]
    solved = model.to_system(theta)
    problems += [p.replace("at the start", "at the solution") for p in _transit_problems(model, solved)]
    ok = not problems
    message = ("converged: " + verdict["summary"]) if ok else "failed: " + "; ".join(problems)
    cov, derived, values = _physical_covariance(model, theta, verdict["cov_theta"])
    errors = _standard_errors(cov)
    if ok and not np.all(np.isfinite(errors)):
        ok = False
        bad = [nm for nm, e in zip(model.free, errors) if not np.isfinite(e)]
        message = (f"failed: the covariance gives no error for {bad} (a variance that is negative or not finite: "
                   "the curvature at the solution is not that of a minimum in every direction; jaxppo.sample gives "
                   "the errors)")
    _warn_if_degenerate(model.free, verdict)
    chi2_data = float(np.sum(verdict["residuals"][:n] ** 2)) if verdict["residuals"] is not None else np.nan
    if "lc.jitter" not in model.free:
        _warn_if_misfit(chi2_data, n - k)
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


# passes of Levenberg-Marquardt at most, and minimum checks (``assess``)
# among them
MAX_PASSES = 20
MAX_CHECKS = 10


def _solve(model: Model, theta, chi2, max_steps: int, rtol: float, atol: float, say):
    """Levenberg-Marquardt passes until the solution is a minimum of a model
    whose frame sets cover it. Returns (model, theta, why the last pass
    ended where that is a failure, or None; steps, the ``assess`` verdict).

    After a pass the fit decides with the check's Hessian whether the point
    is a minimum. The check (``assess``, second differences: a few hundred
    residual vectors) costs as much as 35-50 steps; between checks the fit
    carries its Hessian along as a model, H = 2 J^T J + S with J the
    Jacobian at the current point and S (the curvature that Gauss-Newton's
    2 J^T J misses) from the last check, updated by the secant condition
    over each pass (``secant_update``, as NL2SOL does). A pass ends with
    the check where that model sees a minimum (positive definite, Newton
    decrement below 0.01) or where its trust-region steps go nowhere; so
    only the check declares a minimum.
    From a point not yet a minimum the fit takes the best of the
    trust-region steps of the Hessian (``trust_region_steps``, chi^2 at all
    of them in one batch): along a bending valley or off a saddle they go
    where Levenberg-Marquardt's model, which has no negative curvature,
    crawls. The frames that take the union integral are fixed from the
    starting parameters (with a margin). If the solution brings disks
    together in other frames, those frames are added (a new Model with the
    same programs while the frame counts stay in their buckets) and the
    fit goes on with it: the check that ends the fit is on that model."""
    steps, status, verdict, checks = 0, 0, None, 0
    curv = None  # the Hessian model between checks: (scale, S, theta, scaled Jacobian, gradient) there
    for stage in range(MAX_PASSES):
        theta, jac, r, num_steps, status = lm_pass(theta, model.data(), max_steps, rtol, atol)
        steps, status = steps + int(num_steps), int(status)
        jac, r = np.asarray(jac), np.asarray(r)
        moved = chi2 - float(r @ r)
        say(f"Levenberg-Marquardt pass {stage + 1}: {steps} steps in all")
        wider = model.widened([model.to_system(theta)])
        if wider is not None:
            model = wider
            _, jac, r, _, _ = lm_pass(theta, model.data())
            jac, r = np.asarray(jac), np.asarray(r)
            say(f"the solution brings disks together or onto the star in new frames: the model has now "
                f"{model.union_idx.size} union and {model.active_idx.size} computed frames")
        chi2 = float(r @ r)
        step, source = None, "carried"
        if curv is not None and stage < MAX_PASSES - 1:
            curv = _carry(curv, np.asarray(theta), jac, r, learn=wider is None)
            hess, grad = _model_hessian(curv)
            if not newton_decrement(hess, grad) < DECREMENT:  # else the check decides
                # None: the carried Hessian's steps go nowhere, and the check measures it anew here
                step = _trust_region(model, np.asarray(theta), curv[0], hess, grad, chi2)
        if step is None:
            verdict = assess(model, theta, jac, r)
            checks += 1
            chi2 = verdict["chi2"]
            say(f"checked the minimum: chi^2 {chi2:.6g}" + ("" if verdict["optimum"] else "; not a minimum yet"))
            if verdict["optimum"] or verdict["hessian"] is None or checks == MAX_CHECKS or stage == MAX_PASSES - 1:
                break
            jz = jac / verdict["scale"]
            curv = (verdict["scale"], verdict["hessian"] - 2.0 * jz.T @ jz, np.asarray(theta), jz, verdict["grad"])
            step, source = _trust_region(model, np.asarray(theta), curv[0], verdict["hessian"], verdict["grad"],
                                         chi2), "check"
            if step is None and wider is None and moved < _PROGRESS:
                break  # neither Levenberg-Marquardt nor the Hessian's steps go lower
        if step is not None:
            theta, chi2 = step
            say(f"a trust-region step of the {source} Hessian: chi^2 {chi2:.6g}")
    failure = []
    if not verdict["optimum"]:
        if status != 0:
            failure.append("Levenberg-Marquardt stopped: " + LM_STATUS[status])
        if checks == MAX_CHECKS or stage == MAX_PASSES - 1:
            failure.append(f"the fit stopped after {stage + 1} passes and {checks} minimum checks (at most "
                           f"{MAX_PASSES} and {MAX_CHECKS})")
    return model, theta, "; ".join(failure) or None, steps, verdict


# a trust-region step is taken, and a pass counts as progress, when chi^2
# falls by more than this (a hundredth of the minimum check's tolerance)
_PROGRESS = 1e-4


def _carry(curv, theta, jac, r, learn: bool = True):
    """The Hessian model ``curv`` moved to ``theta`` (Jacobian ``jac``,
    residuals ``r`` there): S updated by the secant condition over the
    move (``secant_update``), unless not ``learn``: across a widening of
    the frames the gradients at the two ends are of different models, and
    their difference is not a curvature."""
    c, s_mat, theta_old, jz_old, grad_old = curv
    jz = jac / c
    grad = 2.0 * jz.T @ r
    if learn:
        s_mat = secant_update(s_mat, (theta - theta_old) * c, grad - grad_old, 2.0 * (jz - jz_old).T @ r)
    return c, s_mat, theta, jz, grad


def _model_hessian(curv):
    """(Hessian, gradient) of chi^2 in the scaled coordinates of the
    carried model: 2 J^T J + S."""
    c, s_mat, _, jz, grad = curv
    return 2.0 * jz.T @ jz + s_mat, grad


def _trust_region(model: Model, theta, c, hess, grad, chi2: float):
    """(theta, chi^2) at the best of the trust-region steps of ``hess``
    (``TRUST_RADII``; in the coordinates theta * c), or None when none
    lowers chi^2 by more than ``_PROGRESS``."""
    trial = theta + trust_region_steps(hess, grad) / c
    f = chi2_at(model, trial, 2 * c.size + 1)
    best = int(np.argmin(np.where(np.isfinite(f), f, np.inf)))
    if not f[best] < chi2 - _PROGRESS:
        return None
    return trial[best], float(f[best])


def _fold_inc(model: Model, theta, cov_theta):
    """(theta, cov_theta) with every inclination's coordinate (b = (1 + p)
    tanh theta) made >= 0: i -> 180 deg - i, the identical light curve;
    not where the sign of cos i changes it (``inc_sign_matters``: N-body
    orbits, moons)."""
    theta = np.asarray(theta)  # on the host: indexing a device array is a program per index
    flip = np.array([-1.0 if par == "inc" and theta[k] < 0 and not inc_sign_matters(model.system, owner)
                     else 1.0 for k, (owner, par) in enumerate(model.slots)])
    if cov_theta is not None:
        cov_theta = cov_theta * np.outer(flip, flip)
    return jnp.asarray(theta * flip), cov_theta


def _standard_errors(cov) -> np.ndarray:
    """1-sigma errors, the square roots of the covariance's diagonal; NaN
    where a variance is negative (an indefinite curvature, seen in float32
    fits of a nearly circular orbit with the eccentricity free: once
    clipped to 0, printed as +- 0, perfect knowledge) or not finite."""
    var = np.diag(np.asarray(cov, float))
    return np.where(var >= 0.0, np.sqrt(np.abs(var)), np.nan)


def _physical_covariance(model: Model, theta, cov_theta):
    """(covariance of the free parameters in physical units, derived: name
    -> (value, 1-sigma error), the free parameters' values) from the
    covariance in theta: cov_q = D cov_theta D^T with D = dq / dtheta; NaN
    without ``cov_theta``."""
    k = len(model.free)
    jac, q = (np.asarray(v) for v in model.physical_jacobian(jnp.asarray(theta)))
    cov = np.full((q.size, q.size), np.nan) if cov_theta is None else jac @ cov_theta @ jac.T
    errors = _standard_errors(cov)
    derived = {nm: (float(q[k + i]), float(errors[k + i])) for i, nm in enumerate(model.derived_names())}
    return cov[:k, :k], derived, q[:k]


def _warn_if_degenerate(free, verdict) -> None:
    """The UserWarning of ``fit`` when the linearised covariance is
    ill-conditioned or chi^2 at its 1 sigma is far from chi^2_min + 1."""
    condition, dchi2 = verdict["condition"], verdict["dchi2_1sigma"]
    # float64: in a float32 run the floor 1e-300 below was 0 (log: divide by zero)
    dchi2 = None if dchi2 is None else np.asarray(dchi2, float)
    why = []
    if condition > CONDITION_WARN:
        why.append(f"condition number {condition:.3g} of the scaled Fisher matrix, most degenerate combination "
                   f"{verdict['weakest']}")
    # Delta chi^2 at the linearised 1 sigma outside [1/4, 4]: the error along
    # that axis is off by more than a factor 2 (a milder mismatch is common:
    # chi^2(t0) of 1-min data has kinks where samples cross contact points)
    if dchi2 is not None and not np.all((dchi2 > 0.25) & (dchi2 < 4.0)):
        if not np.all(np.isfinite(dchi2)):
            why.append("chi^2 at 1 sigma along a principal axis of the covariance is not finite")
        else:
            worst = dchi2[np.argmax(np.abs(np.log(np.where(dchi2 > 0, dchi2, 1e-300))))]
            why.append(f"chi^2 rises by {worst:.3g} instead of 1 at 1 sigma along a principal axis of the covariance")
    if why:
        warnings.warn(
            f"jaxppo.fit: the linearised covariance of {list(free)} is degenerate or ill-conditioned ("
            + "; ".join(why) + "): the errors and correlations from the curvature are not reliable (e.g. a and inc "
            "of a grazing or single transit); jaxppo.sample gives the posterior", UserWarning, stacklevel=3)


def misfit_note(chi2: float, dof: int) -> "str | None":
    """What chi^2 / (N - k) says of flux_err, or None: it understates the
    scatter (above 1.25 with a chi^2 p-value below 1e-3, the rule of
    ``measure_transit_times`` and the scan) or overstates it many times
    (below 0.2, as unlikely: flux_err of other units); the errors of
    ``fit`` and the widths of ``sample``, which take flux_err as given, are
    then off by about its square root, whatever ``success`` says.

    Parameters
    ----------
    chi2 : float
        chi^2 of the data at the best fit (or the posterior mode).
    dof : int
        N - k: data points less free parameters.

    Returns
    -------
    str or None
        One sentence with the factor and the remedies, or None.
    """
    if not np.isfinite(chi2) or dof < 1:
        return None
    red = chi2 / dof
    if 0.2 <= red <= 1.25:
        return None  # no p-value needed (importing scipy.special took 0.1 s of a new process's fit)
    from scipy.special import chdtr, chdtrc

    if red > 1.25 and chdtrc(dof, chi2) < 1e-3:
        why = (f"the model does not fit the data within flux_err, and the errors, which take flux_err as given, are "
               f"too small by about a factor {np.sqrt(red):.3g}; free 'lc.jitter' (flux_err too small), 'lc.offset' "
               "or 'lc.baseline' (a flux level that is not 1 or a trend), or rescale flux_err")
    elif red < 0.2 and chdtr(dof, chi2) < 1e-3:
        why = (f"flux_err overstates the scatter about the model, and the errors, which take flux_err as given, are "
               f"too large by about a factor {1.0 / np.sqrt(red):.3g}; check flux_err's units (relative flux) or "
               "rescale it")
    else:
        return None
    return f"chi^2 / (N - k) = {red:.3g} with N - k = {dof}: {why}"


def _warn_if_misfit(chi2: float, dof: int) -> None:
    """The UserWarning of ``fit`` where ``misfit_note`` has something to say."""
    note = misfit_note(chi2, dof)
    if note is not None:
        warnings.warn(f"jaxppo.fit: {note}", UserWarning, stacklevel=3)


def _transit_problems(model: Model, system: System) -> list:
    """Planets with a free parameter that do not transit in any model frame.

    An N-body planet's ``PERTURBER_PARAMS`` (mass, lnode, period, t0) are
    exempt: they act on the transiting planets through gravity. With only
    such parameters (or the star's, or the light curve's) free, at least
    one planet must transit."""
    x, y, r = system.positions(np.asarray(model.t_model), model.alpha, model.case, xp=np)
    nbody = system.orbits == "nbody"
    owners = sorted({o for o, p in model.slots
                     if o not in ("star", "lc") and not (nbody and isinstance(p, str) and p in PERTURBER_PARAMS)})
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
