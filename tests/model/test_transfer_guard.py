"""No host round trip inside the compiled paths (what runs on a GPU in the
hot loops): with inputs already on the device, jax.transfer_guard
("disallow") lets the jitted flux, its gradient, a jitted System.flux and
the fit / NUTS model's residuals and Jacobian and the fit's whole
Levenberg-Marquardt pass run. The eager "auto" path
plans on the host (which frames need which rule, docs/methods.md), so it
moves data by design, and the guard sees that too."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo.inference._lm import levenberg_marquardt
from jaxppo.inference._model import Model


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(0)
    return tuple(jnp.asarray(v) for v in (rng.uniform(-1, 1, (500, 2)), rng.uniform(-0.5, 0.5, (500, 2)),
                                          rng.uniform(0.01, 0.1, (500, 2))))


def test_jitted_flux_and_gradient_stay_on_the_device(scene):
    star = jp.kepler20_star()
    f = jax.jit(lambda a, b, c: jp.occultation_flux(star, a, b, c))
    g = jax.jit(jax.grad(lambda a, b, c: jp.occultation_flux(star, a, b, c).sum(), argnums=(0, 1, 2)))
    ref = f(*scene).block_until_ready()
    g(*scene)[0].block_until_ready()
    with jax.transfer_guard("disallow"):
        out = f(*scene)
        grads = g(*scene)
        out.block_until_ready()
    assert np.array_equal(np.asarray(out), np.asarray(ref))
    assert all(np.all(np.isfinite(np.asarray(v))) for v in grads)
    # the eager "auto" plan runs on the host: the guard catches its transfers
    with pytest.raises(Exception, match="Disallowed"):
        with jax.transfer_guard("disallow"):
            jp.occultation_flux(star, *scene).block_until_ready()


def test_jitted_system_flux_and_model_residuals_stay_on_the_device():
    system = jp.kepler20_system()
    b = system.planets[0]
    t = jnp.linspace(float(b.t0) - 0.1, float(b.t0) + 0.1, 300)
    alpha = jnp.asarray(30.0)
    flux = jax.jit(lambda tt, a: system.flux(tt, a, case="same"))
    flux(t, alpha).block_until_ready()
    lc = jp.simulate_kepler20(seed=1)
    near = np.abs(((lc.time - float(b.t0)) / float(b.period) + 0.5) % 1 - 0.5) * float(b.period) < 0.3
    model = Model(system, lc.select(near & (np.cumsum(near) <= 300)), ("b.t0", "b.radius", "c.t0"))
    theta = model.to_theta(system)
    res, jac = jax.jit(model.residuals), jax.jit(jax.jacfwd(model.residuals))
    res(theta).block_until_ready()
    jac(theta).block_until_ready()
    start = jnp.asarray(theta) + jnp.asarray([1e-3, 0.0, 0.0])
    numbers = (jnp.asarray(50, jnp.int32), jnp.asarray(1e-6), jnp.asarray(1e-6))
    data = model.data()
    jax.block_until_ready(levenberg_marquardt(start, data, *numbers))
    with jax.transfer_guard("disallow"):
        f = flux(t, alpha)
        r = res(theta)
        J = jac(theta)
        J.block_until_ready()
        lm = levenberg_marquardt(start, data, *numbers)
        jax.block_until_ready(lm)
    assert np.all(np.isfinite(np.asarray(f))) and np.all(np.isfinite(np.asarray(r)))
    assert np.asarray(J).shape == (np.asarray(r).size, 3)
    assert int(lm[3]) > 0 and np.sum(np.asarray(lm[2]) ** 2) < np.sum(np.asarray(res(start)) ** 2)
