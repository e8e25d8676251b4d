"""jaxppo.core.geometry: the trigonometric polynomials and the circle
crossings the quadrature kernels rely on."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxppo.core.geometry import circle_intersection_angles, cos_sin, heron_product


def test_cos_sin_polynomials_on_their_range():
    x = np.linspace(-np.pi, np.pi, 100_001)
    c, s = cos_sin(jnp.asarray(x))
    assert np.max(np.abs(np.asarray(c) - np.cos(x))) < 1.3e-15
    assert np.max(np.abs(np.asarray(s) - np.sin(x))) < 1.3e-15
    c32, s32 = cos_sin(jnp.asarray(x, jnp.float32))
    assert c32.dtype == jnp.float32
    assert np.max(np.abs(np.asarray(c32, float) - np.cos(x))) < 1e-6
    assert np.max(np.abs(np.asarray(s32, float) - np.sin(x))) < 1e-6
    dc = jax.vmap(jax.grad(lambda v: cos_sin(v)[0]))(jnp.asarray(x))
    assert np.max(np.abs(np.asarray(dc) + np.sin(x))) < 1e-14


def test_heron_product_decides_crossing_symmetrically():
    rng = np.random.default_rng(0)
    p, q = rng.uniform(1e-4, 0.5, (2, 2000))
    # centres just inside / outside outer and inner tangency
    for delta in (p + q, np.abs(p - q)):
        for eps in (-1e-13, 1e-13):
            dd = delta * (1 + eps)
            a = np.asarray(heron_product(p, dd, q)) > 0
            b = np.asarray(heron_product(q, dd, p)) > 0
            assert np.array_equal(a, b)
            _, _, crosses, _ = circle_intersection_angles(0.0, 0.0, p, dd, 0.0, q)
            assert np.array_equal(np.asarray(crosses), a)


def test_safe_hypot_accuracy_and_gradients():
    """Within one ulp of np.hypot; finite gradient (x, y) / hypot where x^2
    underflows (it was NaN for |x| < 1e-154) or overflows, 0 at the origin."""
    from jaxppo.core.geometry import safe_hypot

    rng = np.random.default_rng(1)
    x, y = rng.normal(size=(2, 5000)) * 10.0 ** rng.uniform(-200, 200, (2, 5000))
    got = np.asarray(safe_hypot(x, y))
    want = np.hypot(x, y)
    assert np.all(np.abs(got - want) <= 2 * np.spacing(want))
    gx = jax.grad(safe_hypot)
    for v in (1e-300, 1e-170, 1e-100, 0.3, 1e200):
        assert float(gx(v, 0.0)) == 1.0
        assert abs(float(jax.grad(safe_hypot, 1)(v, v)) - 2**-0.5) < 1e-15
    assert float(gx(0.0, 0.0)) == 0.0
    assert float(jax.grad(safe_hypot)(jnp.float32(1e-30), jnp.float32(0.0))) == 1.0


def test_crossing_half_width_under_a_huge_disk():
    """The limb's arc inside a disk of radius R whose edge is 0.5 from the
    centre: cos h = (1 + (d - R)(d + R)) / (2 d), d = R + 0.5, in exact
    decimal arithmetic; the old cosine term (1 - R)(1 + R) + d^2 cancelled
    R^2 and lost 2e-8 at R = 1e8."""
    from decimal import Decimal, getcontext

    getcontext().prec = 60
    for R in (1e2, 1e4, 1e6, 1e8, 1e10):
        d = R + 0.5
        c = (1 + (Decimal(d) - Decimal(R)) * (Decimal(d) + Decimal(R))) / (2 * Decimal(d))
        want = np.arccos(float(c))
        _, half, crosses, _ = circle_intersection_angles(0.0, 0.0, 1.0, d, 0.0, R)
        assert bool(crosses)
        assert abs(float(half) - want) < 4e-16, (R, float(half) - want)
