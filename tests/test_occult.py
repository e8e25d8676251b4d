"""The exact engine against independent references (tests/helpers.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from helpers import (
    KEPLER20_P100,
    adversarial_pairs,
    adversarial_single,
    random_configs,
    reference_deficit,
    reference_total,
    union_area,
)

STARS = {
    "uniform": jp.Star.uniform(),
    "quadratic": jp.Star.quadratic(0.495, 0.154),
    "nonlinear": jp.Star.nonlinear(*KEPLER20_P100),
    "power2": jp.Star.power2(0.71780284, 0.77644690),
}
TOL64 = 1e-10


def _intensity_r(star):
    def f(r):
        mu = np.sqrt(max(1.0 - r * r, 0.0))
        return float(star.intensity(mu))

    return f


def _check(star, cfgs, tol=TOL64):
    ir = _intensity_r(star)
    f0 = reference_total(ir)
    np.testing.assert_allclose(float(star.total_flux), f0, rtol=1e-12)
    worst = 0.0
    for x, y, p in cfgs:
        ref = 1.0 - reference_deficit(ir, x, y, p) / f0
        got = float(jp.occultation_flux(star, np.array(x), np.array(y), np.array(p), method="exact"))
        worst = max(worst, abs(got - ref))
        assert abs(got - ref) < tol, (x, y, p, got, ref)
    return worst


@pytest.mark.parametrize("law", list(STARS))
def test_single_disks_adversarial(law):
    _check(STARS[law], adversarial_single())


@pytest.mark.parametrize("law", ["nonlinear", "quadratic", "power2"])
def test_pairs_adversarial(law):
    _check(STARS[law], adversarial_pairs())


@pytest.mark.parametrize("k", [2, 3])
def test_random_overlaps(k):
    rng = np.random.default_rng(k)
    _check(STARS["nonlinear"], random_configs(rng, 25, k))


def test_uniform_star_is_union_area():
    """For I = 1 the deficit is the area of (union of disks) cap star."""
    star = STARS["uniform"]
    for x, y, p in adversarial_pairs()[:20]:
        got = 1.0 - float(jp.occultation_flux(star, np.array(x), np.array(y), np.array(p), method="exact"))
        assert abs(got * np.pi - union_area(x, y, p)) < 1e-12


def test_two_disk_lens_closed_form():
    """Lens area of two disks inside a uniform star, closed form."""
    star = STARS["uniform"]
    r1, r2, dd = 0.1, 0.07, 0.12
    lens = (
        r1**2 * np.arccos((dd**2 + r1**2 - r2**2) / (2 * dd * r1))
        + r2**2 * np.arccos((dd**2 + r2**2 - r1**2) / (2 * dd * r2))
        - 0.5 * np.sqrt((-dd + r1 + r2) * (dd + r1 - r2) * (dd - r1 + r2) * (dd + r1 + r2))
    )
    union = np.pi * (r1**2 + r2**2) - lens
    got = 1.0 - float(jp.occultation_flux(star, np.array([0.2, 0.32]), np.array([0.1, 0.1]), np.array([r1, r2])))
    assert abs(got - union / np.pi) < 1e-14  # ~50 ulp of 1: rounding only


def test_overlap_is_not_double_counted():
    star = STARS["nonlinear"]
    x, y, r = np.array([0.3, 0.31]), np.array([0.1, 0.1]), np.array([0.05, 0.03])
    both = 1 - float(jp.occultation_flux(star, x, y, r))
    singles = sum(1 - float(jp.occultation_flux(star, x[i:i + 1], y[i:i + 1], r[i:i + 1])) for i in range(2))
    # the small disk lies wholly inside the big one
    assert abs(both - (1 - float(jp.occultation_flux(star, x[:1], y[:1], r[:1])))) < 1e-14
    assert singles - both > 1e-4


def test_rotation_invariance():
    star = STARS["nonlinear"]
    x, y, r = np.array([0.5, 0.53, 0.9]), np.array([0.2, 0.21, -0.4]), np.array([0.04, 0.03, 0.1])
    base = float(jp.occultation_flux(star, x, y, r))
    for ang in np.linspace(0.1, 6.2, 7):
        c, s = np.cos(ang), np.sin(ang)
        rot = float(jp.occultation_flux(star, c * x - s * y, s * x + c * y, r))
        assert abs(rot - base) < 1e-14
    perm = float(jp.occultation_flux(star, x[::-1], y[::-1], r[::-1]))
    assert abs(perm - base) < 1e-14


def test_broadcasting_and_shapes():
    star = STARS["quadratic"]
    x = np.linspace(-1.2, 1.2, 12).reshape(3, 4, 1) + np.array([0.0, 0.02])
    out = jp.occultation_flux(star, x, 0.1, np.array([0.05, 0.03]))
    assert out.shape == (3, 4)
    one = jp.occultation_flux(star, 0.3, 0.1, 0.05)
    assert one.shape == ()


@pytest.mark.parametrize("method", ["exact", "auto"])
def test_auto_equals_exact(method):
    rng = np.random.default_rng(7)
    star = STARS["nonlinear"]
    cfgs = random_configs(rng, 200, 2) + adversarial_pairs()
    k = 3
    x = np.array([c[0] + [5.0] * (k - len(c[0])) for c in cfgs])
    y = np.array([c[1] + [0.0] * (k - len(c[1])) for c in cfgs])
    r = np.array([c[2] + [0.01] * (k - len(c[2])) for c in cfgs])
    exact = np.asarray(jp.occultation_flux(star, x, y, r, method="exact"))
    got = np.asarray(jp.occultation_flux(star, x, y, r, method=method))
    assert np.max(np.abs(got - exact)) < 1e-13


def _grad_cases():
    cases = adversarial_pairs() + [(c[0] + [3.0], c[1] + [0.0], c[2] + [0.1]) for c in adversarial_single()[::3]]
    return [c for c in cases if len(c[0]) == 2 or len(c[0]) == 3]


@pytest.mark.parametrize("law", ["nonlinear", "quadratic", "power2"])
def test_gradients_finite_at_contacts(law):
    star = STARS[law]

    def f(x, y, r, params):
        st = jp.Star(law=star.law, params=params)
        return jp.occultation_flux(st, x, y, r, method="exact")

    grad = jax.jit(jax.grad(f, argnums=(0, 1, 2, 3)))
    for x, y, p in _grad_cases():
        gs = grad(jnp.array(x), jnp.array(y), jnp.array(p), star.params)
        for g in gs:
            assert np.all(np.isfinite(np.asarray(g))), (x, y, p, gs)


def test_gradient_matches_finite_difference():
    star = STARS["nonlinear"]
    x, y, r = jnp.array([0.5, 0.53]), jnp.array([0.2, 0.21]), jnp.array([0.04, 0.03])
    f = lambda x: jp.occultation_flux(star, x, y, r, method="exact")
    g = jax.grad(f)(x)
    h = 1e-6
    fd = [(f(x.at[i].add(h)) - f(x.at[i].add(-h))) / (2 * h) for i in range(2)]
    np.testing.assert_allclose(np.asarray(g), np.asarray(fd), rtol=1e-6, atol=1e-10)


def test_jit_vmap():
    star = STARS["nonlinear"]
    f = jax.jit(jax.vmap(lambda x: jp.occultation_flux(star, x, jnp.array([0.1, 0.1]), jnp.array([0.05, 0.03]))))
    xs = jnp.linspace(-1.2, 1.2, 50)[:, None] + jnp.array([0.0, 0.04])
    out = f(xs)
    ref = jp.occultation_flux(star, xs, 0.1, jnp.array([0.05, 0.03]), method="exact")
    np.testing.assert_allclose(np.asarray(out), np.asarray(ref), atol=1e-15)


def test_float32_error_is_bounded():
    """float32 inputs run in float32; error measured against float64 (docs)."""
    star = STARS["nonlinear"]
    rng = np.random.default_rng(3)
    cfgs = random_configs(rng, 100, 2)
    x = np.array([c[0] for c in cfgs]); y = np.array([c[1] for c in cfgs]); r = np.array([c[2] for c in cfgs])
    f64 = np.asarray(jp.occultation_flux(star, x, y, r, method="exact"))
    star32 = jp.Star(law=star.law, params=star.params.astype(jnp.float32))
    f32 = jp.occultation_flux(star32, x.astype(np.float32), y.astype(np.float32), r.astype(np.float32), method="exact")
    assert f32.dtype == jnp.float32
    assert np.max(np.abs(np.asarray(f32, float) - f64)) < 2e-6


def test_bad_inputs():
    star = STARS["quadratic"]
    with pytest.raises(ValueError, match="r"):
        jp.occultation_flux(star, [0.1], [0.1], [-0.1])
    with pytest.raises(ValueError, match="x must be finite"):
        jp.occultation_flux(star, [np.nan], [0.1], [0.1])
    with pytest.raises(ValueError, match="broadcast"):
        jp.occultation_flux(star, np.zeros(3), np.zeros(4), np.zeros(3))
    with pytest.raises(ValueError, match="method"):
        jp.occultation_flux(star, [0.1], [0.1], [0.1], method="blender")


def test_inner_midpoint_rule_at_its_margin():
    """Disks with 1 - d - p >= INNER_MARGIN p use the 8-node midpoint rule in
    "auto": check it against the general rule right at the margin, for small
    and large disks, every law."""
    from jaxppo.core.occult import INNER_MARGIN, disk_deficit, inner_disk_deficit

    p = np.exp(np.linspace(np.log(1e-4), np.log(0.33), 40))
    d = 1.0 - p - INNER_MARGIN * p
    for star in STARS.values():
        g, phi1 = star.radial_kernel()
        ref = jax.vmap(lambda a, b: disk_deficit(a, b, g, phi1, 64))(jnp.asarray(d), jnp.asarray(p))
        got = inner_disk_deficit(jnp.asarray(d), jnp.asarray(p), g)
        assert float(jnp.max(jnp.abs(got - ref))) / float(star.total_flux) < 1e-13


@pytest.mark.parametrize("law", ["nonlinear", "quadratic", "power2"])
def test_inner_pair_kernel_against_union(law):
    """Overlapping pairs well inside the star use inclusion-exclusion in
    "auto" (full circles by the midpoint rule, the lens by Gauss-Legendre);
    nested, near-tangent and concentric pairs included."""
    from jaxppo.core.occult import INNER_MARGIN, inner_pair_deficit, union_deficit

    star = STARS[law]
    g, phi1 = star.radial_kernel()
    rng = np.random.default_rng(5)
    n = 3000
    r = np.exp(rng.uniform(np.log(1e-4), np.log(0.3), (n, 2)))
    x1, y1 = rng.uniform(-0.9, 0.9, (2, n))
    ang = rng.uniform(0, 2 * np.pi, n)
    sep = rng.uniform(0, 1, n) * r.sum(1)
    sep[:50] = np.abs(r[:50, 0] - r[:50, 1])  # internally tangent
    sep[50:100] = 0.0  # concentric
    sep[100:150] = r[100:150].sum(1) * (1 - 1e-12)  # just overlapping
    x = np.stack([x1, x1 + sep * np.cos(ang)], 1)
    y = np.stack([y1, y1 + sep * np.sin(ang)], 1)
    ok = np.all(1 - np.hypot(x, y) - r >= INNER_MARGIN * r, axis=1)
    special = (np.arange(n) < 150)[ok]
    x, y, r = x[ok], y[ok], r[ok]
    ref = jax.vmap(lambda a, b, c: union_deficit(a, b, c, g, phi1, 64))(x, y, r)
    got = jax.vmap(lambda a, b, c: inner_pair_deficit(a, b, c, g))(x, y, r)
    err = np.abs(np.asarray(got - ref)) / float(star.total_flux)
    assert np.max(err[~special]) < 1e-12  # random pairs
    assert np.max(err) < 1e-11  # with tangent and concentric pairs: ~5e-13 measured (requirement: 1e-10)
    grad = jax.grad(lambda xx: jnp.sum(jax.vmap(lambda a, b, c: inner_pair_deficit(a, b, c, g))(xx, y, r)))(jnp.asarray(x))
    assert np.all(np.isfinite(np.asarray(grad)))
