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


@pytest.fixture(autouse=True)
def _lens_path_on_every_batch(monkeypatch):
    """By default "auto" sends calls with few crossing pairs to the union
    integral (cheaper to compile); here its lens path runs on every batch, so
    the single-configuration checks below test it too."""
    import jaxppo.model._plan

    monkeypatch.setattr(jaxppo.model._plan, "LENS_MIN_PAIRS", 0)


def _intensity_r(star):
    # the star's own profile, compiled once: the reference's quadrature
    # calls it at ~10^4 radii per scene list (eager, each call dispatched
    # JAX's primitives one by one, most of these tests' time)
    intensity = jax.jit(lambda mu: star.intensity(mu))

    def f(r):
        mu = np.sqrt(max(1.0 - r * r, 0.0))
        return float(intensity(mu))

    return f


def _check(star, cfgs, tol=TOL64):
    ir = _intensity_r(star)
    f0 = reference_total(ir)
    np.testing.assert_allclose(float(star.total_flux), f0, rtol=1e-12)
    worst = 0.0
    for x, y, p in cfgs:
        ref = 1.0 - reference_deficit(ir, x, y, p) / f0
        for method in ("exact", "auto"):
            got = float(jp.occultation_flux(star, np.array(x), np.array(y), np.array(p), method=method))
            worst = max(worst, abs(got - ref))
            assert abs(got - ref) < tol, (method, x, y, p, got, ref)
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
    # "auto" uses cheaper rules (midpoint, lens) where they converge; both
    # methods are checked against the union integral at 128 nodes per piece
    # (itself checked against the independent radial reference above).
    # Measured: exact 2.8e-12, auto 3.9e-12, both from the one-disk rule on a
    # large disk (p = 0.27) 0.03 from the limb.
    ref = np.asarray(jp.occultation_flux(star, x, y, r, method="exact", order=128))
    got = np.asarray(jp.occultation_flux(star, x, y, r, method=method))
    assert np.max(np.abs(got - ref)) < 1e-11


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


def _padded_scenes(cfgs, k=3):
    x = np.array([c[0] + [5.0] * (k - len(c[0])) for c in cfgs])
    y = np.array([c[1] + [0.0] * (k - len(c[1])) for c in cfgs])
    r = np.array([c[2] + [0.01] * (k - len(c[2])) for c in cfgs])
    return x, y, r


def _tabulated(interpolation):
    mu = np.sort(np.concatenate([[0.0], np.cos(np.linspace(0, np.pi / 2, 40))[:-1]]))
    mu[-1] = 1.0
    return jp.Star.tabulated(mu, np.asarray(STARS["nonlinear"].intensity(mu)), interpolation=interpolation)


@pytest.mark.parametrize("star", [STARS["nonlinear"], _tabulated("sqrt-poly"), _tabulated("linear")], ids=["nonlinear", "sqrt-poly", "linear"])
def test_jitted_auto_equals_concrete(star):
    """Under jit "auto" plans on the device (lens, midpoint, general and
    union rules on the frames that need them): the same numbers as the host
    plan and the union integral, on random scenes of two and three disks,
    contacts, nested, identical and limb-crossing disks."""
    rng = np.random.default_rng(11)
    cfgs = random_configs(rng, 150, 2) + random_configs(rng, 60, 3) + adversarial_pairs()
    cfgs += [(c[0] + [0.2], c[1] + [-0.3], c[2] + [0.05]) for c in adversarial_single()]
    x, y, r = _padded_scenes(cfgs)
    jitted = np.asarray(jax.jit(lambda a, b, c: jp.occultation_flux(star, a, b, c))(x, y, r))
    host = np.asarray(jp.occultation_flux(star, x, y, r))
    ref = np.asarray(jp.occultation_flux(star, x, y, r, method="exact", order=128))
    assert np.max(np.abs(jitted - host)) < 1e-12  # measured 3e-15
    if star.smooth:
        # as the host plan (test_auto_equals_exact); a piecewise table's
        # kinks keep every rule at order 24 ~1e-8 from order 128, both plans alike
        assert np.max(np.abs(jitted - ref)) < 1e-11
        # the fast rules did run: the union integral alone differs in the last digits
        assert not np.array_equal(jitted, np.asarray(jp.occultation_flux(star, x, y, r, method="exact")))


def test_jitted_auto_gradient_matches_finite_differences():
    """Gradients of jitted "auto" (shape derivatives of the lens, one-disk and
    union rules) equal to "exact"'s, and to the mean of the one-sided
    differences within their spread (random scenes can put a disk h from a
    contact, where the flux has a kink)."""
    star = STARS["nonlinear"]
    rng = np.random.default_rng(12)
    x, y, r = (jnp.asarray(v) for v in _padded_scenes(random_configs(rng, 40, 2) + random_configs(rng, 20, 3)))
    f = {m: jax.jit(lambda a, b, c, m=m: jp.occultation_flux(star, a, b, c, method=m)) for m in ("auto", "exact")}
    g = {m: jax.jit(jax.grad(lambda a, b, c, m=m: jnp.sum(f[m](a, b, c)), argnums=(0, 1, 2)))(x, y, r) for m in f}
    h = 1e-6
    for arg in range(3):
        ga = np.asarray(g["auto"][arg])
        assert np.all(np.isfinite(ga))
        np.testing.assert_allclose(ga, np.asarray(g["exact"][arg]), rtol=0, atol=1e-9)
        for k in range(3):
            args = [x, y, r]
            step = jnp.zeros_like(x).at[:, k].set(h)
            f0 = np.asarray(f["auto"](*args))
            args[arg] = args[arg] + step
            fp = np.asarray(f["auto"](*args))
            args[arg] = args[arg] - 2 * step
            fm = np.asarray(f["auto"](*args))
            plus, minus = (fp - f0) / h, (f0 - fm) / h
            # smooth: the one-sided differences differ by f'' h <~ 3e-6, and the
            # gradient is their mean; a kink within h: within their spread
            spread = np.abs(plus - minus)
            kink = spread > 1e-5
            assert np.all(np.abs(ga[:, k] - 0.5 * (plus + minus)) <= np.where(kink, spread, 0.0) + 2e-8)
            assert np.mean(kink) < 0.1


def test_lens_gradient_where_its_parametrisation_is_singular():
    """The lens rule's derivatives are shape derivatives: by automatic
    differentiation of its parametrisation they were 3% off for equal radii
    at delta = p (a tie in the sorted Heron product) and half the true value
    for a disk centred on the star."""
    from jaxppo.core.occult import lens_deficit

    star = STARS["nonlinear"]
    g, _ = star.radial_kernel()
    inten = star.radial_intensity()
    h = 1e-6
    for xs, ys, rs in (([0.31, 0.37], [0.12, 0.2], [0.1, 0.1]), ([0.0, 0.06], [0.0, 0.08], [0.1, 0.1])):
        args = [jnp.array(v) for v in (xs, ys, rs)]
        for arg in range(3):
            def lens(v, arg=arg):
                a = list(args)
                a[arg] = v
                return lens_deficit(*a, g, 16, inten)

            got = np.asarray(jax.grad(lens)(args[arg]))
            fd = [(lens(args[arg].at[i].add(h)) - lens(args[arg].at[i].add(-h))) / (2 * h) for i in range(2)]
            np.testing.assert_allclose(got, np.asarray(fd), rtol=0, atol=1e-9)


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


def _crossing_pairs(rng, n):
    """Crossing pairs anywhere on and around the star, p from 1e-4 to 0.5,
    with near-tangent (outer and inner) ones."""
    r = np.exp(rng.uniform(np.log(1e-4), np.log(0.5), (n, 2)))
    x1, y1 = rng.uniform(-1.1, 1.1, (2, n))
    ang = rng.uniform(0, 2 * np.pi, n)
    lo, hi = np.abs(r[:, 0] - r[:, 1]), r.sum(1)
    sep = rng.uniform(lo, hi)
    sep[:100] = hi[:100] * (1 - 1e-12)
    sep[100:200] = lo[100:200] * (1 + 1e-12) + 1e-300
    x = np.stack([x1, x1 + sep * np.cos(ang)], 1)
    y = np.stack([y1, y1 + sep * np.sin(ang)], 1)
    return x, y, r


def _lens_rho_complex(x, y, r):
    """lens_rho written independently: complex arithmetic, angles from atan2."""
    dx, dy = x[:, 1] - x[:, 0], y[:, 1] - y[:, 0]
    delta, base = np.hypot(dx, dy), np.arctan2(dy, dx)
    h4 = (r[:, 0] + r[:, 1] + delta) * (-r[:, 0] + r[:, 1] + delta) * (r[:, 0] - r[:, 1] + delta) * (r[:, 0] + r[:, 1] - delta)
    area4 = np.sqrt(np.maximum(h4, 0.0))
    rho = np.full(len(x), np.inf)

    def wrap(a):
        return np.mod(a + np.pi, 2 * np.pi) - np.pi

    for i, centre in ((0, base), (1, base + np.pi)):
        p, q = r[:, i], r[:, 1 - i]
        h = np.arctan2(area4, p * p - q * q + delta**2)
        d = np.hypot(x[:, i], y[:, i])
        c = (1 - d * d - p * p) / (2 * p * d)
        off = wrap(np.arctan2(y[:, i], x[:, i]) - centre)
        with np.errstate(all="ignore"):
            z = (off + 1j * np.arccosh(np.maximum(c, 1))) / h
            rho_in = np.abs(z + np.sqrt(z - 1) * np.sqrt(z + 1))
            ac = np.arccos(np.clip(c, -1, 1))
            zr = np.minimum(np.abs(wrap(off + ac)), np.abs(wrap(off - ac))) / h
            rho_x = np.where(zr > 1, zr + np.sqrt(np.maximum(zr * zr - 1, 0)), 1)
        rho = np.minimum(rho, np.where(c >= 1, rho_in, np.where(c > -1, rho_x, 1)))
        if i == 0:
            corner = np.hypot(x[:, 0] + p * np.cos(base + h), y[:, 0] + p * np.sin(base + h))
            rho = np.where(corner < 1, rho, 1)
    return rho


def test_lens_rho_against_complex_formula():
    from jaxppo.core.occult import lens_rho

    x, y, r = _crossing_pairs(np.random.default_rng(3), 5000)
    got = np.asarray(lens_rho(x, y, r))
    want = _lens_rho_complex(x, y, r)
    assert np.array_equal(np.isinf(got), np.isinf(want))
    rel = np.abs(got - want) / np.where(np.isfinite(want), want, 1.0)
    rel[~np.isfinite(want)] = 0.0
    assert np.max(rel[200:]) < 1e-9  # random pairs (measured 1e-11)
    # near-tangent pairs: the naive Heron product above loses half the digits
    assert np.max(rel[:200]) < 1e-3
    assert np.all((got == 1.0) == (want == 1.0))


@pytest.mark.parametrize("law", ["nonlinear", "quadratic", "power2"])
def test_lens_kernel_against_union(law):
    """Crossing pairs whose lens is on the star: D(A u B) = D(A) + D(B) - lens.
    At every tier of LENS_RULES the lens rule meets its bound where lens_rho
    admits it, and the bound rho^(-2n) is not loose: just below the admitted
    rho the same rule is measurably worse."""
    from jaxppo.core.occult import LENS_RULES, disk_deficit, lens_deficit, lens_rho, union_deficit

    star = STARS[law]
    g, phi1 = star.radial_kernel()
    f0 = float(star.total_flux)
    x, y, r = _crossing_pairs(np.random.default_rng(5), 6000)
    rho = np.asarray(lens_rho(x, y, r))
    keep = rho > 1.2
    x, y, r, rho = x[keep], y[keep], r[keep], rho[keep]
    d = np.hypot(x, y)
    one = jax.vmap(lambda a, b: disk_deficit(a, b, g, phi1, 96))
    union = jax.vmap(lambda a, b, c: union_deficit(a, b, c, g, phi1, 96))(x, y, r)
    ref = (np.asarray(one(d[:, 0], r[:, 0])) + np.asarray(one(d[:, 1], r[:, 1])) - np.asarray(union)) / f0
    for nodes, rho_min in LENS_RULES:
        got = np.asarray(jax.vmap(lambda a, b, c: lens_deficit(a, b, c, g, nodes))(x, y, r)) / f0
        err = np.abs(got - ref)
        admitted = rho >= rho_min
        assert admitted.sum() > 100
        assert np.max(err[admitted]) < 1e-13  # measured <= 1e-14
        below = (rho < rho_min) & (rho > 0.6 * rho_min)
        assert np.max(err[below]) > 10 * np.max(err[admitted])
    grad = jax.grad(lambda xx: jnp.sum(jax.vmap(lambda a, b, c: lens_deficit(a, b, c, g))(xx, y, r)))(jnp.asarray(x))
    assert np.all(np.isfinite(np.asarray(grad)))


def test_auto_plan_scenes():
    """"auto" drops disks off the star or inside another, sums one-disk terms
    and lenses where each disk crosses at most one other, and sends the rest
    (a disk crossing two others, lenses at the limb) to the union integral:
    every scene class against the union integral at 96 nodes."""
    from jaxppo.model._plan import _survey

    star = STARS["nonlinear"]
    rows = [
        ([0.1, 0.15, 2.0], [0.0, 0.0, 0.0], [0.1, 0.1, 0.1]),  # a pair, a disk off the star
        ([0.1, 0.12, -0.5], [0.0, 0.01, 0.2], [0.1, 0.02, 0.05]),  # nested pair, separate disk
        ([0.3, 0.3, 0.3], [0.2, 0.2, 0.2], [0.05, 0.05, 0.05]),  # identical disks
        ([0.0, 0.1, 0.05], [0.0, 0.0, 0.08], [0.07, 0.07, 0.07]),  # three mutually crossing
        ([-0.5, -0.42, 0.5], [0.0, 0.0, 0.0], [0.06, 0.06, 0.06]),  # one pair crosses, third separate
        ([0.97, 1.02, 0.0], [0.0, 0.05, 0.0], [0.06, 0.06, 0.0]),  # lens on the limb
        ([0.0, 0.05, 0.0], [0.0, 0.0, 0.0], [1.5, 0.1, 0.0]),  # the star covered
        ([0.3, 0.3 + 0.14, 0.0], [0.0, 0.0, 0.0], [0.07, 0.07, 0.0]),  # tangent from outside
    ]
    x, y, r = (np.array([row[i] for row in rows]) for i in range(3))
    multiple, counts, inner, inner_sum, cross = (np.asarray(v) for v in _survey(star, x, y, r))
    assert list(multiple) == [False, False, False, True, False, False, False, False]
    assert not counts[0, 2] and not counts[1, 1] and counts[2].tolist() == [True, False, False]
    assert counts[6].tolist() == [True, False, False]  # the disk inside the one covering the star
    assert sorted(np.nonzero(cross)[0].tolist()) == [0, 3, 3, 3, 4, 5]
    assert not inner[5, 0] and inner[4].all()
    got = np.asarray(jp.occultation_flux(star, x, y, r))
    ref = np.asarray(jp.occultation_flux(star, x, y, r, method="exact", order=96))
    assert np.max(np.abs(got - ref)) < 1e-13
    assert abs(got[6]) < 1e-15 and got[7] < 1.0


def test_small_batches_take_the_union_integral(monkeypatch):
    """Below LENS_MIN_PAIRS crossing pairs a call's overlap frames are the
    union integral's, bit for bit; above it they take the lens path."""
    import jaxppo.model._plan as F

    star = STARS["nonlinear"]
    x = np.array([[0.1, 0.15], [0.3, 0.32], [0.5, 2.0]])
    y = np.zeros_like(x)
    r = np.full_like(x, 0.05)
    exact = np.asarray(jp.occultation_flux(star, x, y, r, method="exact"))
    monkeypatch.setattr(F, "LENS_MIN_PAIRS", 3)
    assert np.array_equal(np.asarray(jp.occultation_flux(star, x, y, r))[:2], exact[:2])
    monkeypatch.setattr(F, "LENS_MIN_PAIRS", 2)
    lens = np.asarray(jp.occultation_flux(star, x, y, r))
    assert not np.array_equal(lens[:2], exact[:2])
    assert np.max(np.abs(lens - exact)) < 1e-14


# ---------------------------------------------------------------------------
# Issue 16: degenerate geometry, float32, traced bad input (each test fails on
# the engine before the fix).
# ---------------------------------------------------------------------------
S16 = jp.Star.quadratic(0.4, 0.25)


def _as32(star):
    return jax.tree_util.tree_map(lambda v: v.astype(jnp.float32) if hasattr(v, "astype") else v, star)


@pytest.mark.parametrize("method", ["exact", "auto"])
def test_disk_matching_the_star_counts_once(method):
    """A disk that is the stellar disk hides the whole star: flux 0, not -1
    (the circle was counted as a planet arc on the star and as a disk covering
    it), also with a second disk crossing the limb, under jit, with integer
    input and in float32."""
    assert abs(float(jp.occultation_flux(S16, [0.0], [0.0], [1.0], method=method))) < 1e-15
    assert abs(float(jp.occultation_flux(S16, [0, 0], [0, 0], [1, 1], method=method))) < 1e-15
    assert abs(float(jp.occultation_flux(S16, [0.0, 1.0], [0.0, 0.0], [1.0, 0.3], method=method))) < 1e-15
    jitted = jax.jit(lambda x, y, r: jp.occultation_flux(S16, x, y, r, method=method))
    assert abs(float(jitted(jnp.zeros(1), jnp.zeros(1), jnp.ones(1)))) < 1e-15
    f32 = jp.occultation_flux(_as32(S16), np.float32([0.0, 1.0]), np.float32([0.0, 0.0]), np.float32([1.0, 0.3]), method=method)
    assert abs(float(f32)) < 1e-6
    # just inside and just outside: continuous
    for r in (1 - 1e-12, 1 + 1e-12):
        assert abs(float(jp.occultation_flux(S16, [0.0], [0.0], [r], method=method))) < 1e-11


def test_float32_no_nan_where_an_edge_passes_the_centre():
    """float32 power-2 law: a disk edge through (or within 4e-5 of) the
    stellar centre gave NaN (a float64 guard constant, 1e-290, is 0 in float32)."""
    star = jp.Star.power2(0.7, 0.6)
    s32 = _as32(star)
    x = np.linspace(-0.4, 0.4, 4001)
    x = np.concatenate([x, [0.3, 0.3 + 1e-6, 0.3 - 3e-5, 0.5]])[:, None]
    r = np.where(x == 0.5, 0.5, 0.3)
    for method in ("exact", "auto"):
        f32 = np.asarray(jp.occultation_flux(s32, x.astype(np.float32), np.zeros_like(x, np.float32), r.astype(np.float32), method=method))
        f64 = np.asarray(jp.occultation_flux(star, x, 0 * x, r, method=method))
        assert np.all(np.isfinite(f32)), method
        assert np.max(np.abs(f32 - f64)) < 2e-6
    grad = jax.grad(lambda v: jp.occultation_flux(s32, v, jnp.zeros(1, jnp.float32), jnp.full(1, 0.3, jnp.float32), method="exact"))
    assert np.isfinite(float(grad(jnp.full(1, 0.3, jnp.float32))[0]))
    # the guarded kernels themselves at s = 0, both dtypes
    from jaxppo.core.intensity import power_basis_g

    a, e = star._power()
    for dt in (jnp.float32, jnp.float64):
        val, dval = jax.value_and_grad(lambda s: power_basis_g(s, a.astype(dt), e.astype(dt)))(jnp.zeros((), dt))
        assert np.isfinite(float(val)) and np.isfinite(float(dval))
        assert abs(float(val) - float(a[0] + a[1]) / 2) < 1e-6  # g(0) = I(mu = 1) / 2


@pytest.mark.parametrize("angle", [0.0, 0.7])
def test_huge_occultors(angle):
    """A disk of radius R whose edge crosses the star 0.5 from its centre:
    arcs integrated from the near point keep ~1e-15 where the old
    parametrisation lost R^2 eps (1e-7 at R = 1e6); radii above MAX_RADIUS
    are refused."""
    ir = _intensity_r(S16)
    f0 = reference_total(ir)
    for R in (1e2, 1e4, 1e6):
        x, y = [(R + 0.5) * np.cos(angle), 0.3], [(R + 0.5) * np.sin(angle), 0.1]
        for k in (1, 2):
            ref = 1 - reference_deficit(ir, x[:k], y[:k], [R, 0.1][:k]) / f0
            for method in ("exact", "auto"):
                got = float(jp.occultation_flux(S16, x[:k], y[:k], [R, 0.1][:k], method=method))
                # measured <= 1e-14; the rounding of d ~ R alone is ~1e-16 R
                assert abs(got - ref) < 1e-10, (R, k, method, got - ref)
        # a planet crossing the huge disk's edge on the star: "auto" took the
        # lens rule (cosines about the far point) and lost 5e-8 at R = 1e6
        x, y = [(R + 0.5) * np.cos(angle), 0.5 * np.cos(angle)], [(R + 0.5) * np.sin(angle), 0.5 * np.sin(angle) + 0.05]
        ref = 1 - reference_deficit(ir, x, y, [R, 0.1]) / f0
        for method in ("exact", "auto"):
            got = float(jp.occultation_flux(S16, x, y, [R, 0.1], method=method))
            assert abs(got - ref) < 1e-10, (R, "lens", method, got - ref)
    from jaxppo.core.occult import MAX_RADIUS

    with pytest.raises(ValueError, match="r \\(disk radius\\) must be <= 1e\\+06"):
        jp.occultation_flux(S16, [2 * MAX_RADIUS], [0.0], [2 * MAX_RADIUS])
    traced = jax.jit(lambda r: jp.occultation_flux(S16, jnp.array([2e6]), jnp.zeros(1), r))(jnp.array([2e6]))
    assert np.isnan(float(traced))


def _one_sided(f, x, i, h=1e-7):
    e = jnp.zeros_like(x).at[i].set(h)
    return float((f(x + e) - f(x)) / h), float((f(x) - f(x - e)) / h)


def _check_grad_fd(f, x, tol=2e-6):
    g = np.asarray(jax.grad(f)(x))
    for i in range(x.size):
        plus, minus = _one_sided(f, x, i)
        assert abs(plus - minus) < tol, ("not differentiable here", i, plus, minus)
        assert abs(g[i] - 0.5 * (plus + minus)) < tol, (i, g[i], plus, minus)


def test_gradient_at_a_triple_point():
    """Three circles through one point: the cut points of the slivers there
    were classified inconsistently and their end-point derivatives made
    d flux/dx wrong by 0.08 (the union area is C^1 there)."""
    px, py = 0.35, 0.2
    r = jnp.array([0.1, 0.15, 0.12])
    ang = np.array([0.3, 2.0, 4.1])
    x = jnp.asarray(px + np.asarray(r) * np.cos(ang))
    y = jnp.asarray(py + np.asarray(r) * np.sin(ang))
    _check_grad_fd(lambda v: jp.occultation_flux(S16, v, y, r, method="exact"), x)
    _check_grad_fd(lambda v: jp.occultation_flux(S16, x, v, r, method="exact"), y)
    _check_grad_fd(lambda v: jp.occultation_flux(S16, x, y, v, method="exact"), r)


def test_gradient_at_a_crossing_on_the_limb():
    """Two circles crossing exactly on the limb (issue 16 item 5): gradient
    [0.093, 0.019] against finite differences [0.046, 0.066] before."""
    x = jnp.array([1 + 0.1 * np.cos(2), 1 + 0.12 * np.cos(4)])
    y = jnp.array([0.1 * np.sin(2), 0.12 * np.sin(4)])
    r = jnp.array([0.1, 0.12])
    _check_grad_fd(lambda v: jp.occultation_flux(S16, v, y, r, method="exact"), x)
    _check_grad_fd(lambda v: jp.occultation_flux(S16, x, v, r, method="exact"), y)


def test_gradient_of_a_disk_centred_on_the_star():
    """A disk centred exactly on the star with a crossing disk: d/dx was
    half the true value (the polar angle of the centre had no derivative);
    a single disk at 0 < |x| < 1e-154 had a NaN gradient (x^2 underflowed)."""
    y, r = jnp.zeros(2), jnp.array([0.2, 0.1])
    _check_grad_fd(lambda v: jp.occultation_flux(S16, v, y, r, method="exact"), jnp.array([0.0, 0.25]))
    for v in (0.0, 1e-300, 1e-170, 1e-100):
        for fn in (
            lambda a: jp.occultation_flux(S16, a, jnp.zeros(1), jnp.full(1, 0.2), method="exact"),
            lambda a: jp.occultation_flux(S16, a, jnp.zeros(1), jnp.full(1, 0.2)),
        ):
            g = float(jax.grad(fn)(jnp.full(1, v))[0])
            assert np.isfinite(g) and abs(g) < 1e-12
    from jaxppo.model._terms import separate_frames

    for v in (0.0, 1e-170):
        g = jax.grad(lambda a: separate_frames(S16, a, jnp.zeros((1, 1)), jnp.full((1, 1), 0.2), 24)[0])(jnp.full((1, 1), v))
        assert np.isfinite(float(g[0, 0])) and abs(float(g[0, 0])) < 1e-12
    g32 = jax.grad(lambda a: jp.occultation_flux(_as32(S16), a, jnp.zeros(1, jnp.float32), jnp.full(1, 0.2, jnp.float32), method="exact"))
    assert np.isfinite(float(g32(jnp.full(1, 1e-30, jnp.float32))[0]))


def test_traced_bad_input_gives_nan():
    """Under jit a NaN position gave 0.98789 and a negative radius 1.0: now
    that frame (only) is NaN, and so is its gradient."""
    for method in ("exact", "auto"):
        f = jax.jit(lambda x, r: jp.occultation_flux(S16, x, jnp.zeros_like(x), r, method=method))
        out = np.asarray(f(jnp.array([[np.nan], [0.2]]), jnp.array([[0.1], [0.1]])))
        assert np.isnan(out[0]) and np.isfinite(out[1])
        out = np.asarray(f(jnp.array([[0.0], [0.2]]), jnp.array([[-0.1], [0.1]])))
        assert np.isnan(out[0]) and np.isfinite(out[1])
        out = np.asarray(f(jnp.array([[np.inf, 0.1]]), jnp.array([[0.1, 0.1]])))
        assert np.isnan(out[0])
        g = jax.grad(lambda x: f(x, jnp.array([[0.1]]))[0])(jnp.array([[np.nan]]))
        assert np.isnan(float(g[0, 0]))
    from jaxppo.model._terms import separate_frames

    sep = separate_frames(S16, jnp.array([[np.nan], [0.2]]), jnp.zeros((2, 1)), jnp.full((2, 1), 0.1), 24)
    assert np.isnan(float(sep[0])) and np.isfinite(float(sep[1]))


@pytest.mark.parametrize("method", ["exact", "auto"])
def test_empty_axes(method):
    out = jp.occultation_flux(S16, np.zeros((4, 0)), np.zeros((4, 0)), np.zeros((4, 0)), method=method)
    assert out.shape == (4,) and np.all(np.asarray(out) == 1.0)
    out = jp.occultation_flux(S16, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)), method=method)
    assert out.shape == (0,)


def test_order_and_chunk_are_validated():
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="order must be a positive integer"):
            jp.occultation_flux(S16, [0.1], [0.1], [0.1], order=bad)
    with pytest.raises(ValueError, match="chunk must be a positive integer"):
        jp.occultation_flux(S16, [0.1], [0.1], [0.1], chunk=0)


def test_float32_policy_warns_once_when_x64_is_off():
    """Issue 15 item 2: with JAX's x64 off (the default) a light curve is
    float32 end to end (~20 ppm near a PPO); the first flux call says so,
    once, and never flips the global switch."""
    import subprocess
    import sys

    code = (
        "import warnings, numpy as np, jax\n"
        "import jaxppo as jp\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    s = jp.Star.quadratic(0.4, 0.25)\n"
        "    a = jp.occultation_flux(s, np.array([0.3]), np.array([0.1]), np.array([0.05]))\n"
        "    b = jp.occultation_flux(s, np.array([0.3]), np.array([0.1]), np.array([0.05]), method='exact')\n"
        "msgs = [str(x.message) for x in w if 'jaxppo: float32' in str(x.message)]\n"
        "print(len(msgs), a.dtype, jax.config.jax_enable_x64, 'jax_enable_x64' in msgs[0])\n"
    )
    import os

    env = {k: v for k, v in os.environ.items() if k != "JAX_ENABLE_X64"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1", "float32", "False", "True"], out.stdout


def test_overlap_calls_share_one_program():
    """The sweep's overlap frames (fewer than OVERLAP_LENS_MIN per call) run
    the union integral in calls of one padded size, so the blocks of a scan
    (each with its own number of overlap frames) reuse one compiled program;
    the numbers are the union integral's, frame by frame."""
    from jaxppo.model._plan import OVERLAP_CALL, overlap_flux
    from jaxppo.model._terms import exact_frames

    star = STARS["nonlinear"]
    rng = np.random.default_rng(4)
    x, y, r = _crossing_pairs(rng, 2 * OVERLAP_CALL + 300)
    # (calls of 512 frames: a program of its own, not counted below)
    ref = np.asarray(jp.occultation_flux(star, x, y, r, method="exact", chunk=512))
    before = exact_frames._cache_size()
    for n in (5, 700, OVERLAP_CALL + 1, 2 * OVERLAP_CALL + 300):
        got = overlap_flux(star, x[:n], y[:n], r[:n], 24, 65536)
        assert np.array_equal(got, ref[:n])
    assert exact_frames._cache_size() - before <= 1


def test_vmapped_auto_takes_the_union_integral():
    """Batched by vmap, the device plan's switches would run every rule on
    every frame (2.3x the union integral): "auto" sees the batching and takes
    the union integral, bit for bit."""
    star = STARS["nonlinear"]
    rng = np.random.default_rng(6)
    x, y, r = (jnp.asarray(v) for v in _crossing_pairs(rng, 300))
    f = {m: jax.jit(jax.vmap(lambda a, b, c, m=m: jp.occultation_flux(star, a, b, c, method=m))) for m in ("auto", "exact")}
    assert np.array_equal(np.asarray(f["auto"](x, y, r)), np.asarray(f["exact"](x, y, r)))
