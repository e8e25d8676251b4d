"""Moons (jaxppo.model._moon): positions of a planet with its moons, and
their light curves, against gefera's hierarchical system (Gordon & Agol
2022: one moon, quadratic law), against the independent overlap integral
of tests/helpers.py (two moons, power-2 law), and their derivatives against
central differences.

Mapping to gefera (established here: positions agree to ~1e-14 R*).
gefera's sky frame is Winn's (2010): x = -r cos(w + f), y = -r sin(w + f)
cos i, z = r sin(w + f) sin i, i.e. ours with y -> -y (x and z alike).
Its times ``t`` are times of periastron, not of conjunction; its moon
orbit is the satellite's position relative to the planet reflected through
the planet (gefera stores planet minus moon), which is an argument of
periastron larger by pi; its node ``o`` turns the orbit as our ``lnode``
does once y is flipped. So, with t_peri = t0 - P M_c(e, omega) / (2 pi)
(``conjunction_mean_anomaly``, the mean anomaly at conjunction):

    PrimaryOrbit(a=a, t=t_peri, e=e, p=P, w=omega, i=inc)          [rad]
    SatelliteOrbit(a=a_m, t=t_peri_m, e=e_m, p=P_m, o=lnode,
                   w=omega_m + pi, i=inc_m, m=mass_ratio)           [rad]

and gefera's (x, y, z) = our (x, -y, z) for both bodies. gefera's flux is
its light curve + 1. The flux depends on distances only, so the mirror in
y cannot show there; the positions test sees it. A wrong mapping breaks the
flux comparison by 2e-4 to 1e-3 (checked once: w = omega without + pi,
o = -lnode, mass ratio 0), against a tolerance of 1e-11.
"""

import importlib
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo.core.geometry import conjunction_mean_anomaly
from jaxppo.model._moon import Moon, hierarchical_positions

# Measured on these frames: gefera against our exact engine fed gefera's
# own positions, 2.1e-13 at worst (median 4e-16), and that worst frame (the
# moon crossing the planet's limb near the star's limb) is our default
# order-24 quadrature's error: at order 32 we and gefera both equal the
# independent integral of tests/helpers.py to 2e-16. Our engine's
# documented worst case is ~1e-11 (order 24), gefera's ~1e-12
# (tests/model/test_peers.py); the positions agree to 2e-14 R*.
TOL_GEFERA = 1e-11


def _peer(name):
    """Import a peer code as tests/model/test_peers.py does: required where
    JAXPPO_REQUIRE_PEERS=1 (.ci/run), skipped otherwise when missing."""
    if os.environ.get("JAXPPO_REQUIRE_PEERS") == "1":
        return importlib.import_module(name)
    return pytest.importorskip(name)


def _t_peri(period, t0, e, omega_deg):
    """Time of periastron from a time of conjunction (gefera's ``t``)."""
    return float(t0) - float(period) * float(conjunction_mean_anomaly(float(e), np.deg2rad(float(omega_deg)), np)) / (2 * np.pi)


def _gefera_system(pl, mo):
    _peer("gefera")
    from gefera.orbits import PrimaryOrbit, SatelliteOrbit
    from gefera.systems import HierarchicalSystem

    f = lambda v: float(v)  # noqa: E731
    po = PrimaryOrbit(a=f(pl.a), t=_t_peri(pl.period, pl.t0, pl.e, pl.omega), e=f(pl.e), p=f(pl.period),
                      w=np.deg2rad(f(pl.omega)), i=np.deg2rad(f(pl.inc)))
    so = SatelliteOrbit(a=f(mo.a), t=_t_peri(mo.period, mo.t0, mo.e, mo.omega), e=f(mo.e), p=f(mo.period),
                        o=np.deg2rad(f(mo.lnode)), w=np.deg2rad(f(mo.omega)) + np.pi, i=np.deg2rad(f(mo.inc)),
                        m=f(mo.mass_ratio))
    return HierarchicalSystem(po, so)


def _radii(z, radii):
    return np.where(np.asarray(z) > 0, np.asarray(radii, float), 0.0)


# (planet, moon): an eccentric pair with a small node; a circular moon on a
# retrograde, strongly turned orbit with a heavy moon
GEFERA_CASES = [
    (jp.Planet(period=30.0, t0=0.0, a=50.0, inc=89.7, radius=0.1, e=0.05, omega=70.0),
     Moon(period=1.5, t0=0.02, a=0.3, inc=88.0, radius=0.04, mass_ratio=0.05, lnode=20.0, e=0.1, omega=40.0)),
    (jp.Planet(period=30.0, t0=0.0, a=50.0, inc=89.5, radius=0.1),
     Moon(period=2.0, t0=-0.03, a=0.25, inc=100.0, radius=0.05, mass_ratio=0.3, lnode=130.0)),
]


@pytest.mark.parametrize("case", range(len(GEFERA_CASES)))
def test_against_gefera(case):
    pl, mo = GEFERA_CASES[case]
    star = jp.Star.quadratic(0.4, 0.26)
    t = np.linspace(-0.13, 0.13, 61)
    x, y, z = (np.asarray(v) for v in hierarchical_positions(pl, [mo], t))
    sysg = _gefera_system(pl, mo)
    (xp, yp, zp), (xm, ym, zm) = sysg.coords(t.copy())
    gx, gy, gz = np.stack([xp, xm], -1), -np.stack([yp, ym], -1), np.stack([zp, zm], -1)  # y -> -y
    for ours, theirs in ((x, gx), (y, gy), (z, gz)):
        assert np.max(np.abs(ours - theirs)) < 1e-10
    r = _radii(z, [pl.radius, mo.radius])
    ref = 1.0 + sysg.lightcurve(t.copy(), 0.4, 0.26, float(pl.radius), float(mo.radius))
    flux = np.asarray(jp.occultation_flux(star, x, y, r, method="exact"))
    fed = np.asarray(jp.occultation_flux(star, gx, gy, r, method="exact"))  # gefera's own positions
    assert np.max(np.abs(fed - ref)) < TOL_GEFERA  # gefera's photometric accuracy
    assert np.max(np.abs(flux - ref)) < TOL_GEFERA
    # the frames cover the transit, with the moon crossing the planet's
    # limb on the star, and the moon's disk inside the planet's
    sep = np.hypot(x[:, 1] - x[:, 0], y[:, 1] - y[:, 0])
    on_star = np.hypot(x, y).max(-1) < 1 - 0.1
    rp, rm = float(pl.radius), float(mo.radius)
    assert np.sum(on_star & (sep > rp - rm) & (sep < rp + rm)) >= 4
    assert np.sum(on_star & (sep < rp - rm)) >= 2
    assert ref.min() < 0.99 and ref[0] == 1.0 and ref[-1] == 1.0


def _two_moons():
    pl = jp.Planet(period=20.0, t0=0.0, a=40.0, inc=89.8, radius=0.09, name="b")
    m1 = Moon(period=0.9, t0=0.0, a=0.17, inc=85.0, radius=0.035, mass_ratio=0.02, lnode=10.0, e=0.15, omega=200.0)
    m2 = Moon(period=2.3, t0=0.1, a=0.33, inc=93.0, radius=0.05, mass_ratio=0.04, lnode=-25.0)
    return pl, (m1, m2)


def _overlap_frames(x, y, r, k=4):
    """Indices of up to k frames with every disk on the star and two disks
    crossing, the one with most crossing pairs first."""
    n = x.shape[-1]
    pairs = np.zeros(x.shape[0], int)
    for i in range(n):
        for j in range(i + 1, n):
            d = np.hypot(x[:, i] - x[:, j], y[:, i] - y[:, j])
            pairs += (d < r[:, i] + r[:, j]) & (d > np.abs(r[:, i] - r[:, j]))
    inside = (np.hypot(x, y) + r).max(-1) < 1.0
    idx = np.nonzero(inside & (pairs > 0))[0]
    best = idx[np.argsort(-pairs[idx], kind="stable")]
    return np.unique(np.concatenate([best[:1], idx[np.linspace(0, len(idx) - 1, k - 1).astype(int)]])), pairs


# the reference's total flux: scipy reports roundoff at epsabs 1e-15 near
# the limb, where mu^0.6 has an infinite slope; the 1e-12 agreement holds
@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
def test_two_moons_power2_against_reference_integral():
    from helpers import numpy_intensity, reference_deficit, reference_total

    pl, moons = _two_moons()
    star = jp.Star.power2(0.7, 0.6)
    t = np.linspace(-0.12, 0.12, 241)
    x, y, z = hierarchical_positions(pl, moons, t, xp=np)
    r = _radii(z, [pl.radius] + [m.radius for m in moons])
    idx, pairs = _overlap_frames(x, y, r)
    assert len(idx) >= 3 and pairs[idx].max() >= 2  # a frame where three disks meet
    flux = np.asarray(jp.occultation_flux(star, x[idx], y[idx], r[idx], method="exact"))
    prof = numpy_intensity(star)
    ir = lambda rr: float(prof(np.sqrt(max(1.0 - rr * rr, 0.0))))  # noqa: E731
    f0 = reference_total(ir)
    ref = np.array([1.0 - reference_deficit(ir, x[i], y[i], r[i]) / f0 for i in idx])
    assert np.max(np.abs(flux - ref)) < 1e-12
    # the moons change the light curve: the planet alone differs
    alone = np.asarray(jp.occultation_flux(star, x[idx, :1], y[idx, :1], r[idx, :1], method="exact"))
    assert np.min(np.abs(alone - flux)) > 1e-5


def test_hierarchical_barycentre_and_batching():
    """The barycentre follows the planet's orbit; jit and vmap give the
    eager numbers; numpy and jax agree."""
    pl, moons = _two_moons()
    t = np.linspace(-0.2, 0.2, 9)
    x, y, z = jax.jit(lambda p, ms: hierarchical_positions(p, ms, t))(pl, moons)
    q = np.array([1.0] + [float(m.mass_ratio) for m in moons])
    bary = np.asarray(pl.position(t))
    for c, v in enumerate((x, y, z)):
        assert np.allclose(np.asarray(v) @ q / q.sum(), bary[c], atol=1e-13, rtol=0)
    xn = hierarchical_positions(pl, moons, t, xp=np)[0]
    assert np.allclose(xn, x, atol=1e-13, rtol=0)
    xe = hierarchical_positions(pl, moons[1:], t)[0]  # eager (jax), one moon
    assert np.allclose(xe, hierarchical_positions(pl, moons[1:], t, xp=np)[0], atol=1e-13, rtol=0)
    batch = jax.tree_util.tree_map(lambda v: jnp.stack([v, v]), moons[0])
    batch = eqx_replace(batch, a=jnp.array([0.17, 0.2]))
    xv = jax.jit(jax.vmap(lambda m: hierarchical_positions(pl, [m, moons[1]], t)[0]))(batch)
    assert np.allclose(xv[0], x, atol=1e-13, rtol=0) and not np.allclose(xv[1], x)
    # traced out-of-domain parameters give NaN (the constructor refuses them)
    bad = jax.jit(lambda e: hierarchical_positions(pl, [eqx_replace(moons[0], e=e)], t)[0])(1.2)
    assert np.all(np.isnan(bad))
    hit = jax.jit(lambda a: hierarchical_positions(pl, [eqx_replace(moons[0], a=a)], t)[0])(0.1)
    assert np.all(np.isnan(hit))  # periapsis inside planet + moon radii


def eqx_replace(module, **changes):
    import equinox as eqx

    names = list(changes)
    return eqx.tree_at(lambda m: [getattr(m, k) for k in names], module, [jnp.asarray(changes[k], float) for k in names])


ELEMENTS = ("period", "t0", "a", "inc", "radius", "mass_ratio", "lnode", "e", "omega")
STEPS = {"period": 1e-5, "t0": 1e-5, "a": 1e-5, "inc": 1e-3, "radius": 1e-5, "mass_ratio": 1e-5,
         "lnode": 1e-3, "e": 1e-5, "omega": 1e-3}


@pytest.mark.parametrize("ecc", [0.0, 0.1])
def test_gradients_match_central_differences(ecc):
    pl, mo = GEFERA_CASES[0]
    mo = eqx_replace(mo, e=ecc)
    star = jp.Star.quadratic(0.4, 0.26)
    t = jnp.linspace(-0.07, 0.07, 8)  # moon and planet overlapping on the star

    def total(m):
        x, y, z = hierarchical_positions(pl, [m], t)
        r = jnp.where(z > 0, jnp.stack([pl.radius, m.radius]), 0.0)
        return jnp.sum(jp.occultation_flux(star, x, y, r, method="exact"))

    f = jax.jit(total)
    grad = jax.jit(jax.grad(total))(mo)
    for k in ELEMENTS:
        g, h, v = float(getattr(grad, k)), STEPS[k], float(getattr(mo, k))
        assert np.isfinite(g), k
        if k == "e" and ecc == 0.0:  # e >= 0: a one-sided second-order difference
            fd = (-3 * f(mo) + 4 * f(eqx_replace(mo, e=h)) - f(eqx_replace(mo, e=2 * h))) / (2 * h)
        else:
            fd = (f(eqx_replace(mo, **{k: v + h})) - f(eqx_replace(mo, **{k: v - h}))) / (2 * h)
        # measured: within 8e-9 (the differences' truncation), 5e-13 for
        # the small lnode and inc terms
        assert abs(g - float(fd)) <= 1e-5 * abs(g) + 1e-9, (k, g, float(fd))
    # the elements matter: the light curve moves with the moon
    assert abs(float(grad.t0)) > 1e-3 and abs(float(grad.a)) > 1e-3


def test_system_with_moons_disks_tilt_cases_and_refusals():
    """A System whose planets have moons: the planets' disks first (each at its recoiled position), then the
    moons' in planet order, equal to hierarchical_positions; a tilt turns the tilted planet's whole group
    about the line of sight and a mirrored hemisphere case mirrors an untilted group (y -> -y); a moon
    behind the star has r = 0; Planet(moons=...) refuses what is not a Moon and a moon inside its planet."""
    m1 = Moon(period=1.3, t0=0.2, a=0.3, inc=87.0, radius=0.03, mass_ratio=0.04, lnode=10.0)
    m2 = Moon(period=2.9, t0=-0.4, a=0.55, inc=92.0, radius=0.02, mass_ratio=0.01, e=0.1, omega=40.0)
    b = jp.Planet(period=40.0, t0=0.0, a=60.0, inc=89.8, radius=0.09, name="b", moons=[m1, m2])
    c = jp.Planet(period=90.0, t0=0.05, a=100.0, inc=89.9, radius=0.05, name="c", moons=[m1])
    system = jp.System(jp.Star.quadratic(0.4, 0.25), [b, c])
    t = np.array([-0.2, 0.0, 0.1, 20.0])
    x, y, r = system.positions(t, xp=np)
    assert x.shape == (4, 5)
    for pl, cols in ((b, [0, 2, 3]), (c, [1, 4])):
        hx, hy, hz = (np.asarray(v) for v in hierarchical_positions(pl, pl.moons, t))
        np.testing.assert_allclose(x[:, cols], hx, rtol=0, atol=1e-12)
        np.testing.assert_allclose(y[:, cols], hy, rtol=0, atol=1e-12)
        radii = np.array([pl.radius] + [m.radius for m in pl.moons], float)
        np.testing.assert_array_equal(r[:, cols], np.where(hz > 0, radii, 0.0))
    assert np.all(r[3, [0, 2, 3]] == 0.0)  # b, half its orbit later: its group behind the star
    xa, ya, _ = system.positions(t, alpha=30.0, case="opposite", xp=np)
    ca, sa = np.cos(np.deg2rad(30.0)), np.sin(np.deg2rad(30.0))
    np.testing.assert_allclose(xa[:, [0, 2, 3]], x[:, [0, 2, 3]] * ca + y[:, [0, 2, 3]] * sa, atol=1e-12)
    np.testing.assert_allclose(ya[:, [0, 2, 3]], -x[:, [0, 2, 3]] * sa + y[:, [0, 2, 3]] * ca, atol=1e-12)
    np.testing.assert_allclose(xa[:, [1, 4]], x[:, [1, 4]], atol=1e-12)
    np.testing.assert_allclose(ya[:, [1, 4]], -y[:, [1, 4]], atol=1e-12)
    f = np.asarray(system.flux(t))
    f_ref = np.asarray(jp.occultation_flux(system.star, x, y, r, method="exact"))
    np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13)
    with pytest.raises(ValueError, match="must be a Moon"):
        jp.Planet(period=40.0, t0=0.0, a=60.0, inc=89.8, radius=0.09, moons=[b])
    with pytest.raises(ValueError, match=r"^moons\[0\]: periapsis .* would hit its planet"):
        jp.Planet(period=40.0, t0=0.0, a=60.0, inc=89.8, radius=0.09,
                  moons=[Moon(period=1.0, t0=0.0, a=0.1, inc=90.0, radius=0.02)])
    # multi-transit windows are the planets' contacts: a moon's events would be missed (a review found
    # a moon on the star with planet c listed as no event at all), so a system with moons is refused
    with pytest.raises(ValueError, match="do not follow moons"):
        jp.multi_transits(system, 0.0, 100.0)
    with pytest.raises(ValueError, match="do not follow moons"):
        jp.multi_transit_counts(system, np.linspace(0.0, 100.0, 50))
    # an unnamed moon's errors say it is a moon's parameter
    with pytest.raises(ValueError, match="^moon: mass_ratio must be finite and >= 0, got -0.1"):
        Moon(period=1.0, t0=0.0, a=0.5, inc=90.0, radius=0.02, mass_ratio=-0.1)
    with pytest.raises(ValueError, match="^planet 'b': mass must be a number, got None"):
        jp.Planet(period=40.0, t0=0.0, a=60.0, inc=89.8, radius=0.09, name="b", mass=None)


def test_no_never_transits_warning_when_a_moon_can_transit():
    """A planet at |b| = 1.26 whose moon (a = 0.5 R*) crosses the star warned
    "never transits"; without the moon (or with the moon out of reach) it
    still warns."""
    import warnings

    moon = jp.Moon(period=1.2, t0=0.0, a=0.5, inc=90.0, radius=0.02, name="I")
    for moons, warns in (([moon], False), ([], True)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            jp.Planet(period=40.0, t0=0.0, a=60.0, inc=88.8, radius=0.05, moons=moons, name="b")
        assert any("never transits" in str(w.message) for w in caught) == warns, moons
    with pytest.warns(UserWarning, match="never transits"):  # |b| = 1.57: the moon cannot reach the star either
        jp.Planet(period=40.0, t0=0.0, a=60.0, inc=88.5, radius=0.05, moons=[moon], name="b")


def test_a_moon_outside_its_planets_hill_sphere_or_heavier_than_it_warns():
    """Found by a review, accepted silently before: a moon at a = 500 R* about a planet at 60 R*, a moon
    50 times heavier than its planet, a moon outside the planet's Hill sphere. A Keplerian planet has no
    mass: the moon's own a and period give it (Kepler's third law), so for circular orbits the Hill test
    is P_moon > P / sqrt(3) = 23.1 d here; an N-body planet's mass gives it directly. Each warns (a
    UserWarning: the model is still defined); the moons of the other tests do not."""
    import warnings

    def system(**kw):
        moon = jp.Moon(**{**dict(period=1.2, t0=0.15, a=0.35, inc=88.0, radius=0.04, mass_ratio=0.05, name="I"),
                          **kw})
        return jp.System(jp.Star.quadratic(0.4, 0.25),
                         [jp.Planet(period=40.0, t0=0.0, a=60.0, inc=89.9, radius=0.09, moons=[moon], name="b")])

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        system()
        system(period=20.0)  # inside: 20 d < 23.1 d
    with pytest.warns(UserWarning, match=r"moon 'I' of planet 'b': its orbit reaches 500 R\* .*outside the planet's "
                                         r"Hill sphere \(41\.6 R\*"):
        system(a=500.0)
    with pytest.warns(UserWarning, match=r"outside the planet's Hill sphere \(0\.294 R\*"):
        system(period=30.0)
    with pytest.warns(UserWarning, match=r"mass_ratio = 50\.0 makes the moon heavier than its planet"):
        system(mass_ratio=50.0)
    if importlib.util.find_spec("jnkepler") is not None:  # N-body: r_H = 19.5 R* (3.7e-5 / 3)^(1/3) = 0.451 R*
        def nbody(a):
            moon = jp.Moon(period=1.2, t0=0.1, a=a, inc=88.0, radius=0.03, mass_ratio=0.02, name="I")
            planet = jp.Planet(period=10.0, t0=101.0, a=None, inc=89.5, radius=0.05, mass=3.7e-5, name="b",
                               moons=[moon])
            return jp.System(jp.Star.uniform(), [planet], orbits="nbody", epoch=100.0, star_mass=1.0,
                             star_radius=1.0)

        with warnings.catch_warnings():
            warnings.simplefilter("error")
            nbody(0.3)
        with pytest.warns(UserWarning, match=r"Hill sphere \(0\.451\d R\* .*mass ratio 3\.7e-05 \(its mass"):
            nbody(0.6)
