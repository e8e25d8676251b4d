"""Is a point a minimum of chi^2? The check that ends every pass of
``jaxppo.fit``: the Hessian of chi^2 by second differences (in a basis
that measures the nearly degenerate combinations of the free parameters
directly), the Newton decrement, the conditioning of the Fisher matrix and
the linearised covariance.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model._programs import threads
from ._lm import lm_pass
from ._model import Model, physical_jacobian, residuals_batch

__all__ = ["assess", "chi2_at", "WEAK", "newton_decrement", "DECREMENT", "precompile"]

# A combination of the free parameters whose Gauss-Newton curvature
# (eigenvalue of J^T J with J's columns scaled to unit norm) is below WEAK is
# 10 times (or more) less determined than the parameters one by one. The
# Hessian's second differences take such combinations as directions of their
# own: assembled from differences along the parameters' axes, its curvature
# along them is the small difference of large numbers, and on the Kepler-20
# b + c benchmark it read a minimum (curvature +0.0013 along c's a-inc
# combination, measured along it) as a saddle (-0.09).
WEAK = 0.01


def precompile(model: Model, theta) -> None:
    """Start compiling the programs of ``assess`` (the residuals at 2 k + 1
    points, k free parameters) and of the fit's covariance (the physical
    parameters' Jacobian) in a thread, while the caller traces the
    Levenberg-Marquardt program (``_programs.stored.precompile``: where
    the program store is on; 0.3-0.4 s less of a new process's first fit
    of Kepler-20 b + c: XLA's compiler already keeps both cores of a
    2-core CPU busy, so it overlaps with the tracing only)."""
    theta = jnp.asarray(theta)
    k = theta.shape[0]
    residuals_batch.precompile(jnp.zeros((2 * k + 1, k), theta.dtype), model.data(), jnp.asarray(0, jnp.int32))
    physical_jacobian.precompile(theta, model.data())


def assess(model: Model, theta, jac=None, r=None) -> dict:
    """Is theta a minimum of chi^2? From the residuals' Jacobian J (and
    residuals r: ``jac``, ``r``, computed here when not given) and the full
    Hessian H of chi^2, both with theta scaled by J's column norms (so the
    verdict does not depend on units): H positive definite and the Newton
    decrement g^T H^-1 g / 2 (the chi^2 a Newton step would gain) below
    0.01. Also the covariance (J^T J)^-1 in theta; "hessian" and "grad"
    (scaled) for the fit's trust-region steps."""
    if jac is None:
        _, jac, r, _, _ = lm_pass(theta, model.data())
    jac, r = np.asarray(jac), np.asarray(r)
    chi2 = float(np.sum(r**2))
    out = {"chi2": chi2, "problems": [], "optimum": False, "scale": None, "cov_theta": None, "summary": "",
           "condition": np.nan, "weakest": "", "dchi2_1sigma": None, "residuals": r, "hessian": None, "grad": None}
    if not np.isfinite(chi2):
        out["problems"].append(f"chi^2 at the solution is {chi2}")
        return out
    c = np.sqrt(np.sum(jac**2, axis=0))
    flat = [n for n, ci in zip(model.free, c) if not ci > 0]
    if flat or not np.all(np.isfinite(jac)):
        out["problems"].append(f"the data do not constrain {flat} (zero or non-finite derivative at the solution)")
        out["condition"], out["weakest"] = np.inf, f"{flat} alone"
        return out
    jtj = (jac / c).T @ (jac / c)  # unit diagonal
    jitter = any(par == "jitter" for _, par in model.slots)
    try:
        cov_gn = np.linalg.inv(jtj) / np.outer(c, c)
    except np.linalg.LinAlgError:
        cov_gn = None
    # the Hessian, gradient and trust-region steps in theta * c, c the
    # column norms where they give the scale of chi^2's curvature
    c, axis_res = _step_scales(model, np.asarray(theta), c)
    out["scale"] = c
    grad = 2.0 * (jac.T @ r) / c
    # chi^2 at +-1 sigma along the principal axes of the linearised
    # covariance (see _axis_steps), in the same batches as the Hessian's
    axes = None if jitter else _axis_steps(cov_gn)
    hess, f_axes = _hessian(model, np.asarray(theta), c, axis_res, (jac / c).T @ (jac / c),
                            [] if axes is None else list(axes * c))
    if not np.all(np.isfinite(hess)):
        out["problems"].append("the Hessian of chi^2 at the solution is not finite")
        return out
    hess = _measure_lowest(model, np.asarray(theta), c, hess, chi2)
    out["hessian"], out["grad"] = hess, grad
    _judge_minimum(out, hess, grad)
    _conditioning(out, jtj, model.free)
    if not jitter:
        out["cov_theta"] = cov_gn
        if axes is not None:
            out["dchi2_1sigma"] = f_axes - chi2
        return out
    return _laplace_with_jitter(out, model, theta, hess, c, 2 * c.size + 1)


def _step_scales(model: Model, theta, c) -> tuple:
    """(scales, residual vectors at the centre and +-h along each axis at
    those scales: the rows of ``_hessian_points`` without pairs). The
    scales are the Jacobian's column norms ``c``, made larger where chi^2
    curves far more along an axis than the Gauss-Newton part says (2 in
    the scaled coordinates): where a column nearly vanishes (the
    inclination at an impact parameter b ~ 0, where the flux depends on
    b^2) a step of ``_HESSIAN_STEP`` in theta * c swings b from 0 to
    grazing, and the second differences read curvatures 1e4 times too
    large. Such an axis is rescaled by sqrt(curvature / 2) until its
    curvature is within a factor 4 of 2 (three times at most)."""
    c = np.array(c, float)
    h = _HESSIAN_STEP
    axes = _hessian_points(np.eye(c.size), [])[0]
    for attempt in range(4):
        res = _residual_rows(model, theta + axes / c, len(axes))
        f = np.sum(res**2, axis=1)
        curv = (f[1::2] + f[2::2] - 2.0 * f[0]) / h**2
        steep = np.isfinite(curv) & (curv > 8.0) | ~np.isfinite(curv)
        if not np.any(steep) or attempt == 3:
            return c, res
        c = np.where(steep, c * np.sqrt(np.where(np.isfinite(curv), curv, 1e8) / 2.0), c)


def _hessian(model: Model, theta, c, axis_res, jtj, extra) -> tuple:
    """(Hessian of chi^2 in the scaled coordinates z = theta * c, chi^2 at
    the scaled steps ``extra``). Second differences in a basis B whose
    columns are the parameters' axes, except that the combinations weaker
    than WEAK replace the axes they lean on most (``_weak_basis``): H_B =
    B^T H B, H = B^-T H_B B^-1. ``axis_res``: the residual vectors at the
    centre and +-h along each axis (``_step_scales``), which say which
    parameters share data points (the others have no cross term)."""
    k = c.size
    rows = 2 * k + 1
    share = _sharing(axis_res)
    basis, replaced = _weak_basis(jtj)
    if replaced:
        moves = (np.abs(basis) > 0).T.astype(np.int32)  # [k, k]: the parameters each direction moves
        share = (moves @ share.astype(np.int32) @ moves.T) > 0
    pairs = [(i, j) for i in range(k) for j in range(i + 1, k) if share[i, j]]
    pts = np.array(_hessian_points(basis, pairs)[1] + list(extra)).reshape(-1, k)
    if replaced:  # the centre and the new axes in the same batches as the pairs
        pts = np.concatenate([_hessian_points(basis, [])[0], pts])
        f = np.sum(_residual_rows(model, theta + pts / c, rows) ** 2, axis=1)
    else:
        f = np.concatenate([np.sum(axis_res**2, axis=1), chi2_at(model, theta + pts / c, rows)])
    hess_b = _second_differences(f, pairs, k)
    inv = np.linalg.inv(basis)
    hess = inv.T @ hess_b @ inv
    return 0.5 * (hess + hess.T), f[rows + 4 * len(pairs):]


def _measure_lowest(model: Model, theta, c, hess, chi2: float):
    """``hess`` with its curvature along each eigenvector whose eigenvalue
    is below ``_MEASURED_BELOW`` measured along that eigenvector (second
    differences over the Hessian's step, all in one batch): H + sum_j
    (measured_j - w_j) v_j v_j^T, the same eigenvectors with the measured
    curvatures. Assembled from differences in another basis, the curvature
    along a direction no difference was taken along carries their errors
    (the light curve's second derivative jumps at contact points): on
    Kepler-20 b + c (seed 19 of the benchmark) the Hessian read -0.99 along
    a direction along which chi^2 curves by +0.08, and the fit failed at a
    minimum as "not positive definite". The verdict rests on the lowest
    eigenvalues, so those are the ones measured."""
    h = _HESSIAN_STEP
    w, v = np.linalg.eigh(0.5 * (hess + hess.T))
    low = np.flatnonzero(w < _MEASURED_BELOW)
    if low.size == 0:
        return hess
    pts = np.array([s * h * v[:, j] for j in low for s in (1.0, -1.0)])
    f = chi2_at(model, theta + pts / c, 2 * c.size + 1)
    measured = (f[0::2] + f[1::2] - 2.0 * chi2) / h**2
    ok = np.isfinite(measured)
    vs = v[:, low[ok]]
    return hess + (vs * (measured[ok] - w[low[ok]])) @ vs.T


# the Hessian's curvatures are measured along their eigenvectors
# (``_measure_lowest``) where they are below this (scaled coordinates, where a
# well-determined parameter curves chi^2 by about 2)
_MEASURED_BELOW = 0.5


def _weak_basis(jtj) -> tuple:
    """(B, replaced): the identity with each combination of the free
    parameters weaker than WEAK (an eigenvector of ``jtj`` with
    eigenvalue < WEAK; its diagonal is 1 but on the axes ``_step_scales``
    rescaled, which are weak by their own small diagonal and so measured
    along themselves) in place of one axis; the axes are
    chosen by elimination with pivoting on the largest component (B stays
    well conditioned). ``replaced`` lists the axes replaced."""
    w, v = np.linalg.eigh(jtj)
    weak = v[:, w < WEAK]
    basis = np.eye(jtj.shape[0])
    m = weak.T.copy()
    replaced = []
    for a in range(m.shape[0]):
        row = np.abs(m[a])
        row[replaced] = -1.0
        j = int(np.argmax(row))
        replaced.append(j)
        m[a + 1:] -= np.outer(m[a + 1:, j] / m[a, j], m[a])
        basis[:, j] = weak[:, a]
    return basis, replaced


def _residual_rows(model: Model, thetas, rows: int) -> np.ndarray:
    """The residual vectors at each row of ``thetas``: the residuals program
    of ``rows`` rows, in as many batches as it takes, and at least one per
    thread (``threads()``), the points shared evenly among them; the
    batches run several at a time (``map_to_host``), each padded to
    ``rows`` rows, the program stopping at its last real row."""
    n = len(thetas)
    if n == 0:
        return np.zeros((0, 0))
    size = -(-n // max(-(-n // rows), min(threads(), n)))
    calls, sizes = [], []
    for lo in range(0, n, size):
        batch = thetas[lo:lo + size]
        sizes.append(len(batch))
        batch = np.concatenate([batch, np.repeat(batch[:1], rows - len(batch), axis=0)])
        calls.append((jnp.asarray(batch), model.data(), jnp.asarray(sizes[-1], jnp.int32)))
    return np.concatenate([out[:m] for out, m in zip(residuals_batch.map_to_host(calls), sizes)])


def chi2_at(model: Model, thetas, rows: int) -> np.ndarray:
    """chi^2 at each row of ``thetas``: the residuals program of the
    Hessian's axis points (``rows`` rows) run batch by batch, summed here.
    One program for every point of ``assess`` and the fit's trust-region
    steps: a chi^2 program of its own cost a second compilation (1.3 s on
    the Kepler-20 b + c benchmark), and each batch size another."""
    if len(thetas) == 0:
        return np.zeros(0)
    return np.sum(_residual_rows(model, np.asarray(thetas), rows) ** 2, axis=1)


# Hessian of chi^2 in the scaled coordinates by second differences of chi^2
# itself (2 k^2 forward evaluations in one program; a traced jax.hessian
# costs ~8 s of compilation here). The step is a fraction of the scale on
# which chi^2 changes by 1: the light curve's second derivative jumps at
# contact points, and differences of the gradient over tiny steps read a
# 10-parameter Kepler-20 minimum as a saddle.
_HESSIAN_STEP = 0.3


def _hessian_points(basis, pairs) -> tuple:
    """Points in the scaled coordinates: (the centre and +-h along each
    column of ``basis`` [2k + 1, k], the points (+-h, +-h) in each of the
    ``pairs`` (i, j), i < j, of columns: a list of 4 per pair)."""
    h = _HESSIAN_STEP
    cols = basis.T * h
    axes = np.array([np.zeros(len(cols))] + [s * cols[i] for i in range(len(cols)) for s in (1.0, -1.0)])
    return axes, [si * cols[i] + sj * cols[j] for i, j in pairs for si in (1.0, -1.0) for sj in (1.0, -1.0)]


def _sharing(res) -> np.ndarray:
    """[k, k] bool: which parameters move a common residual (``res``: the
    residuals at the centre and at +-h along each axis). Parameters that
    move disjoint sets of points (the transit times of different transits,
    the baselines of different windows) add separately to chi^2: their
    cross derivative is zero, and skipping those pairs turns the 2 k^2 chi^2
    evaluations of a fit of many transit times into a few per transit."""
    moved = np.abs(res[1:] - res[0]) > 0
    moved = moved[0::2] | moved[1::2]  # [k, n]: the points parameter i moves
    return (moved.astype(np.int32) @ moved.T.astype(np.int32)) > 0


def _second_differences(f, pairs, k: int) -> np.ndarray:
    """The Hessian in the basis of ``_hessian_points`` from chi^2 ``f`` at
    its points, the centre and axes first, then the pairs (zero for the
    pairs not listed)."""
    h = _HESSIAN_STEP
    hess = np.zeros((k, k))
    for i in range(k):
        hess[i, i] = (f[1 + 2 * i] - 2 * f[0] + f[2 + 2 * i]) / h**2
    base = 1 + 2 * k
    for n, (i, j) in enumerate(pairs):
        fpp, fpm, fmp, fmm = f[base + 4 * n: base + 4 * n + 4]
        hess[i, j] = hess[j, i] = (fpp - fpm - fmp + fmm) / (4 * h**2)
    return hess


def newton_decrement(hess, grad) -> float:
    """The chi^2 a Newton step would gain, g^T H^-1 g / 2 (scaled
    coordinates), or inf where ``hess`` is not positive definite (its
    lowest eigenvalue at most 2e-9 of the largest, or of 1): the number
    the minimum check judges against ``DECREMENT``, and the fit's carried
    Hessian too."""
    w = np.linalg.eigvalsh(0.5 * (hess + hess.T))
    # scaled so that the Gauss-Newton part has unit diagonal: eigenvalues
    # near 2 for well-determined parameters; 1e-9 of that is degenerate
    if not w[0] > 2e-9 * max(w[-1], 1.0):
        return np.inf
    return 0.5 * float(grad @ np.linalg.solve(hess, grad))


# a point is a minimum where the Newton decrement is at most this
DECREMENT = 0.01


def _judge_minimum(out: dict, hess, grad) -> None:
    """Positive definite Hessian and a Newton decrement below ``DECREMENT``:
    sets ``out["optimum"]``, ``"summary"`` or adds to ``"problems"``."""
    decrement = newton_decrement(hess, grad)
    if not np.isfinite(decrement):
        w = np.linalg.eigvalsh(0.5 * (hess + hess.T))
        out["problems"].append(f"not a minimum: the Hessian of chi^2 is not positive definite (scaled eigenvalues "
                               f"{w[0]:.3g} .. {w[-1]:.3g}, gradient norm {np.linalg.norm(grad):.3g}); the free parameters are "
                               "degenerate, or the fit stopped on a slope or a saddle")
        return
    out["summary"] = f"Newton step would lower chi^2 by {decrement:.2g}"
    if decrement > DECREMENT:
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
    (``chi2_at`` in batches of ``n_batch``)."""
    try:
        out["cov_theta"] = 2.0 * np.linalg.inv(0.5 * (hess + hess.T)) / np.outer(c, c)
    except np.linalg.LinAlgError:
        return out
    axes = _axis_steps(out["cov_theta"])
    if axes is not None:
        out["dchi2_1sigma"] = chi2_at(model, np.asarray(theta) + axes, n_batch) - out["chi2"]
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
