"""The steps of ``jaxppo.fit``: Levenberg-Marquardt with Marquardt's
scaling as one compiled program, and trust-region steps from the minimum
check's Hessian.

Why not optimistix's ``LevenbergMarquardt`` here: it damps with the
identity, so in coordinates where chi^2 is much steeper along some axes
than others (t0 in days against a in R*) its steps crawl. On the
benchmark of ``benchmarks/fit_timing.py`` (Kepler-20 b + c, 10 free
parameters) it took 451 steps and two restarts in Jacobian-scaled
coordinates; with the damping scaled by the diagonal of J^T J (Marquardt
1963) and Nielsen's (1999) update of the damping, 34. The program also
returns the Jacobian and the residuals at its end, which the minimum check
needs: one compiled program serves the steps, the start's chi^2 and the
check (before, two: 3.2 s and 4.8 s to compile).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..model._programs import stored
from ._model import ModelData, residuals

__all__ = ["levenberg_marquardt", "lm_pass", "check_settings", "LM_STATUS", "trust_region_steps", "TRUST_RADII",
           "secant_update", "STALL_STEPS"]

# a pass ends when this many steps in a row (taken or refused) lowered chi^2
# by less than atol + rtol chi^2 together: Levenberg-Marquardt crawling
# along a bending valley near the minimum, damped and never quite meeting
# its own test, which on the Kepler-20 b + c benchmark spent a pass's 200
# steps on 0.0006 of chi^2 (the data rounded differently in the last
# digit: 91 steps); the minimum check and its Hessian's steps go on from there
STALL_STEPS = 10

# what ended a pass (the last output of levenberg_marquardt)
LM_STATUS = ("a step lowered chi^2 by less than atol + rtol chi^2", "it used all its max_steps steps",
             "no step lowers chi^2 (the damping grew past 1e16)",
             f"{STALL_STEPS} steps in a row lowered chi^2 by less than atol + rtol chi^2 in all")

# radii (in the coordinates scaled by the Jacobian's columns, where a step
# of 1 along an axis changes chi^2 by about 1) of the trust-region steps
# tried at once from a point the minimum check refuses
TRUST_RADII = np.geomspace(0.1, 30.0, 21)


def _jacobian(theta, d: ModelData):
    return jax.jacfwd(lambda th: (residuals(th, d),) * 2, has_aux=True)(theta)


@stored(filtered=True)
def levenberg_marquardt(theta, d: ModelData, max_steps, rtol, atol):
    """Levenberg-Marquardt from ``theta`` in one program: (theta at the
    end, the residuals' Jacobian there, the residuals there, the steps
    taken, what ended it: an index into ``LM_STATUS``).

    Each step solves (J^T J + lambda D) delta = -J^T r, D the largest
    diagonal of J^T J met in the pass (Moré 1978), and is
    taken when it lowers chi^2 = r^T r; lambda follows Nielsen's rule
    (times max(1/3, 1 - (2 rho - 1)^3) on a taken step, rho the actual over
    the predicted decrease; times 2, 4, 8, ... on a refused one). The pass
    ends at a step that the linear model predicts to lower chi^2 by at most
    atol + rtol chi^2 after a taken step with lambda <= 1 that lowered it by
    at most that much (the step is taken where it lowers chi^2), when
    ``STALL_STEPS`` steps in a row (taken or not) lowered chi^2 by at most
    atol + rtol chi^2 together, after ``max_steps`` steps (taken or not),
    or when lambda passes 1e16. ``max_steps``, ``rtol`` and ``atol`` are traced: one program for
    every value, and ``max_steps`` = 0 gives the Jacobian and residuals at
    ``theta``."""
    # the loop's first turn evaluates the start (a step of zero, always
    # taken, not counted): the Jacobian's code appears once in the program
    n_res = jax.eval_shape(lambda th: residuals(th, d), theta).shape[0]
    dtype = theta.dtype
    jac0 = jnp.zeros((n_res, theta.shape[0]), dtype)
    state = (theta, jac0, jnp.zeros(n_res, dtype), jnp.asarray(jnp.inf, dtype), jnp.asarray(1e-3, dtype),
             jnp.asarray(2.0, dtype), jnp.asarray(-1, jnp.int32), jnp.asarray(1, jnp.int32), jnp.asarray(False),
             jnp.zeros(theta.shape[0], dtype), jnp.asarray(jnp.inf, dtype), jnp.asarray(0, jnp.int32))

    def running(s):
        return (s[6] < max_steps) & (s[7] == 1)

    def step(s):
        th, jac, r, f, lam, nu, n, _, small, scale, ref, since = s
        first = n < 0
        jtj = jac.T @ jac
        g = jac.T @ r
        # Moré's scaling: the largest diagonal of J^T J met so far, so that
        # a column that vanishes on the way (the inclination's at b = 0,
        # where the flux depends on b^2) keeps its damping
        scale = jnp.maximum(scale, jnp.diag(jtj))
        diag = jnp.maximum(scale, 1e-12 * jnp.max(scale))
        solvable = jtj + lam * jnp.diag(jnp.where(first, 1.0, diag))
        delta = jnp.where(first, 0.0, -jnp.linalg.solve(solvable, g))
        jac_new, r_new = _jacobian(th + delta, d)
        f_new = jnp.sum(r_new**2)
        predicted = -(2.0 * g @ delta + delta @ jtj @ delta)
        taken = first | (jnp.isfinite(f_new) & jnp.all(jnp.isfinite(jac_new)) & (f_new < f))
        rho = (f - f_new) / jnp.maximum(predicted, jnp.finfo(dtype).tiny)
        # the pass ends when a step near Gauss-Newton's (lambda <= 1) gained
        # little and the next one promises little: after refused steps the
        # damped step is short and gains little far from the minimum (from
        # a radius of 1e-6 R*, chi^2 is flat in log p), and a step that
        # gained little can precede one that gains more
        tol = atol + rtol * f
        met = small & (predicted <= tol)
        small = taken & ~first & (f - f_new <= tol) & (lam <= 1.0)
        lam = jnp.where(first, lam, jnp.where(taken, lam * jnp.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3),
                                              lam * nu))
        nu = jnp.where(taken, 2.0, 2.0 * nu)
        # the stall window: chi^2 at its start (after the start's evaluation) and the steps in it
        f_after = jnp.where(taken, f_new, f)
        since = jnp.where(first, 0, since + 1)
        ref = jnp.where(first, f_after, ref)
        window = since >= STALL_STEPS
        stalled = window & (ref - f_after <= tol)
        ref, since = jnp.where(window, f_after, ref), jnp.where(window, 0, since)
        status = jnp.where(met, 0, jnp.where(stalled, 3, jnp.where(lam > 1e16, 2, 1))).astype(jnp.int32)
        pick = lambda new, old: jnp.where(taken, new, old)  # noqa: E731
        return (pick(th + delta, th), pick(jac_new, jac), pick(r_new, r), f_after, lam, nu, n + 1, status,
                small, scale, ref, since)

    th, jac, r, _, _, _, n, status, _, _, _, _ = jax.lax.while_loop(running, step, state)
    return th, jac, r, n, status  # status 1 ("running") at the end: it ran out of steps


def check_settings(max_steps, rtol, atol) -> None:
    """ValueError naming the parameter unless ``max_steps`` is a whole
    number >= 0 and ``rtol``, ``atol`` are finite and >= 0."""
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 0:
        raise ValueError(f"max_steps must be a whole number >= 0, got {max_steps!r}")
    for name, value in (("rtol", rtol), ("atol", atol)):
        if isinstance(value, bool) or not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {value!r}")


def lm_pass(theta, d: ModelData, max_steps: int = 0, rtol: float = 0.0, atol: float = 0.0):
    """``levenberg_marquardt`` with its numbers as traced arrays (one
    compiled program for every value): by default no step, which gives
    (theta, the Jacobian, the residuals, 0, 1) at ``theta``."""
    check_settings(max_steps, rtol, atol)
    return levenberg_marquardt(jnp.asarray(theta), d, jnp.asarray(int(max_steps), jnp.int32),
                               jnp.asarray(float(rtol)), jnp.asarray(float(atol)))


def trust_region_steps(hess, grad, radii=TRUST_RADII) -> np.ndarray:
    """The minimisers of the quadratic model grad^T s + s^T hess s / 2
    over |s| <= radius, one row per radius (Moré and Sorensen: s = -(hess +
    mu I)^-1 grad with mu >= max(0, -smallest eigenvalue) found by
    bisection so that |s| = radius, or the Newton step where hess is
    positive definite and that step is shorter). Along a direction of
    negative curvature the model falls without bound and the step goes to
    the radius: the way off a saddle or along a bending valley that
    Levenberg-Marquardt, whose model has no negative curvature, crawls."""
    w, v = np.linalg.eigh(0.5 * (hess + hess.T))
    gt = v.T @ grad
    gt = np.where(gt == 0.0, 1e-300, gt)  # the "hard case": a step along the eigenvector still leaves mu > -w0

    def size(mu):
        return np.linalg.norm(gt / (w + mu))

    out = []
    for radius in radii:
        if w[0] > 0 and size(0.0) <= radius:
            out.append(-v @ (gt / w))
            continue
        lo = max(0.0, -w[0])
        hi = lo + np.linalg.norm(grad) / radius + abs(w[-1]) + 1.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            lo, hi = (mid, hi) if size(mid) > radius else (lo, mid)
        out.append(-v @ (gt / (w + hi)))
    return np.array(out)


def secant_update(s_mat, step, dgrad, dgrad_sharp):
    """Dennis, Gay and Welsch's (1981; NL2SOL) update of S, the part of
    chi^2's Hessian that Gauss-Newton's 2 J^T J misses, over a move
    ``step``: the symmetric rank-two change of least weight for which
    2 J^T J + S maps the step to the change of the gradient ``dgrad``,
    given that S is to map it to ``dgrad_sharp`` = 2 (J_new - J_old)^T
    r_new. Unchanged where the step and ``dgrad`` are nearly orthogonal
    (y^T s <= 1e-12 |y| |s|: the update would divide by ~0)."""
    ys = float(dgrad @ step)
    if not ys > 1e-12 * np.linalg.norm(dgrad) * np.linalg.norm(step):
        return s_mat
    u = dgrad_sharp - s_mat @ step
    return s_mat + (np.outer(u, dgrad) + np.outer(dgrad, u)) / ys - float(u @ step) * np.outer(dgrad, dgrad) / ys**2
