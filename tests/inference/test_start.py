"""The chains' start (jaxppo.inference._start): BFGS's mode and the Newton
decrement that accepts it, computed from BFGS's own gradient."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxppo.inference import _start

A = jnp.array([[3.0, 1.0], [1.0, 2.0]])


def _potential(u):
    return 0.5 * (u - 1.0) @ A @ (u - 1.0) + 0.1 * jnp.sum((u - 1.0) ** 4)


def test_mode_and_the_gradient_that_accepts_it(monkeypatch):
    """A non-quadratic potential with its mode at (1, 1): find_mode reaches
    it, and the gradient it judges the mode by (from BFGS's state, in the
    whitened coordinates, mapped back) is the gradient of the potential at
    the solution, to rounding."""
    seen = {}
    original = _start._gradient_u

    def spy(sol, chol0):
        seen["g"] = original(sol, chol0)
        return seen["g"]

    monkeypatch.setattr(_start, "_gradient_u", spy)
    pot = jax.jit(_potential)
    jac = jax.jit(jax.jacfwd(lambda u: jnp.linalg.cholesky(A).T @ (u - 1.0)))
    u, chol, ok, why = _start.find_mode(pot, jac, np.array([3.0, -2.0]), np.array([10.0, 10.0]))
    assert ok, why
    assert np.allclose(u, 1.0, atol=1e-6)
    assert seen["g"] is not None
    ref = np.asarray(jax.grad(_potential)(jnp.asarray(u)))
    assert np.allclose(seen["g"], ref, rtol=1e-6, atol=1e-12), (seen["g"], ref)
    # the Laplace factor at the mode: L L^T is the inverse curvature of the quadratic part
    assert np.allclose(chol @ chol.T, np.linalg.inv(np.asarray(A) + np.diag([0.01, 0.01])), rtol=1e-6)
