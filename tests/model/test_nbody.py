"""N-body orbits (``jaxppo.model._nbody``, ``System(orbits="nbody")``; the
orbits integrated by jnkepler): the Keplerian limit against Keplerian
Systems, Kepler-51's transit times, positions and a double-transit light
curve against REBOUND, jit and gradients.

The REBOUND reference is stored, not run here (REBOUND is no dependency of
jaxppo's tests): ``tests/data/kepler51_rebound_transits.csv`` (every
mid-transit of Kepler-51 b, c, d from BKJD 155 to 1600, the Kepler
baseline), ``tests/data/kepler51_rebound_positions.csv`` (astrocentric
positions [au] in REBOUND's frame at 170 times: random over the baseline,
10 before the epoch of the elements, and 60 off mid-transit) and
``tests/data/kepler51_rebound_double_transit.csv`` (positions across the
b + d double transit near BKJD 1513.7, inclinations 89.8, 89.5, 89.95 deg
so that b and d overlap on the star), all from
REBOUND 5.2.2's IAS15 with the elements below, written by
``python benchmarks/nbody_vs_rebound.py --write-csv``.

Measured (jnkepler 0.2.9, default dt = P_b / 40 = 1.13 d): transit times
within 0.0004 min (0.03 s) of REBOUND's, positions within 3.6e-6 R*; the
Keplerian limit within 3.6e-6 R* over 600 d at masses 1e-10 M_sun (the
osculating periods are not the mean ones, a drift proportional to the
masses) and 3e-10 R* at 1e-14 M_sun.
"""

import importlib.util
import os
import subprocess
import sys
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

if importlib.util.find_spec("jnkepler") is None:
    # CI installs the nbody extra and sets JAXPPO_REQUIRE_NBODY=1: there a
    # missing jnkepler fails instead of skipping these comparisons
    if os.environ.get("JAXPPO_REQUIRE_NBODY") == "1":
        raise ImportError("jnkepler is required here (JAXPPO_REQUIRE_NBODY=1): pip install 'jaxppo[nbody]'")
    pytest.skip("jnkepler is not installed (pip install 'jaxppo[nbody]')", allow_module_level=True)

import jaxppo as jp  # noqa: E402
from jaxppo.model._nbody import R_SUN_AU, nbody_positions, nbody_xyz, semi_major_axis  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "data"

# Kepler-51 b, c, d: osculating Jacobi elements at BKJD 155 from Masuda's jnkepler example
# (kep51_dt1.0_start155.00_end2950.00_pdict.csv; masses are planet / star mass ratios, star 1 M_sun)
K51_PERIOD = np.array([45.15410798392322, 85.31448324119035, 130.18413706111033])
K51_ECOSW = np.array([-0.017185959106750172, 0.018881511466098927, 0.011665980547369371])
K51_ESINW = np.array([-0.04069871999841418, -0.034823941422281166, -0.028107346169576518])
K51_TIC = np.array([159.11026537277118, 295.32101703450786, 212.0234348357531])
K51_MASS = np.array([9.914288803950785e-06, 1.2239239443515162e-05, 1.5982929660558063e-05])
K51 = dict(periods=K51_PERIOD, eccs=np.hypot(K51_ECOSW, K51_ESINW),
           omegas=np.rad2deg(np.arctan2(K51_ESINW, K51_ECOSW)), incs=np.full(3, 90.0), lnodes=np.zeros(3),
           tics=K51_TIC, masses=K51_MASS, star_mass=1.0, star_radius=0.881, epoch=155.0)
NAMES = ("b", "c", "d")


def _read(name):
    return np.genfromtxt(DATA / name, delimiter=",", names=True, dtype=None, encoding="utf-8")


def _kepler51_system(incs=(90.0, 90.0, 90.0), radii=(0.07, 0.06, 0.1), **kw):
    """Kepler-51 b, c, d as an N-body jp.System (the elements above)."""
    planets = [jp.Planet(period=K51_PERIOD[j], t0=K51_TIC[j], a=None, inc=incs[j], radius=radii[j], e=K51["eccs"][j],
                         omega=K51["omegas"][j], mass=K51_MASS[j], name=NAMES[j]) for j in range(3)]
    return jp.System(jp.Star.quadratic(0.42, 0.16), planets, orbits="nbody", epoch=K51["epoch"],
                     star_mass=K51["star_mass"], star_radius=K51["star_radius"], **kw)


def test_kepler51_transit_times_match_rebound():
    """System(orbits="nbody").transit_times: every Kepler-51 transit over the Kepler baseline (60, the same
    planets and epochs) within 0.005 min of REBOUND's IAS15 (measured: 0.0004 min), found from the osculating
    ephemeris t0 + n P, which is up to hours off (the TTVs)."""
    ref = _read("kepler51_rebound_transits.csv")
    table = _kepler51_system().transit_times(155.0, 1600.0)
    got = {(str(r["planet"]), int(r["epoch"])): float(r["tc"]) for r in table}
    assert sorted(got) == sorted((str(p), int(e)) for p, e in zip(ref["planet"], ref["epoch"]))
    err = np.array([abs(got[(str(p), int(e))] - tc) for p, e, tc in zip(ref["planet"], ref["epoch"], ref["tc"])])
    for name in NAMES:
        worst = 1440 * err[ref["planet"] == name].max()
        assert worst < 0.005, f"Kepler-51 {name}: {worst:.4f} min from REBOUND"
    planet = np.array([NAMES.index(p) for p in ref["planet"]])
    guess = K51_TIC[planet] + ref["epoch"] * K51_PERIOD[planet]
    assert 1440 * np.abs(guess - ref["tc"]).max() > 30  # the guesses were far off: the TTVs are real


def test_kepler51_double_transit_light_curve_matches_rebound():
    """The light curve across the b + d double transit near BKJD 1513.7, where b and d overlap on the star:
    System(orbits="nbody").flux against REBOUND's positions fed to the exact engine, within 1e-7 (measured
    7e-9; the positions agree to 3e-7 R*). The overlap is real: the sum of single-planet deficits (what
    jnkepler, photodynam and Photodynamics.jl compute) is off by more than 1e-4 there (measured 1.9e-3)."""
    ref = _read("kepler51_rebound_double_transit.csv")
    t = ref["t"][::3]
    xyz = np.stack([ref["x"], ref["y"], ref["z"]], -1).reshape(len(t), 3, 3) / (K51["star_radius"] * R_SUN_AU)
    system = _kepler51_system(incs=(89.8, 89.5, 89.95))
    radii = np.array([pl.radius for pl in system.planets], float)
    r_ref = np.where(xyz[..., 2] > 0, radii, 0.0)
    f_ref = np.asarray(jp.occultation_flux(system.star, -xyz[..., 0], xyz[..., 1], r_ref, method="exact"))
    f = np.asarray(system.flux(t))
    assert np.abs(f - f_ref).max() < 1e-7, np.abs(f - f_ref).max()
    x, y, r = system.positions(t, xp=np)
    singles = sum(np.asarray(jp.occultation_flux(system.star, x[:, [j]], y[:, [j]], r[:, [j]], method="exact")) - 1.0
                  for j in range(3))
    assert np.abs(1.0 + singles - f).max() > 1e-4
    assert f.min() < 0.985  # both planets on the star


def test_system_keplerian_limit_node_tilt_and_cases():
    """An N-body System with negligible masses is the Keplerian System of the same elements (a from Kepler's
    third law; each planet's lnode turns its orbit like a tilt); alpha adds to the tilted planet's node, and
    the "opposite" case mirrors the untilted planets (i -> 180 - i)."""
    t = np.linspace(150.0, 700.0, 2001)
    light = _kepler51_system(incs=(89.6, 89.7, 89.8)).replace(
        planets=[pl.replace(mass=1e-15, lnode=node) for pl, node in zip(_kepler51_system().planets, (0.0, 3.0, -5.0))])
    light = light.replace(planets=[pl.replace(inc=i) for pl, i in zip(light.planets, (89.6, 89.7, 89.8))])
    a = np.asarray(semi_major_axis(K51_PERIOD, K51["star_mass"], K51["star_radius"]))
    kepler = jp.System(light.star, [pl.replace(mass=0.0, a=a[j]) for j, pl in enumerate(light.planets)])
    for alpha, case in ((0.0, "same"), (25.0, "same"), (25.0, "opposite")):
        xn, yn, rn = light.positions(t, alpha, case, xp=np)
        xk, yk, rk = kepler.positions(t, alpha, case, xp=np)
        assert np.hypot(xn - xk, yn - yk).max() < 1e-6, (alpha, case)
        np.testing.assert_array_equal(rn, rk)
    f = np.asarray(light.flux(t[:50], alpha=np.array([0.0, 25.0])))
    np.testing.assert_allclose(f[1], np.asarray(light.flux(t[:50], alpha=25.0)), rtol=0, atol=1e-12)


def test_system_nbody_bad_inputs():
    """Missing or out-of-range N-body keywords, N-body keywords without orbits="nbody", planets out of
    period order, listed transit times, an a that contradicts Kepler's third law, traced times without a
    span, and a Keplerian planet without a: each a ValueError naming the problem."""
    pl = _kepler51_system().planets
    star = jp.Star.uniform()
    ok = dict(orbits="nbody", epoch=155.0, star_mass=1.0, star_radius=0.9)
    with pytest.raises(ValueError, match="needs star_mass"):
        jp.System(star, pl, orbits="nbody", epoch=155.0, star_radius=0.9)
    with pytest.raises(ValueError, match="star_radius must be a finite number > 0"):
        jp.System(star, pl, **{**ok, "star_radius": -1.0})
    with pytest.raises(ValueError, match="apply to N-body orbits only"):
        jp.System(star, pl, star_mass=1.0)
    with pytest.raises(ValueError, match="orbits must be"):
        jp.System(star, pl, orbits="rebound")
    with pytest.raises(ValueError, match="periods must increase"):
        jp.System(star, pl[::-1], **ok)
    with pytest.raises(ValueError, match="drop transit_times"):
        jp.System(star, [pl[0].replace(transit_times=[159.1], transit_epochs=[0])], **ok)
    with pytest.raises(ValueError, match="disagrees with Kepler's third law"):
        jp.System(star, [pl[0].replace(a=40.0)], **ok)
    with pytest.raises(ValueError, match="no a"):
        jp.System(star, [pl[0].replace(a=None)])
    with pytest.raises(ValueError, match="span"):
        jax.jit(lambda t: jp.System(star, pl, **ok).flux(t))(jnp.array([200.0]))
    inside = jax.jit(lambda t: jp.System(star, pl, **ok, span=(150.0, 250.0)).flux(t))(jnp.array([159.1102]))
    assert float(inside[0]) < 0.999


def test_an_epoch_on_another_time_scale_than_t0_warns():
    """Kepler-51 with its epoch typed in BJD (2455155) beside t0 in BKJD:
    the elements were integrated over 6,700 years and the transit times came
    out 6 to 43 days off, without a word (the bundled N-body config's
    planets). Now the System warns, naming the planets and how many orbits
    separate t0 from the epoch; epoch 155 (BKJD) and a t0 82 orbits from it
    (a TESS-era transit) stay silent."""
    pl = _kepler51_system().planets
    star = jp.Star.uniform()
    ok = dict(orbits="nbody", star_mass=1.0, star_radius=0.881)
    with pytest.warns(UserWarning, match=r"N-body planets b \(t0 = 159\.11 d, 5\.4\de\+04 orbits\), c .*, d .*one time "
                                         r"scale \(BJD = BKJD \+ 2454833"):
        jp.System(star, pl, epoch=2455155.0, **ok)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        jp.System(star, pl, epoch=155.0, **ok)
        jp.System(star, [pl[0].replace(t0=float(K51_TIC[0]) + 82 * float(K51_PERIOD[0]))], epoch=155.0, **ok)


def test_derived_orbits_get_the_checks_of_a_keplerian_planet():
    """An N-body planet's a comes from Kepler's third law, after Planet's
    checks ran on a = None: a periastron inside the star (P = 1 d, e = 0.9:
    0.42 R*), a star_radius in km or a star_mass in kg (a = 2.8e-5 R* or
    2.5e11 R*) gave a normal-looking light curve, or none, without a word.
    Now the same refusal as for a Keplerian planet, a refusal of star sizes
    no star has, and the "never transits" warning on the osculating orbit."""
    star = jp.Star.uniform()
    ok = dict(orbits="nbody", epoch=0.0, star_mass=1.0, star_radius=1.0)

    def planet(**kw):
        return jp.Planet(**{**dict(period=10.0, t0=0.0, a=None, inc=90.0, radius=0.05, mass=3e-6, name="b"), **kw})

    with pytest.raises(ValueError, match="planet 'b'.*periastron at a \\(1 - e\\) = 0.42.*would hit the star"):
        jp.System(star, [planet(period=1.0, e=0.9)], **ok)
    with pytest.raises(ValueError, match="a = 0.57.*would hit the star"):
        jp.System(star, [planet(period=0.05)], **ok)
    with pytest.raises(ValueError, match="star_radius = 695700 R_sun is outside"):
        jp.System(star, [planet()], **{**ok, "star_radius": 695700.0})
    with pytest.raises(ValueError, match="star_mass = 1.989e\\+30 M_sun is outside"):
        jp.System(star, [planet()], **{**ok, "star_mass": 1.989e30})
    with pytest.warns(UserWarning, match="planet 'b' \\(its osculating orbit at epoch 0.*never transits"):
        jp.System(star, [planet(inc=80.0)], **ok)  # a = 19.5 R*, b = 3.4: no planet transits
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        jp.System(star, [planet(inc=89.0)], **ok)  # b = 0.34: transits, no warning
        # a perturber that does not transit beside one that does (Kepler-88 c): no warning
        jp.System(star, [planet(inc=89.0), planet(name="c", period=20.0, inc=80.0)], **ok)
        # a white dwarf (0.013 R_sun) and a brown dwarf host are stars
        jp.System(star, [planet(period=3.0)], **{**ok, "star_mass": 0.6, "star_radius": 0.013})


def test_kepler51_positions_match_rebound():
    """Positions at 170 times (random, before the epoch, off mid-transit) within 2e-5 R* of REBOUND's
    (measured: 3.6e-6 R*); r is the planet's radius exactly where REBOUND has it in front (z > 0)."""
    ref = _read("kepler51_rebound_positions.csv")
    t = ref["t"][::3]
    xyz = np.stack([ref["x"], ref["y"], ref["z"]], -1).reshape(len(t), 3, 3) / (K51["star_radius"] * R_SUN_AU)
    assert np.all(ref["planet"].reshape(len(t), 3) == np.array(NAMES))
    radii = np.array([0.07, 0.08, 0.09])
    x, y, r = nbody_positions(t, radii=radii, **K51)
    _, _, z = nbody_xyz(t, **K51)
    err = np.sqrt((np.asarray(x) + xyz[..., 0])**2 + (np.asarray(y) - xyz[..., 1])**2
                  + (np.asarray(z) - xyz[..., 2])**2)
    assert err.max() < 2e-5, f"{err.max():.2e} R* from REBOUND"
    assert (t < K51["epoch"]).sum() == 10 and err[t < K51["epoch"]].max() < 2e-5
    np.testing.assert_array_equal(np.asarray(r), np.where(xyz[..., 2] > 0, radii, 0.0))
    near = (np.abs(np.asarray(x)) < 1.5) & (xyz[..., 2] > 0)  # on or next to the disk, off mid-transit
    assert near.sum() >= 30 and np.all(np.abs(np.asarray(x)[near]) > 0.1)


def test_jit_and_derivative_finite_and_match_finite_differences():
    """Under jax.jit with traced times (t_range), masses and elements: the derivative of a loss on the
    positions along a direction that moves every mass and element (forward mode, jax.jvp) is finite and
    equals central differences along it.

    Reverse mode (jax.grad, what NUTS uses) gives the same numbers; its XLA compilation takes 20-35 s on a
    2-core CPU (as for jnkepler's own gradients), too long for this suite: benchmarks/nbody_vs_rebound.py
    runs jax.grad with respect to every mass and element and prints its agreement with jax.jacfwd."""
    t = _read("kepler51_rebound_positions.csv")["t"][::3]
    span = (float(t.min()), float(t.max()))
    names = ("masses", "periods", "eccs", "omegas", "incs", "lnodes", "tics")

    def loss(t, *values):
        # traced periods: dt given (the default's value, P_b / 40)
        x, y, _ = nbody_xyz(t, t_range=span, dt=float(np.min(K51_PERIOD)) / 40, **{**K51, **dict(zip(names, values))})
        return jnp.sum(x * jnp.sin(t)[:, None]) + jnp.sum(y)

    values = tuple(jnp.asarray(K51[n], float) for n in names)
    values = values[:4] + (jnp.array([89.9, 89.8, 90.1]), jnp.array([0.0, 1.0, -2.0])) + values[6:]
    # a step of each: 1 % of the masses, 1e-6 d, 1e-4, 1e-3 deg (omega, i, Omega), 1e-5 d
    steps = (0.01 * K51_MASS, 1e-6, 1e-4, 1e-3, 1e-3, 1e-3, 1e-5)
    direction = tuple(s * jnp.array([1.0, -0.7, 0.4]) for s in steps)
    _, deriv = jax.jit(lambda t, *v: jax.jvp(lambda *v: loss(t, *v), v, direction))(t, *values)
    assert np.isfinite(float(deriv)) and float(deriv) != 0.0
    up = loss(t, *(v + d for v, d in zip(values, direction)))
    down = loss(t, *(v - d for v, d in zip(values, direction)))
    fd = float(up - down) / 2
    assert abs(float(deriv) - fd) < 1e-4 * abs(fd), (float(deriv), fd)


def test_float64_setting_kept():
    """jnkepler turns float64 on when imported; jaxppo puts the user's setting back (a fresh process)."""
    code = ("import jax; jax.config.update('jax_enable_x64', False); "
            "from jaxppo.model._nbody import _jnkepler; _jnkepler(); print(jax.config.jax_enable_x64)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr


def test_bad_inputs():
    """Traced times need t_range; element arrays of different lengths and a step <= 0 are refused."""
    kw = {**K51, "radii": np.full(3, 0.05)}
    with pytest.raises(ValueError, match="t_range"):
        jax.jit(lambda t: nbody_positions(t, dt=1.0, **kw))(jnp.array([200.0]))
    with pytest.raises(ValueError, match="1D of one length"):
        nbody_positions([200.0], **{**kw, "tics": K51_TIC[:2]})
    with pytest.raises(ValueError, match="dt must be > 0"):
        nbody_positions([200.0], dt=0.0, **kw)


def test_workflows_that_assume_keplerian_planets_refuse_nbody_and_moons():
    """The obliquity scan, the marginal scan, alpha_limits, ppo_or_spot and measure_transit_times take
    windows, masks or angle limits from Keplerian ephemerides: given an N-body system or planets with moons
    they refuse by name instead of using a linear ephemeris or leaving a moon out; in_transit_mask of an
    N-body system follows the integrated transit times (Kepler-51 b's TTVs move its transits by up to 20 min,
    a linear ephemeris would put the mask's edges off)."""
    from jaxppo.model._overlap import in_transit_mask

    nbody = _kepler51_system()
    moon = jp.Moon(period=1.0, t0=0.0, a=0.3, inc=90.0, radius=0.02)
    with_moon = jp.System(jp.Star.uniform(), [jp.Planet(period=10.0, t0=0.0, a=20.0, inc=90.0, radius=0.05,
                                                        moons=[moon]), jp.Planet(period=21.0, t0=3.0, a=33.0,
                                                                                 inc=90.0, radius=0.05)])
    lc = jp.LightCurve(np.linspace(0.0, 1.0, 10), np.ones(10), np.full(10, 1e-3))
    for system in (nbody, with_moon):
        for call in (lambda: jp.scan(system, lc), lambda: jp.marginal_scan(system, lc),
                     lambda: jp.alpha_limits(system), lambda: jp.measure_transit_times(system, lc),
                     lambda: jp.activity.ppo_or_spot(None, system)):
            with pytest.raises(ValueError, match="Keplerian orbits|moons"):
                call()
    ref = _read("kepler51_rebound_transits.csv")
    tc, others = ref["tc"][ref["planet"] == "b"], ref["tc"][ref["planet"] != "b"]
    t1, t4 = (float(v) for v in nbody.planets[0].contacts())  # b's osculating contacts about mid-transit
    inside = np.concatenate([tc + t1 + 0.003, tc + t4 - 0.003])  # 4 min inside first / last contact
    outside = np.concatenate([tc + t1 - 0.003, tc + t4 + 0.003])
    outside = outside[np.abs(outside[:, None] - others).min(1) > 0.5]  # not in a transit of c or d
    mask = in_transit_mask(nbody, np.concatenate([inside, outside]))
    assert mask[:inside.size].all() and not mask[inside.size:].any()
    linear = in_transit_mask(jp.System(nbody.star, [nbody.planets[0]]), np.concatenate([inside, outside]))
    assert not (linear[:inside.size].all() and not linear[inside.size:].any())  # what the TTVs change


def test_transit_times_of_strongly_interacting_planets_match_rebound():
    """Two Jupiter-mass planets near 2:1 whose transits wander +-5 d from a linear ephemeris on a 10-d period
    (tests/data/strong_ttv_rebound_transits.csv, REBOUND IAS15, written by benchmarks/nbody_vs_rebound.py):
    every one of REBOUND's 224 transits from 100 to 1600 d is found once, within 0.1 min, numbered
    consecutively, at the default step (the masses shorten it: 0.073 d, 2.9 s measured; 0.023 min at
    dt = 0.05 d). The default step that ignored the masses, P (1 - e)^1.5 / 40 = 0.23 d, was off by about
    half a minute (34 s at 0.25 d)."""
    ref = _read("strong_ttv_rebound_transits.csv")
    planets = [jp.Planet(period=p, t0=t0, a=None, inc=i, e=0.05, omega=w, mass=1e-3, radius=0.08, name=n)
               for p, t0, i, w, n in ((10.0, 101.0, 89.7, 40.0, "p0"), (20.3, 107.0, 89.8, -70.0, "p1"))]
    system = jp.System(jp.Star.uniform(), planets, orbits="nbody", epoch=100.0, star_mass=1.0, star_radius=1.0)
    assert system.dt == pytest.approx(10.0 * 0.95**1.5 / 40.0 * np.sqrt(1e-4 / 1e-3), rel=1e-12)
    table = system.transit_times(100.0, 1600.0)
    assert len(table) == len(ref) == 224
    for name in ("p0", "p1"):
        got, want = table[table["planet"] == name], ref[ref["planet"] == name]
        np.testing.assert_array_equal(np.asarray(got["epoch"]), np.arange(len(got)))
        assert 1440 * np.abs(np.asarray(got["tc"]) - np.sort(want["tc"])).max() < 0.1
    guess = 101.0 + 10.0 * np.arange(151)
    assert np.abs(np.sort(ref["tc"][ref["planet"] == "p0"]) - guess).max() > 4.0  # the TTVs are large


def test_span_replace_save_load_and_refusals_from_review():
    """Found by a review, each a wrong number before: an N-body planet of mass 0 (NaN positions) is refused;
    concrete times beyond ``span`` extend the grid and traced ones get NaN (not a long read-out step's
    error); System.replace re-derives a (star mass changed) and a default dt for new planets; save/load
    keeps the N-body settings and the moons; repeated moon names and alpha_limits with a nonzero node are
    refused."""
    from jaxppo.inference._serialise import system_from_dict, system_to_dict

    star = jp.Star.quadratic(0.4, 0.2)
    pls = [jp.Planet(period=10.0, t0=101.0, a=None, inc=89.5, radius=0.05, mass=3.7e-5, name="b"),
           jp.Planet(period=21.0, t0=101.02, a=None, inc=89.6, radius=0.07, mass=3e-5, name="c", lnode=2.0)]
    with pytest.raises(ValueError, match="needs mass > 0"):
        jp.System(star, [pls[0].replace(mass=0.0)], orbits="nbody", epoch=100.0, star_mass=1.0, star_radius=1.0)
    s = jp.System(star, pls, orbits="nbody", epoch=100.0, star_mass=1.0, star_radius=1.0, span=(99.0, 161.0))
    far = np.linspace(600.5, 601.5, 200)
    np.testing.assert_allclose(np.asarray(s.flux(far)), np.asarray(s.replace(span=None).flux(far)), atol=1e-11)
    assert np.asarray(s.flux(far)).min() < 0.998  # a transit there
    assert np.isnan(np.asarray(jax.jit(lambda tt: s.flux(tt))(far))).all()
    assert np.isfinite(np.asarray(jax.jit(lambda tt: s.flux(tt))(np.linspace(150.0, 151.0, 5)))).all()
    heavier = s.replace(planets=s.planets, star_mass=1.3)  # planets that carry their derived a
    assert float(heavier.planets[0].a) == pytest.approx(float(semi_major_axis(10.0, 1.3 + 3.7e-5, 1.0)), rel=1e-12)
    faster = s.replace(planets=[s.planets[0].replace(period=1.5, a=None), s.planets[1]])
    assert faster.dt == pytest.approx(1.5 / 40)
    eccentric = jp.System(star, [pls[0].replace(e=0.9, omega=80.0, period=100.0), pls[1].replace(period=400.0)],
                          orbits="nbody", epoch=100.0, star_mass=1.0, star_radius=1.0)
    assert eccentric.dt == pytest.approx(100.0 * 0.1**1.5 / 40)  # 40 steps per periastron passage
    moon = jp.Moon(period=1.2, t0=0.1, a=0.3, inc=88.0, radius=0.03, mass_ratio=0.02, name="I")
    s = s.replace(planets=[s.planets[0].replace(moons=[moon]), s.planets[1]])
    back = system_from_dict(system_to_dict(s))
    assert (back.orbits, back.epoch, back.dt, back.span) == ("nbody", 100.0, s.dt, s.span)
    assert back.planets[0].moons[0].name == "I"
    t = np.linspace(100.0, 160.0, 3000)
    np.testing.assert_array_equal(np.asarray(back.flux(t)), np.asarray(s.flux(t)))
    with pytest.raises(ValueError, match="moon names must be unique"):
        jp.Planet(period=10.0, t0=1.0, a=20.0, inc=89.5, radius=0.05, moons=[moon, moon])
    kepler = jp.System(star, [jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.0, radius=0.05, name="b"),
                              jp.Planet(period=23.0, t0=0.0, a=35.0, inc=89.3, radius=0.07, name="c", lnode=40.0)])
    with pytest.raises(ValueError, match="node"):
        jp.alpha_limits(kepler)
    with pytest.raises(ValueError, match="sweep assumes planets on Keplerian orbits"):
        jp.sweep(s, np.linspace(100.0, 101.0, 5), [0.0, 10.0])


def test_bundled_nbody_config_is_the_photodynamical_fit(capsys):
    """Issue 25 (config keys): jaxppo/data/kepler51/kepler51_nbody.toml
    builds the N-body System of the photodynamical fit ([system] keys,
    planet masses, a derived): chi^2 of its model on its data is the fit's
    2089.6 for 1,689 points (examples/kepler51_photodynamics.py), and
    `jaxppo scan` on it fails at once naming the N-body orbits."""
    from jaxppo.cli import main
    from jaxppo.model._exposure import exposure_mean, supersampled_times

    path = Path(jp.__file__).parent / "data" / "kepler51" / "kepler51_nbody.toml"
    cfg = jp.load_config(path)
    s = cfg.system
    assert s.orbits == "nbody" and s.epoch == 155.0 and float(s.star_mass) == 0.985
    assert float(s.star_radius) == 0.81313342 and [pl.name for pl in s.planets] == list(NAMES)
    want = semi_major_axis(s.planets[0].period, s.star_mass + s.planets[0].mass, s.star_radius)
    np.testing.assert_allclose(float(s.planets[0].a), float(want), rtol=1e-12)  # b: a Jacobi orbit about star + b
    assert len(cfg.fit_free) == 18 and "b.mass" in cfg.fit_free
    lc = cfg.lightcurve
    times, n = supersampled_times(lc.time, lc.exposure)
    model = np.asarray(exposure_mean(s.flux(times), n))
    chi2 = float(np.sum(((lc.flux - model) / lc.flux_err) ** 2))
    assert lc.time.size == 1689 and abs(chi2 - 2089.634) < 0.01, chi2
    assert main(["scan", str(path), "--out", "unused"]) == 2
    assert "has N-body orbits" in capsys.readouterr().err


def test_a_diverging_integration_is_an_error_naming_the_masses():
    """A planet as heavy as its star beside a light one at twice its period: the map diverges. The flux was
    refused with "x must be finite, found nan" (no word of the integration); the error now says the
    integration diverged and gives each planet's mass ratio and the step; so does transit_times, which
    returned the few transits before the divergence."""
    planets = [jp.Planet(period=10.0, t0=0.0, a=None, inc=89.5, radius=0.1, mass=1.0, name="b"),
               jp.Planet(period=20.0, t0=3.0, a=None, inc=89.5, radius=0.1, mass=1e-5, name="c")]
    system = jp.System(jp.Star.quadratic(0.4, 0.2), planets, orbits="nbody", epoch=0.0, star_mass=1.0, star_radius=1.0)
    with pytest.raises(ValueError, match=r"integration diverged .*b: 1, c: 1e-05"):
        system.flux(np.linspace(-0.2, 0.2, 5))
    with pytest.raises(ValueError, match=r"integration diverged"):  # it listed a few transits, then none
        system.transit_times(0.0, 200.0)


def test_masses_in_earth_masses_given_as_m_sun_are_named():
    """jnkepler's Kepler-51 elements (the pdict file) carry ``pmass`` in Earth masses beside ``mass``, the
    mass ratio; pmass (3.30, 4.08, 5.32) given as mass [M_sun] made the map diverge, and the error said
    only "unstable, or planets this heavy need a smaller dt": a user halves dt. The error now adds that
    mass is in M_sun (with an Earth mass in M_sun); the Quantity in Earth masses gives jnkepler's times."""
    import astropy.units as u

    pmass = K51_MASS * 332946.0487  # Earth masses per M_sun: the file's pmass
    np.testing.assert_allclose(pmass, [3.3009236, 4.0750068, 5.3214538], rtol=1e-6)
    wrong = _kepler51_system()
    wrong = wrong.replace(planets=[p.replace(mass=float(m)) for p, m in zip(wrong.planets, pmass)])
    with pytest.raises(ValueError, match=r"b: 3\.3, c: 4\.08, d: 5\.32.*mass is in M_sun \(an Earth mass is 3\.0e-6"):
        wrong.transit_times(155.0, 400.0)
    right = _kepler51_system()
    right = right.replace(planets=[p.replace(mass=float(m) * u.M_earth) for p, m in zip(right.planets, pmass)])
    tc = right.transit_times(155.0, 260.0)
    np.testing.assert_allclose(tc["tc"][:2], [159.11026746, 204.26401001], atol=2e-5)  # the pdict's tc file
    with pytest.raises(ValueError) as caught:  # planets below 0.1 of their star (0.09, 0.05): no unit hint
        jp.System(jp.Star.quadratic(0.4, 0.2),
                  [jp.Planet(period=10.0, t0=0.0, a=None, inc=89.5, radius=0.1, mass=0.09, name="b"),
                   jp.Planet(period=10.5, t0=3.0, a=None, inc=89.5, radius=0.1, mass=0.05, name="c")],
                  orbits="nbody", epoch=0.0, star_mass=1.0, star_radius=1.0).transit_times(0.0, 300.0)
    assert "mass is in M_sun" not in str(caught.value)


def test_a_scattering_system_is_an_error_not_meaningless_transit_times():
    """Two Jupiter-mass planets at 45 and 50 d scatter (b out to 180-290 R*, c in to 22 R*): transit_times
    over 155-3000 d returned 126 transits that changed by tens of days with the step, and no error (the
    positions stay finite). The integration's reliability is now checked: b and c came within 0.36 mutual
    Hill radii near 910 d and the energy changed by 7.2e-5 (a stable system at the default step: below
    5e-7, Kepler-51 4e-8), so transit_times and flux raise naming both; traced (jit), positions are NaN.
    Kepler-51 keeps its energy error and closest approach far from the limits."""
    from jaxppo.model._nbody import ENERGY_TOLERANCE, HILL_TOLERANCE, system_xyz

    pls = [jp.Planet(period=45.1541, t0=159.1103, a=None, inc=89.8, radius=0.07, e=0.044, omega=-112.89,
                     mass=3e-3, name="b"),
           jp.Planet(period=50.0, t0=295.321, a=None, inc=89.5, radius=0.06, e=0.04, omega=-61.53, mass=3e-3,
                     name="c")]
    s = jp.System(jp.Star.quadratic(0.43, 0.11), pls, orbits="nbody", epoch=155.0, star_mass=1.0, star_radius=0.81)
    want = r"not reliable .*planets b and c came within 0\.3\d+ mutual Hill radii .*energy changed by 7\.\de-05.*dt = 0\.1926"
    with pytest.raises(ValueError, match=want):
        s.transit_times(155.0, 3000.0)
    with pytest.raises(ValueError, match=want):
        s.flux(np.linspace(155.0, 3000.0, 50))
    traced = s.replace(span=(155.0, 3000.0))  # under jit: NaN positions (a fit refuses the step)
    x, y, z = jax.jit(lambda t: system_xyz(traced, t, 0.0, np.ones(2)))(jnp.linspace(155.0, 3000.0, 50))
    assert np.all(np.isnan(np.asarray(x))) and np.all(np.isnan(np.asarray(z)))
    k51 = _kepler51_system()
    _, (_, energy, hill, _) = system_xyz(k51, np.linspace(155.0, 1600.0, 50), 0.0, np.ones(3), checks=True)
    assert float(np.max(energy)) < 1e-2 * ENERGY_TOLERANCE and float(np.min(hill)) > 10.0 * HILL_TOLERANCE


def test_float32_round_off_is_not_called_an_unstable_system():
    """With x64 off the bundled Kepler-51 system over 155-9000 d drifted by
    1.6e-5 in energy from round-off alone and was refused as "unstable, or
    dt too large: try dt / 4" (which drifted more); in float32 the energy
    test takes 1e-3 (close encounters are caught by the Hill test either
    way), and an error says float32."""
    from jaxppo.model._nbody import ENERGY_TOLERANCE, ENERGY_TOLERANCE_32, check_reliable, energy_tolerance

    rel = (np.array([0.0, 1.0]), np.array([0.0, 1.6e-5]), np.array([12.0, 12.0]), np.array([0, 0]))
    s = _kepler51_system()
    with pytest.raises(ValueError, match=r"changed by 1\.6e-05"):
        check_reliable(s, rel)
    with jax.enable_x64(False):
        assert energy_tolerance() == ENERGY_TOLERANCE_32
        check_reliable(s, rel)
        with pytest.raises(ValueError, match=r"more than 0\.001 first at t = 1 d, float32"):
            check_reliable(s, (rel[0], np.array([0.0, 2e-3]), rel[2], rel[3]))
    assert energy_tolerance() == ENERGY_TOLERANCE
