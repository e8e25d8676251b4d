"""Planets with transit times (TTVs): the orbit shifted by the offset of the
nearest listed transit, against an independent numpy computation, and on the
measured transit times of Kepler-51 (Holczer et al. 2016)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo.core.geometry import orbit_position
from jaxppo.model._phoenix import data_path

STAR = jp.Star("quadratic", [0.45, 0.2])


def _ttv_system():
    """b (circular) and c (eccentric) with transit times; both near the
    star's centre at t ~ 20, where their disks overlap."""
    b = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=float(np.degrees(np.arccos(0.2 / 20.0))), radius=0.1, name="b",
                  transit_times=[0.003, 9.996, 20.006, 30.001])
    c = jp.Planet(period=13.0, t0=-6.0, a=25.0, inc=89.4, radius=0.08, name="c", e=0.2, omega=30.0,
                  transit_times=[7.005, 20.002, 32.997], transit_epochs=[1, 2, 3])
    return jp.System(STAR, [b, c])


def _kepler_np(t, P, t0, a, inc_deg, e, omega_deg):
    """Sky position from docs/conventions.md, in numpy (Newton on Kepler's
    equation; shares no code with jaxppo.core.geometry)."""
    w, i = np.radians(omega_deg), np.radians(inc_deg)
    if e == 0:
        phi = 2 * np.pi * (t - t0) / P
        return a * np.sin(phi), a * np.cos(phi) * np.cos(i), a * np.cos(phi) * np.sin(i)
    fc = np.pi / 2 - w
    Ec = 2 * np.arctan(np.sqrt((1 - e) / (1 + e)) * np.tan(fc / 2))
    M = 2 * np.pi * (t - t0) / P + Ec - e * np.sin(Ec)
    E = M.copy()
    for _ in range(50):
        E = E - (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
    f = 2 * np.arctan2(np.sqrt(1 + e) * np.sin(E / 2), np.sqrt(1 - e) * np.cos(E / 2))
    r = a * (1 - e * np.cos(E))
    th = f + w - np.pi / 2
    return r * np.sin(th), r * np.cos(th) * np.cos(i), r * np.cos(th) * np.sin(i)


def _reference_positions(pl, t):
    """Shift every time by hand by the offset of the nearest listed transit
    (brute force over the list; ties to the later one) and evaluate the
    Keplerian orbit there."""
    tc = np.asarray(pl.transit_times, float)
    ep = np.asarray(pl.transit_epochs, float)
    P, t0 = float(pl.period), float(pl.t0)
    dist = np.abs(t[:, None] - tc[None, :])
    # later one on ties: search the reversed list
    k = tc.size - 1 - np.argmin(dist[:, ::-1], axis=1)
    ts = t - (tc[k] - t0 - ep[k] * P)
    return _kepler_np(ts, P, t0, float(pl.a), float(pl.inc), float(pl.e), float(pl.omega))


def test_positions_and_overlap_flux_match_an_independent_computation():
    from helpers import reference_deficit, reference_total

    system = _ttv_system()
    t = np.concatenate([np.linspace(-3, 36, 3001), [19.99, 20.0, 20.003, 20.004, 20.006, 20.01]])
    x, y, r = system.positions(t, xp=np)
    xj, yj, rj = (np.asarray(v) for v in system.positions(jnp.asarray(t)))
    for k, pl in enumerate(system.planets):
        xr, yr, zr = _reference_positions(pl, t)
        assert np.max(np.abs(x[:, k] - xr)) < 1e-10 and np.max(np.abs(y[:, k] - yr)) < 1e-10
        assert np.max(np.abs(xj[:, k] - xr)) < 1e-10 and np.max(np.abs(yj[:, k] - yr)) < 1e-10
        assert np.array_equal(r[:, k] > 0, zr > 0)
    # overlap flux of the two disks near t = 20 against the radial reference
    ir = lambda rr: float(STAR.intensity(np.sqrt(max(1 - rr * rr, 0))))
    f0 = reference_total(ir)
    tt = np.array([19.99, 20.0, 20.003, 20.004, 20.01, 20.05])
    flux = np.asarray(system.flux(tt, method="exact"))
    overlapped = 0
    for m, ti in enumerate(tt):
        xs, ys, ps = [], [], []
        for pl in system.planets:
            xr, yr, zr = _reference_positions(pl, np.array([ti]))
            if zr[0] > 0:
                xs.append(xr[0]), ys.append(yr[0]), ps.append(float(pl.radius))
        overlapped += np.hypot(xs[0] - xs[1], ys[0] - ys[1]) < ps[0] + ps[1]
        ref = 1 - reference_deficit(ir, xs, ys, ps) / f0
        assert abs(flux[m] - ref) < 1e-10, (ti, flux[m], ref)
    assert overlapped >= 4  # the check covers planet-planet overlaps
    # the sweep (host geometry) gives the same numbers
    sw = jp.sweep(system, tt, [0.0], cases=("same",))[0, 0]
    assert np.max(np.abs(sw - flux)) < 1e-12


def test_linear_planets_are_bit_identical():
    """Without transit times nothing changes: the orbit is evaluated at t
    itself (the same array), and a planet listing times with zero offsets
    (exact binary numbers) gives bit-identical positions and flux."""
    base = jp.Planet(period=4.0, t0=0.5, a=12.0, inc=88.5, radius=0.09, name="b")
    ecc = jp.Planet(period=6.0, t0=1.25, a=15.0, inc=89.0, radius=0.05, name="c", e=0.3, omega=70.0)
    t = jnp.linspace(-2.0, 30.0, 2001)
    assert base.orbit_time(t) is t and ecc.orbit_time(t) is t
    phi = 2.0 * np.pi * (t - base.t0) / base.period
    inc = jnp.deg2rad(base.inc)
    x, y, z = base.position(t)
    assert np.array_equal(x, base.a * jnp.sin(phi)) and np.array_equal(y, base.a * jnp.cos(phi) * jnp.cos(inc))
    xe = orbit_position(t, ecc.period, ecc.t0, ecc.a, jnp.deg2rad(ecc.inc), ecc.e, jnp.deg2rad(ecc.omega), jnp)
    assert all(np.array_equal(u, v) for u, v in zip(ecc.position(t), xe))
    zero_b = base.replace(transit_times=[0.5 + 4.0 * n for n in range(9)])
    zero_c = ecc.replace(transit_times=[1.25 + 6.0 * n for n in range(6)])
    f_lin = jp.System(STAR, [base, ecc]).flux(t)
    f_ttv = jp.System(STAR, [zero_b, zero_c]).flux(t)
    assert np.array_equal(np.asarray(f_lin), np.asarray(f_ttv))


def test_nearest_listed_transit_decides_at_the_midpoint():
    """Half-way between two listed transits the later one's offset holds;
    just before, the earlier one's."""
    pl = jp.Planet(period=8.0, t0=0.0, a=15.0, inc=89.0, radius=0.05, transit_times=[0.25, 8.0 - 0.125],
                   name="b")
    mid = 0.5 * (0.25 + 7.875)  # 4.0625, exact in binary
    before = np.nextafter(mid, -np.inf)
    ts = np.asarray(pl.orbit_time(np.array([before, mid, 100.0, -50.0]), np))
    assert ts[0] == before - 0.25 and ts[1] == mid + 0.125
    assert ts[2] == 100.0 + 0.125 and ts[3] == -50.0 - 0.25  # beyond the list: the end offsets hold
    # jax agrees
    assert np.array_equal(np.asarray(pl.orbit_time(jnp.asarray([before, mid]))), ts[:2])


def test_gradient_with_respect_to_a_transit_time():
    system = _ttv_system()
    t = jnp.array([19.985, 20.001, 20.012, 9.99, 30.006])

    def flux_of(tt_b, tt_c, times):
        b, c = system.planets
        return system.replace(planets=[b.replace(transit_times=tt_b), c.replace(transit_times=tt_c)]).flux(times)

    tb, tc = system.planets[0].transit_times, system.planets[1].transit_times
    jac_b, jac_c = (np.asarray(j) for j in jax.jit(jax.jacobian(flux_of, argnums=(0, 1)))(tb, tc, t))  # one program
    flux_of = jax.jit(flux_of)  # the finite differences: one compilation
    h = 1e-6
    for k in range(tb.size):
        e = jnp.zeros(tb.size).at[k].set(h)
        fd = (np.asarray(flux_of(tb + e, tc, t)) - np.asarray(flux_of(tb - e, tc, t))) / (2 * h)
        assert np.allclose(jac_b[:, k], fd, rtol=1e-6, atol=1e-9), (k, jac_b[:, k], fd)
    for k in range(tc.size):
        e = jnp.zeros(tc.size).at[k].set(h)
        fd = (np.asarray(flux_of(tb, tc + e, t)) - np.asarray(flux_of(tb, tc - e, t))) / (2 * h)
        assert np.allclose(jac_c[:, k], fd, rtol=1e-6, atol=1e-9), (k, jac_c[:, k], fd)
    assert np.abs(jac_b[:3, 2]).min() > 1e-3  # the transit at ~20 moves with its listed time
    # moving tc_k shifts the planet's orbit in time near transit k: of a
    # single planet, d F / d tc_k = -d F / d t exactly
    b = jp.System(STAR, [system.planets[0]])
    dfdt = jax.jit(jax.vmap(jax.grad(lambda s: b.flux(s))))(t[:3])
    dfdtc = jax.jit(jax.jacobian(lambda tt: b.replace(planets=[b.planets[0].replace(transit_times=tt)]).flux(t[:3])))(tb)
    assert np.allclose(np.asarray(dfdtc[:, 2]), -np.asarray(dfdt), rtol=1e-12, atol=1e-14)
    # vmap over transit times
    batch = jnp.stack([tb, tb + 0.001])
    fb = jax.jit(jax.vmap(lambda tt: flux_of(tt, tc, t)))(batch)
    assert np.allclose(np.asarray(fb[1]), np.asarray(flux_of(tb + 0.001, tc, t)), rtol=0, atol=1e-15)


@pytest.mark.parametrize("kwargs, match", [
    (dict(transit_times=[0.0, 10.0], transit_epochs=[0]), "transit_epochs has 1 entries but transit_times has 2"),
    (dict(transit_times=[0.0, np.nan]), "transit_times must be finite, got nan for epoch 1"),
    (dict(transit_times=[0.0, 10.0], transit_epochs=[3, 3]), r"distinct, epoch\(s\) \[3\]"),
    (dict(transit_times=[0.0, 10.0], transit_epochs=[0, 1.5]), "must be integers"),
    (dict(transit_times=[0.0, 16.0]), "epoch 1 is \\+6 d from its linear ephemeris"),
    (dict(transit_times=[20.0], transit_epochs=[1]), "epoch 1"),
    (dict(transit_epochs=[0, 1]), "transit_epochs = \\[0, 1\\] needs transit_times"),
    (dict(transit_times=[[0.0, 10.0]]), "1D"),
    (dict(transit_times="0.0"), "transit_times must be a time, got str"),
    (dict(transit_times=[0.0, "x"]), r"1D list of mid-times \[d\] \(numbers\)"),
])
def test_bad_transit_times_name_the_problem(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.0, radius=0.05, name="b", **kwargs)


def test_epochs_are_sorted_and_kept_by_replace_repr_and_serialisation():
    from jaxppo.inference._serialise import system_from_dict, system_to_dict

    pl = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.0, radius=0.05, name="b",
                   transit_times=[30.01, 0.002, 19.99], transit_epochs=[3, 0, 2])
    assert pl.transit_epochs == (0, 2, 3) and np.array_equal(np.asarray(pl.transit_times), [0.002, 19.99, 30.01])
    assert pl.mid_time(2) == 19.99 and pl.mid_time(0) == 0.002
    assert pl.mid_time(1) == 10.0 + (19.99 - 20.0)  # epochs 0 and 2 equally near: the later
    assert pl.mid_time(7) == 70.0 + (30.01 - 30.0)
    moved = pl.replace(radius=0.06)
    assert moved.transit_epochs == pl.transit_epochs and np.array_equal(moved.transit_times, pl.transit_times)
    assert "transit_times=3 listed (epochs 0, 2, 3)" in repr(pl)
    import json

    system = jp.System(STAR, [pl, jp.Planet(period=7.0, t0=1.0, a=15.0, inc=89.5, radius=0.04, name="c")])
    back = system_from_dict(json.loads(json.dumps(system_to_dict(system))))
    assert back.planets[0].transit_epochs == (0, 2, 3) and back.planets[1].transit_times is None
    assert np.array_equal(np.asarray(back.planets[0].transit_times), np.asarray(pl.transit_times))
    t = np.linspace(-1, 35, 500)
    assert np.array_equal(np.asarray(back.flux(t)), np.asarray(system.flux(t)))


def test_windows_tables_and_mask_use_the_listed_times():
    from jaxppo.model._overlap import in_transit_mask
    from jaxppo.model._transits import transit_windows

    system = _ttv_system()
    table = system.transit_times(-7.0, 40.0)
    rows = {(str(r["planet"]), int(r["epoch"])): float(r["tc"]) for r in table}
    b, c = system.planets
    for pl in (b, c):
        for n, tc in zip(pl.transit_epochs, np.asarray(pl.transit_times)):
            if -7.0 <= tc <= 40.0:
                assert rows[(pl.name, n)] == tc
    assert rows[("c", 0)] == pytest.approx(-6.0 + (7.005 - 7.0), abs=1e-12)  # unlisted: offset of the nearest listed epoch
    t1, t4 = (float(v) for v in c.contacts())
    for w in transit_windows(system, [1], -1.0, 40.0):
        assert w[0] == pytest.approx(w[3] + t1, abs=1e-12) and w[3] in rows.values()
    # the mask is the model's own in-transit test: where the mask is off,
    # each planet alone leaves the star untouched
    t = np.linspace(-1.0, 40.0, 40001)
    mask = in_transit_mask(system, t)
    for pl in system.planets:
        f = np.asarray(jp.System(STAR, [pl]).flux(t))
        assert np.all(f[~mask] == 1.0)
        half = float(pl.half_duration())
        for tc in np.asarray(pl.transit_times):
            near = np.abs(t - tc) < 0.9 * half
            assert mask[near].all() and (f[near] < 1).all()
    events = jp.multi_transits(system, 15.0, 25.0)
    assert len(events) == 1 and events[0].transit_mid == (20.006, 20.002)


def _kepler51():
    rows = np.genfromtxt(data_path("kepler51/kepler51_ttvs_holczer2016.csv"), delimiter=",", names=True)
    sel = rows["pidx"] == 1  # planet b
    return rows["N"][sel].astype(int), rows["tc"][sel]


def test_kepler51_b_measured_transit_times():
    """Kepler-51 b's measured mid-times (Holczer et al. 2016) depart from a
    linear ephemeris by many minutes; the model must put each transit at
    its listed time: the table returns them, and the flux minimum of the
    single-planet light curve sits at each to < 1 s. Orbit shape:
    approximately Kepler-51 b's (a/R* ~ 60, p ~ 0.07, b ~ 0.5); the check
    is the timing."""
    epochs, tc = _kepler51()
    assert epochs.size == 30 and tc.min() > 150 and tc.max() < 1600
    slope, icpt = np.polyfit(epochs, tc, 1)  # best linear ephemeris
    assert np.max(np.abs(tc - (icpt + slope * epochs))) * 1440 > 10  # real TTVs of > 10 minutes
    pl = jp.Planet(period=slope, t0=icpt, a=60.0, inc=float(np.degrees(np.arccos(0.5 / 60.0))), radius=0.07,
                   name="b", transit_times=tc, transit_epochs=epochs)
    system = jp.System(STAR, [pl])
    table = system.transit_times(150.0, 1600.0)
    got = dict(zip(np.asarray(table["epoch"]).tolist(), np.asarray(table["tc"])))
    for n, t in zip(epochs, tc):
        assert got[n] == t
    missing = sorted(set(range(epochs.min(), epochs.max() + 1)) - set(epochs.tolist()))
    for n in missing:  # unlisted epochs: offset of the nearest listed epoch
        k = min(range(epochs.size), key=lambda j: (abs(epochs[j] - n), -epochs[j]))
        assert got[n] == pytest.approx(icpt + slope * n + (tc[k] - icpt - slope * epochs[k]), abs=1e-9)
    # flux minimum by bisection on dF/dt, all transits at once
    dfdt = jax.jit(jax.vmap(jax.grad(lambda s: system.flux(s))))
    lo, hi = jnp.asarray(tc - 0.02), jnp.asarray(tc + 0.02)
    assert np.all(np.asarray(dfdt(lo)) < 0) and np.all(np.asarray(dfdt(hi)) > 0)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        neg = dfdt(mid) < 0
        lo, hi = jnp.where(neg, mid, lo), jnp.where(neg, hi, mid)
    tmin = np.asarray(0.5 * (lo + hi))
    assert np.max(np.abs(tmin - tc)) * 86400 < 1.0, np.max(np.abs(tmin - tc)) * 86400
    # the linear ephemeris would have put them minutes away
    lin = jp.System(STAR, [pl.replace(transit_times=None, transit_epochs=None)])
    assert np.min(np.asarray(lin.flux(tc))) > np.min(np.asarray(system.flux(tc)))


@pytest.mark.parametrize("epoch", [1.5, np.nan, True, "2", [1]])
def test_mid_time_refuses_a_non_integer_epoch(epoch):
    """Planet.mid_time(1.5) truncated to epoch 1 and returned its time."""
    pl = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.5, radius=0.05)
    with pytest.raises(ValueError, match="epoch must be an integer"):
        pl.mid_time(epoch)
    assert pl.mid_time(np.int64(2)) == 20.0 and pl.mid_time(2.0) == 20.0
