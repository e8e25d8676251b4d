"""Where ``sample``'s chains start and the metric they start with: the mode
of the posterior in NUTS's coordinates u (optimistix BFGS from the user's
start) and the Cholesky factor of the Laplace covariance there.

The mode is that of the posterior, not of the likelihood (``jp.fit``): with
one transit and a free period the likelihood is flat along P ~ a^(3/2)
(only the chord speed a / P is measured) and its maximum runs outside the
priors (P 20 % off where the prior allows 0.1 %); the posterior in u,
which holds the priors and the Jacobian of their maps, has a mode inside.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["laplace_factor", "find_mode", "NEWTON_TOL"]

NEWTON_TOL = 0.01
"""The mode is accepted when a Newton step with the Laplace curvature would
raise the log-posterior by less than this (the criterion of ``jp.fit``)."""


def laplace_factor(jacobian_u, u, prior_sd) -> np.ndarray:
    """L with L L^T the Laplace covariance at u (NUTS moves w, u = u0 + L w):
    the inverse of the Fisher information of the data (``jacobian_u``: u ->
    the Jacobian of the residuals whose sum of squares is -2 ln L + const,
    compiled once by the caller) plus the prior's
    widths ``prior_sd`` as Gaussian curvature (so that a parameter the data
    do not constrain, like P from one transit, keeps its prior's width),
    each marginal width capped at the prior's. At the mode this is the
    posterior's covariance to second order, so warm-up starts with the
    right metric instead of learning it from a slope."""
    jac = np.asarray(jacobian_u(jnp.asarray(u)))
    jac = np.where(np.isfinite(jac), jac, 0.0)
    info = jac.T @ jac + np.diag(1.0 / prior_sd**2)
    c = np.sqrt(np.diag(info))
    # scaled to unit diagonal: the widths span orders of magnitude (t0 to 1e-4 d)
    w, v = np.linalg.eigh(info / np.outer(c, c))
    cov = (v / np.maximum(w, 1e-12)) @ v.T / np.outer(c, c)
    sd = np.sqrt(np.diag(cov))
    cap = np.minimum(1.0, prior_sd / sd)  # no width beyond the prior's
    cov = cov * np.outer(cap, cap)
    try:
        return np.linalg.cholesky(0.5 * (cov + cov.T))
    except np.linalg.LinAlgError:  # rounding on a near-singular matrix: the marginal widths alone
        return np.diag(np.sqrt(np.clip(np.diag(cov), 1e-300, None)))


def find_mode(potential_u, jacobian_u, u0, prior_sd, max_steps: int = 256):
    """(u at the mode, its Laplace factor, converged, message): BFGS
    (optimistix) on the negative log-posterior ``potential_u`` in the
    coordinates whitened at ``u0``, then the Laplace factor at the end; the
    mode is accepted when the potential is finite there, BFGS stopped on
    its own criteria and the Newton decrement g^T L L^T g / 2 with that
    factor is below ``NEWTON_TOL``. Where it is not, the chains start at
    the better of ``u0`` and BFGS's last point."""
    import optimistix as optx

    u0 = np.asarray(u0, float)
    chol0 = laplace_factor(jacobian_u, u0, prior_sd)
    u0j, l0 = jnp.asarray(u0), jnp.asarray(chol0)
    f0 = float(potential_u(u0j))

    def objective(w, args):
        # shifted by the start's value: BFGS's relative tolerance then acts on
        # the change of ln p, not on the normalisation of the likelihood
        return potential_u(u0j + l0 @ w) - f0

    sol = optx.minimise(objective, optx.BFGS(rtol=1e-8, atol=1e-8), jnp.zeros_like(u0j), max_steps=max_steps,
                        throw=False)
    u = u0 + chol0 @ np.asarray(sol.value)
    f = float(potential_u(jnp.asarray(u)))
    if not (np.isfinite(f) and f <= f0):
        return u0, chol0, False, f"BFGS ended at a worse point (-ln p {f:.6g}, start {f0:.6g}); started at the given system"
    chol = laplace_factor(jacobian_u, u, prior_sd)
    g = _gradient_u(sol, chol0)
    if g is None:
        g = np.asarray(jax.jit(jax.grad(potential_u))(jnp.asarray(u)))
    decrement = 0.5 * float(np.sum((chol.T @ g) ** 2))
    stopped = bool(sol.result == optx.RESULTS.successful)
    ok = stopped and np.isfinite(decrement) and decrement < NEWTON_TOL
    why = (f"posterior mode (BFGS, {int(sol.stats.get('num_steps', -1))} steps): -ln p lowered by {f0 - f:.4g}, "
           f"a Newton step would lower it by {decrement:.2g}")
    if not stopped:
        why += f"; BFGS did not stop on its criteria ({sol.result})"
    return u, chol, ok, why


def _gradient_u(sol, chol0) -> np.ndarray | None:
    """The gradient of the potential in u at BFGS's solution, from BFGS's
    own state (its gradient in the whitened w, u = u0 + L0 w, so g_w =
    L0^T g_u): no second compilation of the gradient. None when the state
    does not hold it."""
    grad = getattr(getattr(getattr(sol, "state", None), "f_info", None), "grad", None)
    if grad is None:
        return None
    g_w = np.asarray(grad, float)
    if g_w.shape != (chol0.shape[0],) or not np.all(np.isfinite(g_w)):
        return None
    return np.linalg.solve(chol0.T, g_w)
