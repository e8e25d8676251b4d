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
