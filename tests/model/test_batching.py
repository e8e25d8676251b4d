"""Which algorithm "auto" runs under vmap, chosen by JAX's public
jax.custom_batching (no private batching tracer): the union integral for
values (a batched plan would run every rule on every block), the device
plan's derivatives everywhere, each at the numbers of the unbatched call."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo.model._flux import device_auto
from jaxppo.model._plan import shared_branch


def _scene(n=300, seed=0):
    rng = np.random.default_rng(seed)
    x = np.stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)], 1)
    x[:, 1] = x[:, 0] + 0.05  # crossing pairs: lenses and the union integral
    y = rng.uniform(-0.3, 0.3, (n, 2))
    r = rng.uniform(0.02, 0.1, (n, 2))
    return tuple(v.reshape(30, 10, 2) for v in (x, y, r))


STAR = jp.kepler20_star()


def auto(a, b, c):
    return jp.occultation_flux(STAR, a, b, c)


def exact(a, b, c):
    return jp.occultation_flux(STAR, a, b, c, method="exact")


def total(a, b, c):
    return jnp.sum(auto(a, b, c))


@pytest.mark.parametrize("wrap", ["vmap", "jit(vmap)", "vmap(jit)"])
def test_batched_auto_is_the_union_integral(wrap):
    """Values under vmap, with jit on either side: the union integral, bit
    for bit as method="exact" (vmap(jit) was missed by the old tracer test)."""
    x, y, r = _scene()
    make = {"vmap": lambda f: jax.vmap(f), "jit(vmap)": lambda f: jax.jit(jax.vmap(f)),
            "vmap(jit)": lambda f: jax.vmap(jax.jit(f))}[wrap]
    ref = np.asarray(make(exact)(x, y, r))
    assert np.array_equal(np.asarray(make(auto)(x, y, r)), ref)
    # and within the plan's error of the unbatched call
    plain = np.asarray(jax.jit(auto)(x, y, r))
    assert 0 < np.max(np.abs(plain - ref)) < 5e-12


def test_the_choice_is_visible_in_the_jaxpr():
    """Unbatched, "auto" is the device plan (its lax.switch per block);
    batched, no switch is left: the union integral alone."""
    x, y, r = _scene()
    one = str(jax.make_jaxpr(auto)(x[0], y[0], r[0]))
    many = str(jax.make_jaxpr(jax.vmap(auto))(x, y, r))
    assert "cond[" in one and "custom_vmap" in one
    assert "cond[" not in many and "custom_vmap" not in many


def test_derivatives_under_vmap_equal_the_unbatched_ones():
    """grad, jacfwd and vmap in any order: the device plan's derivatives at
    the unbatched numbers (grad(vmap) once failed on JAX's transpose of a
    batched switch, jax-ml/jax#39219; shared_branch keeps it a switch)."""
    x, y, r = _scene()
    ref = np.asarray(jax.jit(jax.grad(total))(x, y, r))
    got = {
        "vmap(grad)": jax.jit(jax.vmap(jax.grad(total)))(x, y, r),
        "vmap(jacfwd)": jax.jit(jax.vmap(jax.jacfwd(total)))(x, y, r),
        # (under jit only: the eager grad(vmap) runs the same transpose rule, op by op, in a minute of CI)
        "jit(grad(vmap))": jax.jit(jax.grad(lambda a: jnp.sum(jax.vmap(auto)(a, y, r))))(x),
    }
    for name, g in got.items():
        np.testing.assert_allclose(np.asarray(g), ref, rtol=0, atol=1e-15, err_msg=name)
    # a batched star (limb darkening vmapped): union values, plan derivatives
    u = jnp.array([[0.4, 0.2], [0.3, 0.3]])
    xs, ys, rs = (v[0] for v in (x, y, r))
    flux = lambda uu, m: jp.occultation_flux(jp.Star.quadratic(uu[0], uu[1]), xs, ys, rs, method=m)
    assert np.array_equal(np.asarray(jax.jit(jax.vmap(lambda uu: flux(uu, "auto")))(u)),
                          np.asarray(jax.jit(jax.vmap(lambda uu: flux(uu, "exact")))(u)))
    grad_u = jax.grad(lambda uu: jnp.sum(flux(uu, "auto")))
    gu = jax.jit(jax.vmap(grad_u))(u)
    one = jax.jit(grad_u)
    for i in range(2):
        np.testing.assert_allclose(np.asarray(gu[i]), np.asarray(one(u[i])), rtol=1e-13, atol=1e-15)


def test_shared_branch():
    """Unbatched: the identity; batched: each block's highest rule, unbatched."""
    b = jnp.array([[0, 2, 1], [1, 0, 3]], jnp.int32)
    assert np.array_equal(np.asarray(shared_branch(b[0])), [0, 2, 1])
    out = jax.vmap(shared_branch)(b)  # the unbatched result broadcasts back
    assert np.array_equal(np.asarray(out), [[1, 2, 3], [1, 2, 3]])


def test_device_auto_is_cached_per_order():
    assert device_auto(24) is device_auto(24) and device_auto(24) is not device_auto(20)
