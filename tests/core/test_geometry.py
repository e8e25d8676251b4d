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


# --- Keplerian orbits -------------------------------------------------------

def _dec_sin_cos(x):
    """(sin x, cos x) of a Decimal |x| <= 4 by their Taylor series at the
    context precision."""
    from decimal import Decimal

    s, c, term_s, term_c, k = Decimal(0), Decimal(0), x, Decimal(1), 0
    while True:
        s += term_s
        c += term_c
        term_s = -term_s * x * x / ((2 * k + 2) * (2 * k + 3))
        term_c = -term_c * x * x / ((2 * k + 1) * (2 * k + 2))
        k += 1
        if abs(term_s) < Decimal(10) ** -70 and abs(term_c) < Decimal(10) ** -70:
            return s, c


def _kepler_reference(M, e):
    """E with E - e sin E = M in 60-digit Decimal arithmetic (Newton from
    E = M + e sin M ... converged to 1e-50), for M in [-pi, pi]."""
    from decimal import Decimal, getcontext

    getcontext().prec = 60
    M, e = Decimal(float(M)), Decimal(float(e))
    E = M + (e if M > 0 else -e) * Decimal("0.85")
    for _ in range(200):
        s, c = _dec_sin_cos(E)
        step = (E - e * s - M) / (1 - e * c)
        E -= step
        if abs(step) < Decimal(10) ** -50:
            break
    return E


def _anomaly_grid():
    # uniform in [-pi, pi] and log-spaced down to 1e-16 (E ~ M / (1 - e)
    # there: the corner where Danby's starter needed > 6 Halley steps)
    tiny = np.logspace(-16, 0, 17)
    M = np.concatenate([np.linspace(-np.pi, np.pi, 61), tiny, -tiny[::3], [np.pi - 1e-9, -np.pi + 1e-12]])
    return np.unique(M)


def test_kepler_solver_against_a_60_digit_reference():
    """E - e sin E = M solved to float64 accuracy for e up to 0.9999 (incl.
    the hard corner M -> 0, e -> 1), against Newton's method in 60-digit
    decimal arithmetic; e = 0 returns M exactly."""
    from jaxppo.core.geometry import kepler_eccentric_anomaly

    M = _anomaly_grid()
    for e in (0.0, 0.1, 0.5, 0.8, 0.95, 0.99, 0.999, 0.9999):
        got = np.asarray(kepler_eccentric_anomaly(jnp.asarray(M), e))
        want = np.array([float(_kepler_reference(m, e)) for m in M])
        # a perfect float64 solver is off by ~eps |M| / (1 - e cos E): the
        # rounding of M is amplified by the equation's conditioning
        cond = 1.0 / (1.0 - e * np.cos(want))
        err = np.abs(got - want) / (np.spacing(np.maximum(np.abs(want), np.abs(M))) * cond + 1e-45)  # the reference leaves ~1e-51 at M = 0
        assert np.max(err) <= 3, (e, np.max(err), M[np.argmax(err)])
        if e == 0.0:
            assert np.array_equal(got, M)
    # any mean anomaly: wrapped to [-pi, pi] (sin and cos of E unchanged)
    E = np.asarray(kepler_eccentric_anomaly(jnp.asarray([0.3 + 40 * np.pi, -2.0 - 6 * np.pi]), 0.5))
    want = [float(_kepler_reference(0.3, 0.5)), float(_kepler_reference(-2.0, 0.5))]
    assert np.allclose(E, want, rtol=0, atol=1e-13)


def test_kepler_derivatives_match_the_reference_differences():
    """dE/dM and dE/de (implicit function theorem, custom JVP) against
    central differences of the 60-digit reference; finite for e = 0.95."""
    from decimal import Decimal

    from jaxppo.core.geometry import kepler_eccentric_anomaly

    h = 1e-7
    for M, e in ((0.3, 0.1), (2.5, 0.5), (-1.0, 0.8), (0.02, 0.95), (-3.0, 0.95), (1.0, 0.0)):
        dM, de = jax.grad(kepler_eccentric_anomaly, argnums=(0, 1))(M, e)
        ref_dM = float((_kepler_reference(M + h, e) - _kepler_reference(M - h, e)) / Decimal(2 * h))
        ref_de = float((_kepler_reference(M, e + h) - _kepler_reference(M, e - h)) / Decimal(2 * h))
        assert np.isfinite(float(dM)) and np.isfinite(float(de))
        assert abs(float(dM) - ref_dM) < 1e-6 * abs(ref_dM) + 1e-9, (M, e, float(dM), ref_dM)
        assert abs(float(de) - ref_de) < 1e-6 * abs(ref_de) + 1e-9, (M, e, float(de), ref_de)


def _old_circular_position(pl, t, xp=np):
    """The circular orbit as written before eccentric orbits existed
    (docs/conventions.md): phi = 2 pi (t - t0) / P."""
    phi = 2.0 * np.pi * (xp.asarray(t) - xp.asarray(pl.t0)) / xp.asarray(pl.period)
    i = xp.deg2rad(xp.asarray(pl.inc))
    a = xp.asarray(pl.a)
    return a * xp.sin(phi), a * xp.cos(phi) * xp.cos(i), a * xp.cos(phi) * xp.sin(i)


def test_e_zero_is_the_circular_orbit():
    """e = 0 (the default) keeps the circular code path bit for bit (jax and
    numpy); a traced e = 0 (fitted or differentiated) goes through Kepler's
    equation and agrees to 1e-15 relative, for any omega."""
    import jaxppo as jp

    t = np.linspace(-30.0, 1500.0, 20001)
    for kw in (dict(), dict(e=0.0, omega=37.0)):
        pl = jp.Planet(period=3.6961159, t0=134.501962, a=10.6, inc=87.687, radius=0.018, **kw)
        assert pl.circular
        for xp in (jnp, np):
            got = pl.position(t, xp)
            for g, w in zip(got, _old_circular_position(pl, t, xp)):
                assert np.array_equal(np.asarray(g), np.asarray(w))
        assert float(pl.impact) == float(pl.a) * np.cos(np.deg2rad(float(pl.inc)))

    pl = jp.Planet(period=3.6961159, t0=134.501962, a=10.6, inc=87.687, radius=0.018)
    traced = jax.jit(lambda e: pl.replace(e=e).position(t))(0.0)
    want = _old_circular_position(pl, t)
    # phi itself carries ~|phi| eps of rounding (|phi| <= 2600 rad here); the
    # Keplerian path reduces the phase first and is the more accurate one
    for g, w in zip(traced, want):
        assert np.max(np.abs(np.asarray(g) - w)) < 1e-15 * 10.6 * 2600
    near = np.abs(t - 134.5) < 20
    for g, w in zip(traced, want):
        assert np.max(np.abs(np.asarray(g)[near] - w[near])) < 1e-15 * 10.6 * 40


def test_eccentric_position_is_differentiable():
    """Gradients of the eccentric flux in e, omega, t0 and inc are finite and
    equal central differences; at e = 0 the e-gradient is not dropped."""
    import jaxppo as jp

    star = jp.Star.quadratic(0.4, 0.26)
    t = jnp.linspace(-0.12, 0.12, 41)

    def loss(e, omega, t0, inc):
        pl = jp.Planet(period=7.3, t0=t0, a=25.0, inc=inc, radius=0.1, e=e, omega=omega)
        return jnp.sum(jp.System(star, [pl]).flux(t, method="exact"))

    for e in (0.0, 0.3, 0.8):
        args = (e, 60.0, 0.001, 89.6)
        g = jax.grad(loss, argnums=(0, 1, 2, 3))(*args)
        for k, h in enumerate((1e-6, 1e-4, 1e-7, 1e-5)):
            def at(s):
                v = list(args)
                v[k] += s * h
                return float(loss(*v))

            # e >= 0: a one-sided second-order difference at e = 0
            fd = (at(1) - at(-1)) / (2 * h) if (k or e) else (-3 * at(0) + 4 * at(1) - at(2)) / (2 * h)
            assert np.isfinite(float(g[k]))
            assert abs(float(g[k]) - fd) < 1e-5 * max(abs(fd), 1e-3), (e, k, float(g[k]), fd)
    assert abs(float(jax.grad(loss)(0.0, 60.0, 0.001, 89.6))) > 1e-3


def test_planet_eccentricity_input_checks():
    import astropy.units as u
    import pytest

    import jaxppo as jp

    kw = dict(period=5.0, t0=0.0, a=10.0, inc=89.0, radius=0.1)
    for bad in (1.0, -0.1, float("nan"), 1.5):
        with pytest.raises(ValueError, match=r"e \(eccentricity\) must be in \[0, 1\), got"):
            jp.Planet(**kw, e=bad)
    with pytest.raises(ValueError, match=r"periastron at a \(1 - e\) = 0.5 R\* <= 1 \+ radius = 1.1 R\*, so the planet would hit"):
        jp.Planet(**kw, e=0.95)
    with pytest.raises(ValueError, match="omega must be finite"):
        jp.Planet(**kw, e=0.1, omega=float("inf"))
    q = jp.Planet(**kw, e=0.2 * u.dimensionless_unscaled, omega=(30 * u.deg).to(u.rad))
    assert abs(float(q.omega) - 30.0) < 1e-12 and float(q.e) == 0.2
    with pytest.raises(ValueError, match="omega must be an angle"):
        jp.Planet(**kw, e=0.2, omega=3 * u.m)
    assert repr(q) == "Planet(period=5 d, t0=0 d, a=10 R*, inc=89 deg, radius=0.1, e=0.2, omega=30 deg)"
    assert float(q.replace(t0=1.0).e) == 0.2


def test_eccentric_windows_hold_the_transits():
    """Contacts, half_duration and multi_transits windows of eccentric
    planets: batman's light curve (independent) is 1 just outside [t1, t4]
    and below 1 just inside, and the impact parameter is jaxoplanet's sky
    distance at conjunction."""
    import pytest

    import jaxppo as jp

    batman = pytest.importorskip("batman")
    for e, w in ((0.5, 30.0), (0.8, 250.0), (0.6, 90.0), (0.3, 180.0)):
        pl = jp.Planet(period=7.3, t0=0.0, a=25.0, inc=89.3, radius=0.1, e=e, omega=w)
        t1, t4 = (float(v) for v in pl.contacts())
        assert t1 < 0 < t4 and float(pl.half_duration()) == max(-t1, t4)
        pa = batman.TransitParams()
        pa.t0, pa.per, pa.rp, pa.a, pa.inc, pa.ecc, pa.w = 0.0, 7.3, 0.1, 25.0, 89.3, e, w
        pa.u, pa.limb_dark = [0.4, 0.26], "quadratic"
        tt = np.array([t1 - 2e-5, t1 + 2e-5, t4 - 2e-5, t4 + 2e-5])
        f = batman.TransitModel(pa, tt).light_curve(pa)
        assert f[0] == 1 and f[3] == 1 and f[1] < 1 and f[2] < 1, (e, w, f)
        if w == 90.0:  # periastron at transit: far shorter than the circular orbit's
            circ = jp.Planet(period=7.3, t0=0.0, a=25.0, inc=89.3, radius=0.1)
            assert float(pl.half_duration()) < 0.6 * float(circ.half_duration())
    # a pair of eccentric planets: every transit (batman > 0 deficit) lies in a window
    b = jp.Planet(period=7.3, t0=0.0, a=25.0, inc=89.3, radius=0.1, e=0.5, omega=30.0, name="b")
    c = jp.Planet(period=11.1, t0=0.05, a=33.0, inc=89.8, radius=0.05, e=0.7, omega=200.0, name="c")
    sysm = jp.System(jp.Star.quadratic(0.4, 0.26), [b, c])
    wins = jp.model._transits.transit_windows(sysm, range(2), 0.0, 200.0)
    t = np.linspace(0.0, 200.0, 400001)
    x, y, r = (np.asarray(v) for v in sysm.positions(t, xp=np))
    for i in range(2):
        on = (r[:, i] > 0) & (np.hypot(x[:, i], y[:, i]) < 1 + r[:, i])
        covered = np.zeros(t.size, bool)
        for w0, w1, k, _ in wins:
            if k == i:
                covered |= (t >= w0) & (t <= w1)
        assert on.any() and np.all(covered[on])
        # and the windows are tight: each has a sample on the disk within 1e-3 d of its ends
        for w0, w1, k, _ in wins:
            if k == i and 0 < w0 and w1 < 200:
                inside = t[on & (t >= w0) & (t <= w1)]
                assert inside.min() - w0 < 1e-3 and w1 - inside.max() < 1e-3


def test_eccentric_grazing_beyond_b_is_found():
    """An eccentric orbit's sky distance is smallest off conjunction: with
    b = 1 + radius + 1e-6 the planet still grazes the limb (batman shows the
    dip), so it gets contacts and no "never transits" warning; b = 1.3 warns."""
    import warnings

    import pytest

    import jaxppo as jp

    batman = pytest.importorskip("batman")
    e, w, a = 0.5, 30.0, 25.0

    def inc_for(b):
        return float(np.rad2deg(np.arccos(b * (1 + e * np.sin(np.deg2rad(w))) / (a * (1 - e * e)))))

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pl = jp.Planet(period=7.3, t0=0.0, a=a, inc=inc_for(1.1 + 1e-6), radius=0.1, e=e, omega=w)
    t1, t4 = (float(v) for v in pl.contacts())
    assert t1 < t4 < 0  # the whole graze happens before conjunction
    pa = batman.TransitParams()
    pa.t0, pa.per, pa.rp, pa.a, pa.inc, pa.ecc, pa.w = 0.0, 7.3, 0.1, a, float(pl.inc), e, w
    pa.u, pa.limb_dark = [0.4, 0.26], "quadratic"
    f = batman.TransitModel(pa, np.array([0.5 * (t1 + t4), t1 - 1e-4, t4 + 1e-4])).light_curve(pa)
    assert f[0] < 1 and f[1] == 1 and f[2] == 1
    with pytest.warns(UserWarning, match=r"\(1 - e\^2\) / \(1 \+ e sin omega\) = 1.3 >= 1 \+ radius"):
        far = jp.Planet(period=7.3, t0=0.0, a=a, inc=inc_for(1.3), radius=0.1, e=e, omega=w)
    assert float(far.half_duration()) == 0.0


def test_eccentric_hemispheres_and_alpha_limits():
    """Hemisphere cases stay defined from |b| for eccentric planets: i and
    180 - i give identical PPO light curves at any alpha and case, and
    alpha_limits uses the eccentric impact parameter (the limits equal those
    of circular orbits with the same |b| and radii, paper Eqs. 3-6)."""
    import jaxppo as jp

    star = jp.Star.quadratic(0.4, 0.26)
    kw_b = dict(period=7.3, t0=0.0, a=25.0, radius=0.1, e=0.4, omega=60.0, name="b")
    kw_c = dict(period=11.0, t0=0.02, a=32.0, radius=0.06, e=0.2, omega=300.0, name="c")
    t = np.linspace(-0.15, 0.15, 301)
    for inc_b, inc_c in ((89.3, 89.8), (90.7, 89.8), (89.3, 90.2), (90.7, 90.2)):
        sysm = jp.System(star, [jp.Planet(inc=inc_b, **kw_b), jp.Planet(inc=inc_c, **kw_c)])
        f = np.asarray(sysm.flux(t, jnp.asarray([0.0, 10.0, 170.0]), "same"))
        g = np.asarray(sysm.flux(t, jnp.asarray([0.0, 10.0, 170.0]), "opposite"))
        if inc_b == 89.3 and inc_c == 89.8:
            f0, g0 = f, g
            assert np.max(np.abs(f - g)) > 1e-3  # a PPO in one hemisphere case and not the other
        # cos(180 - i) = -cos(i) to rounding only
        assert np.max(np.abs(f - f0)) < 1e-14 and np.max(np.abs(g - g0)) < 1e-14
    b_pl, c_pl = sysm.planets
    circ = jp.System(star, [
        jp.Planet(period=7.3, t0=0.0, a=25.0, radius=0.1, inc=float(np.rad2deg(np.arccos(abs(float(b_pl.impact)) / 25.0)))),
        jp.Planet(period=11.0, t0=0.02, a=32.0, radius=0.06, inc=float(np.rad2deg(np.arccos(abs(float(c_pl.impact)) / 32.0))))])
    assert np.allclose(jp.alpha_limits(sysm), jp.alpha_limits(circ), rtol=0, atol=1e-9)
    ecc_b = 25.0 * np.cos(np.deg2rad(90.7)) * (1 - 0.16) / (1 + 0.4 * np.sin(np.deg2rad(60.0)))
    assert abs(abs(float(b_pl.impact)) - abs(ecc_b)) < 1e-14
