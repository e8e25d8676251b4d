"""N-body sky positions (jnkepler, read by ``jaxppo.model._nbody``) against
REBOUND's IAS15 from the same initial conditions: Kepler-51 b, c, d with the
osculating Jacobi elements at BKJD 155 of Masuda's jnkepler example
(``kep51_dt1.0_start155.00_end2950.00_pdict.csv``; masses in units of the
stellar mass, which is taken as 1 M_sun, as there).

    python benchmarks/nbody_vs_rebound.py                 # the comparisons and timings
    python benchmarks/nbody_vs_rebound.py --write-csv     # also write the tests' REBOUND reference
    python benchmarks/nbody_vs_rebound.py --t-end 2950    # a longer span than the Kepler baseline

Printed: per planet, max |t_c(jnkepler) - t_c(REBOUND)| in minutes over the
baseline (mid-transit = where the sky-plane x.v of the planet relative to the
star changes sign, z > 0), for the transit times found on jaxppo's
positions and for jnkepler's own transit finder; the largest sky distance
[R*] between the positions and REBOUND's at random times and at times off
mid-transit; the same at grid points (tau = 0) and half-way between them
(|tau| = dt/2, the largest step of the read-out); how both scale with the
map's step dt; the timings (jnkepler compile and run, REBOUND IAS15 and
WHFast). ``--write-csv`` writes ``tests/data/kepler51_rebound_transits.csv``
(planet, epoch, tc [BKJD]) and ``tests/data/kepler51_rebound_positions.csv``
(t [BKJD], planet, x, y, z [au]; astrocentric, in REBOUND's frame, whose
observer is on +z: jaxppo's sky frame is (-x, y, z) / R*), and
``tests/data/kepler51_rebound_double_transit.csv`` (the same columns across
the overlapping b + d double transit near BKJD 1513.7, inclinations
``DOUBLE_INCS``).

CPU speed: jnkepler advises XLA_FLAGS=
"--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=65536"
set before JAX starts; run this script with and without it to compare.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

try:
    import rebound
except ImportError:
    sys.exit("nbody_vs_rebound.py needs REBOUND: pip install rebound")

from jaxppo.model._nbody import G_AU_DAY, R_SUN_AU, nbody_xyz  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PDICT = "kep51_dt1.0_start155.00_end2950.00_pdict.csv"
EPOCH = 155.0          # BKJD at which the elements osculate
STAR_MASS = 1.0        # M_sun (the pdict's masses are planet / star mass ratios)
STAR_RADIUS = 0.881    # R_sun (Libby-Roberts et al. 2020); only the unit of the positions
NAMES = ("b", "c", "d")


def data_dir() -> Path:
    """The data folder ``kepler51_masuda_lc_ttv``: under ``$JAXPPO_DATA`` or ``shared/data`` beside the repository."""
    import os

    for base in (os.environ.get("JAXPPO_DATA", ""), str(ROOT.parent / "shared" / "data")):
        path = Path(base) / "kepler51_masuda_lc_ttv"
        if base and (path / PDICT).exists():
            return path
    raise FileNotFoundError(f"{PDICT} not found; set JAXPPO_DATA to the folder holding kepler51_masuda_lc_ttv")


def kepler51_elements() -> dict:
    """Kepler-51's elements in the units of ``nbody_xyz`` (days, degrees, M_sun)."""
    d = pd.read_csv(data_dir() / PDICT)
    ecc = np.hypot(d.ecosw, d.esinw).to_numpy()
    return dict(periods=d.period.to_numpy(), eccs=ecc, omegas=np.rad2deg(np.arctan2(d.esinw, d.ecosw)).to_numpy(),
                incs=np.rad2deg(np.arccos(d.cosi)).to_numpy(), lnodes=np.rad2deg(d.lnode).to_numpy(),
                tics=d.tic.to_numpy(), masses=d.mass.to_numpy(), star_mass=STAR_MASS, star_radius=STAR_RADIUS,
                epoch=EPOCH)


def mean_anomaly(tic, period, ecc, omega_rad, epoch):
    """Mean anomaly at ``epoch`` of an orbit in inferior conjunction (f = pi/2 - omega) at ``tic``."""
    f_c = 0.5 * np.pi - omega_rad
    e_c = 2.0 * np.arctan(np.sqrt((1.0 - ecc) / (1.0 + ecc)) * np.tan(0.5 * f_c))
    return e_c - ecc * np.sin(e_c) + 2.0 * np.pi * (epoch - tic) / period


def rebound_sim(el: dict, integrator: str = "ias15", dt: float | None = None) -> rebound.Simulation:
    """A REBOUND simulation at ``epoch`` from the Jacobi elements (REBOUND's default primary: the
    centre of mass of the bodies added before, with G (M_interior + m) in Kepler's law)."""
    sim = rebound.Simulation()
    sim.G = G_AU_DAY
    sim.add(m=el["star_mass"])
    for j in range(len(el["periods"])):
        w = np.deg2rad(el["omegas"][j])
        sim.add(m=el["masses"][j], P=el["periods"][j], e=el["eccs"][j], inc=np.deg2rad(el["incs"][j]),
                omega=w, Omega=np.deg2rad(el["lnodes"][j]),
                M=mean_anomaly(el["tics"][j], el["periods"][j], el["eccs"][j], w, el["epoch"]))
    sim.move_to_com()
    sim.t = el["epoch"]
    sim.integrator = integrator
    if dt is not None:
        sim.dt = dt
    return sim


def _sky_g(sim, j):
    """x.v in the sky plane and z of planet j relative to the star."""
    p, s = sim.particles[j + 1], sim.particles[0]
    return (p.x - s.x) * (p.vx - s.vx) + (p.y - s.y) * (p.vy - s.vy), p.z - s.z


def rebound_transits(el: dict, t_end: float, step: float = 0.5) -> pd.DataFrame:
    """Every mid-transit from ``epoch`` to ``t_end``: sign changes of x.v (z > 0), bisected on a copy."""
    sim = rebound_sim(el)
    n = len(el["periods"])
    rows = []
    prev = [_sky_g(sim, j)[0] for j in range(n)]
    t = el["epoch"]
    while t < t_end:
        t_next = t + step
        sim.integrate(t_next, exact_finish_time=1)
        for j in range(n):
            g, z = _sky_g(sim, j)
            if prev[j] < 0 <= g and z > 0:
                lo, hi, c = t, t_next, sim.copy()
                for _ in range(60):
                    mid = 0.5 * (lo + hi)
                    c.integrate(mid, exact_finish_time=1)
                    if _sky_g(c, j)[0] < 0:
                        lo = mid
                    else:
                        hi = mid
                tc = 0.5 * (lo + hi)
                epoch = int(np.round((tc - el["tics"][j]) / el["periods"][j]))
                rows.append((NAMES[j], epoch, tc))
            prev[j] = g
        t = t_next
    out = pd.DataFrame(rows, columns=["planet", "epoch", "tc"])
    return out[out.tc <= t_end].sort_values(["planet", "epoch"]).reset_index(drop=True)


def rebound_positions(el: dict, times, integrator="ias15", dt=None) -> np.ndarray:
    """Astrocentric positions [au] in REBOUND's frame at ``times``: [n_times, n_planets, 3]
    (integrated forward from ``epoch`` for the later times and backward for the earlier ones)."""
    times = np.asarray(times, float)
    out = np.empty((len(times), len(el["periods"]), 3))
    after = np.flatnonzero(times >= el["epoch"])
    before = np.flatnonzero(times < el["epoch"])
    for idx in (after[np.argsort(times[after])], before[np.argsort(times[before])[::-1]]):
        sim = rebound_sim(el, integrator, dt)
        if integrator == "whfast" and len(idx) and times[idx[0]] < el["epoch"]:
            sim.dt = -abs(sim.dt)
        for i in idx:
            sim.integrate(times[i], exact_finish_time=1)
            s = sim.particles[0]
            for j in range(len(el["periods"])):
                p = sim.particles[j + 1]
                out[i, j] = (p.x - s.x, p.y - s.y, p.z - s.z)
    return out


def sample_times(transits: pd.DataFrame, t_end: float, seed: int = 51) -> np.ndarray:
    """100 random times over the span, 10 in the 60 d before ``EPOCH`` (backward integration) and 4 off
    mid-transit (0.02-0.4 d either side) in 15 transits."""
    rng = np.random.default_rng(seed)
    t = list(rng.uniform(EPOCH, t_end, 100)) + list(rng.uniform(EPOCH - 60.0, EPOCH, 10))
    for tc in rng.choice(transits.tc.to_numpy(), 15, replace=False):
        t += list(tc + rng.choice([-1, 1], 4) * rng.uniform(0.02, 0.4, 4))
    return np.sort(np.asarray(t))


def to_sky(xyz_au) -> np.ndarray:
    """REBOUND's astrocentric (x, y, z) [au] -> jaxppo's sky frame (-x, y, z) [R*]."""
    return np.stack([-xyz_au[..., 0], xyz_au[..., 1], xyz_au[..., 2]], -1) / (STAR_RADIUS * R_SUN_AU)


def sky_transit_times(el: dict, guess, planet_idx, dt=None, h=1e-3, iters=4, t_range=None) -> np.ndarray:
    """Mid-transit times on ``nbody_xyz``'s positions: Newton steps on x.v = d(x^2 + y^2)/dt / 2 with
    central differences of x^2 + y^2 (step h [d]), from ``guess`` [d]."""
    t = np.asarray(guess, float)
    rows = np.arange(len(t))
    for _ in range(iters):
        tt = np.stack([t - h, t, t + h])
        x, y, _ = nbody_xyz(tt, dt=dt, t_range=t_range, **el)
        d2 = np.asarray(x**2 + y**2)[:, rows, planet_idx]
        t = t - h * (d2[2] - d2[0]) / (2.0 * (d2[2] - 2.0 * d2[1] + d2[0]))
    return t


def timed(fn, *args, repeat=3, **kwargs):
    """(result, first-call seconds, best of ``repeat`` later calls)."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args, **kwargs))
    first = time.perf_counter() - t0
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args, **kwargs))
        best = min(best, time.perf_counter() - t0)
    return out, first, best


def jnkepler_own_transits(el: dict, transits: pd.DataFrame, t_end: float, dt: float):
    """jnkepler's JaxTTV transit times (its default 'fast' finder) at REBOUND's transits."""
    from jnkepler.jaxttv import JaxTTV

    tcobs = [transits.tc[transits.planet == n].to_numpy() for n in NAMES]
    jt = JaxTTV(EPOCH, t_end + 2 * dt, dt, tcobs, list(el["periods"]), print_info=False)
    par = {"period": el["periods"], "ecc": el["eccs"], "omega": np.deg2rad(el["omegas"]),
           "cosi": np.cos(np.deg2rad(el["incs"])), "lnode": np.deg2rad(el["lnodes"]), "tic": el["tics"],
           "pmass": el["masses"], "smass": el["star_mass"]}
    (tc, _), first, best = timed(jt.get_transit_times_obs, par)
    return np.asarray(tc), first, best


def main(argv=None) -> None:
    """Run the comparisons, print them and optionally write the tests' CSV files."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=1600.0, help="end of the span [BKJD] (default: Kepler's)")
    ap.add_argument("--write-csv", action="store_true", help="write tests/data/kepler51_rebound_*.csv")
    args = ap.parse_args(argv)
    el = kepler51_elements()
    t0 = time.perf_counter()
    transits = rebound_transits(el, args.t_end)
    t_rb_tc = time.perf_counter() - t0
    times = sample_times(transits, args.t_end)
    t0 = time.perf_counter()
    ref_au = rebound_positions(el, times)
    t_rb_pos = time.perf_counter() - t0
    ref = to_sky(ref_au)
    print(f"REBOUND {rebound.__version__} IAS15: {len(transits)} transits {EPOCH}-{args.t_end} in {t_rb_tc:.2f} s "
          f"(bisection), positions at {len(times)} times in {t_rb_pos:.3f} s")
    shipped = pd.read_csv(data_dir() / PDICT.replace("pdict", "tc")).tc.to_numpy()
    shipped = shipped[shipped < args.t_end]
    off = np.array([np.min(np.abs(transits.tc.to_numpy() - tc)) for tc in shipped])
    print(f"  the {len(shipped)} transit times shipped with the elements (jnkepler, dt = 1 d): "
          f"max |dtc| = {1440 * off.max():.4f} min from REBOUND's")
    for integrator, step in (("ias15", None), ("whfast", 1.0)):
        sim = rebound_sim(el, integrator, step)
        t0 = time.perf_counter()
        sim.integrate(args.t_end, exact_finish_time=0)
        print(f"  {integrator} integration {EPOCH}-{args.t_end} d: {1e3 * (time.perf_counter() - t0):.2f} ms")
    pidx = np.array([NAMES.index(n) for n in transits.planet])
    guess = el["tics"][pidx] + transits.epoch.to_numpy() * el["periods"][pidx]
    span = (EPOCH, args.t_end + 1.0)
    print(f"\n{'dt [d]':>7} {'planet':>6} {'max|dtc| sky [min]':>19} {'max|dtc| jnkepler [min]':>24} "
          f"{'max|dr| [R*]':>13} {'grid pts':>10} {'half-way':>10}")
    for dt in (0.25, 0.5, 1.0, float(np.min(el["periods"])) / 40, 1.5, 2.25):
        tc = sky_transit_times(el, guess, pidx, dt=dt, t_range=span)
        tc_jnk, _, _ = jnkepler_own_transits(el, transits, args.t_end, dt)
        x, y, z = nbody_xyz(times, dt=dt, **el)
        dr = np.sqrt((np.asarray(x) - ref[..., 0])**2 + (np.asarray(y) - ref[..., 1])**2
                     + (np.asarray(z) - ref[..., 2])**2)
        grid = EPOCH + dt * np.arange(int((args.t_end - EPOCH) / dt))
        half = grid[:-1] + 0.5 * dt - 1e-9
        gd = _grid_error(el, np.concatenate([grid[::7], half[::7]]), dt)
        for j, n in enumerate(NAMES):
            sel = transits.planet.to_numpy() == n
            print(f"{dt:7.3f} {n:>6} {1440 * np.max(np.abs(tc - transits.tc)[sel]):19.5f} "
                  f"{1440 * np.max(np.abs(tc_jnk - transits.tc)[sel]):24.5f} {dr[:, j].max():13.2e} "
                  f"{gd[0][j]:10.2e} {gd[1][j]:10.2e}")
    near = EPOCH + np.array([-1.1, -0.9, -0.6, -0.3, -0.05, 0.05, 0.3, 0.6, 0.9, 1.1])
    x, y, z = nbody_xyz(near, **el)
    ref_near = to_sky(rebound_positions(el, near))
    dr = np.sqrt((np.asarray(x) - ref_near[..., 0])**2 + (np.asarray(y) - ref_near[..., 1])**2
                 + (np.asarray(z) - ref_near[..., 2])**2)
    print(f"\nwithin 1.1 d of the epoch (read-out steps up to dt), default dt: max |dr| = {dr.max():.2e} R*")
    _timings(el, times, args.t_end)
    if args.write_csv:
        _write(transits, times, ref_au)


def _grid_error(el, t, dt):
    """Largest 3D distance [R*] to REBOUND at the grid points (first half of t) and half-way (second half)."""
    t = np.sort(t)
    ref = to_sky(rebound_positions(el, t))
    x, y, z = nbody_xyz(t, dt=dt, **el)
    dr = np.sqrt((np.asarray(x) - ref[..., 0])**2 + (np.asarray(y) - ref[..., 1])**2 + (np.asarray(z) - ref[..., 2])**2)
    on = np.isclose(((t - EPOCH) / dt) % 1.0, 0.0, atol=1e-6) | np.isclose(((t - EPOCH) / dt) % 1.0, 1.0, atol=1e-6)
    return dr[on].max(0), dr[~on].max(0)


def _timings(el, times, t_end):
    """Compile and run times of ``nbody_xyz`` (jnkepler underneath) for a few sizes; reverse against
    forward mode."""
    import os

    print("\njnkepler via nbody_xyz (default dt = P_b / 40), first call (compile + run) and best later call "
          f"(load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs):")
    for n in (len(times), 10_000, 100_000):
        t = np.linspace(EPOCH, t_end, n)
        _, first, best = timed(lambda tt: nbody_xyz(tt, **el), t)
        print(f"  {n:7d} times over {EPOCH}-{t_end} d: first {first:6.2f} s, then {1e3 * best:8.2f} ms")
    names = ("masses", "periods", "eccs", "omegas", "incs", "lnodes", "tics")
    t = times[times >= EPOCH]
    dt = float(np.min(el["periods"])) / 40

    def loss(*values):
        x, y, _ = nbody_xyz(t, dt=dt, **{**el, **dict(zip(names, values))})
        return jax.numpy.sum(x * np.sin(t)[:, None]) + jax.numpy.sum(y)

    values = tuple(np.asarray(el[n], float) for n in names)
    values = values[:4] + (np.array([89.9, 89.8, 90.1]), np.array([0.0, 1.0, -2.0])) + values[6:]
    argnums = tuple(range(len(names)))
    rev, first, best = timed(jax.jit(jax.grad(loss, argnums=argnums)), *values)
    print(f"  jax.grad wrt masses and elements, {len(t)} times: first {first:6.2f} s, then {1e3 * best:8.2f} ms")
    fwd, first, best = timed(jax.jit(jax.jacfwd(loss, argnums=argnums)), *values)
    print(f"  jax.jacfwd (the same derivatives):             first {first:6.2f} s, then {1e3 * best:8.2f} ms")
    for name, r, f in zip(names, rev, fwd):
        r, f = np.asarray(r), np.asarray(f)
        print(f"    d/d{name:7s} finite: {bool(np.all(np.isfinite(r)))}, "
              f"max |grad - jacfwd| / max |jacfwd| = {np.max(np.abs(r - f)) / np.max(np.abs(f)):.1e}")


# the b + d double transit near BKJD 1513.7 with b and d overlapping on the star: inclinations near those
# of a photodynamical fit of the Kepler data (the pdict's TTV-only solution has all three at 90 deg)
DOUBLE_INCS = (89.8, 89.5, 89.95)
DOUBLE_TIMES = np.linspace(1513.45, 1514.05, 121)


def write_double_transit() -> Path:
    """REBOUND IAS15 positions [au] across the b + d double transit (``DOUBLE_INCS``, ``DOUBLE_TIMES``):
    tests/data/kepler51_rebound_double_transit.csv, the reference of the N-body light curve there."""
    el = {**kepler51_elements(), "incs": np.asarray(DOUBLE_INCS)}
    ref_au = rebound_positions(el, DOUBLE_TIMES)
    out = ROOT / "tests" / "data" / "kepler51_rebound_double_transit.csv"
    rows = [(t, NAMES[j], *ref_au[i, j]) for i, t in enumerate(DOUBLE_TIMES) for j in range(ref_au.shape[1])]
    pd.DataFrame(rows, columns=["t", "planet", "x", "y", "z"]).to_csv(out, index=False, float_format="%.14e")
    return out


# two Jupiter-mass planets near 2:1 (TTVs of +-5 d on a 10-d period): every transit must still be found
STRONG = dict(periods=np.array([10.0, 20.3]), eccs=np.array([0.05, 0.05]), omegas=np.array([40.0, -70.0]),
              incs=np.array([89.7, 89.8]), lnodes=np.zeros(2), tics=np.array([101.0, 107.0]),
              masses=np.array([1e-3, 1e-3]), star_mass=1.0, star_radius=1.0, epoch=100.0)


def write_strong_ttv() -> Path:
    """REBOUND IAS15 mid-transit times of ``STRONG`` from its epoch to 1600 d (planets "p0", "p1"):
    tests/data/strong_ttv_rebound_transits.csv."""
    global NAMES
    names, NAMES = NAMES, ("p0", "p1")
    try:
        transits = rebound_transits(STRONG, 1600.0, step=0.25)
    finally:
        NAMES = names
    out = ROOT / "tests" / "data" / "strong_ttv_rebound_transits.csv"
    transits.to_csv(out, index=False, float_format="%.10f")
    return out


def _write(transits, times, ref_au):
    """The tests' REBOUND reference (tests/data)."""
    out = ROOT / "tests" / "data"
    out.mkdir(exist_ok=True)
    transits.to_csv(out / "kepler51_rebound_transits.csv", index=False, float_format="%.10f")
    rows = [(t, NAMES[j], *ref_au[i, j]) for i, t in enumerate(times) for j in range(ref_au.shape[1])]
    pd.DataFrame(rows, columns=["t", "planet", "x", "y", "z"]).to_csv(
        out / "kepler51_rebound_positions.csv", index=False, float_format="%.14e")
    print(f"\nwrote {out / 'kepler51_rebound_transits.csv'}, {out / 'kepler51_rebound_positions.csv'}, "
          f"{write_double_transit()} and {write_strong_ttv()}")


if __name__ == "__main__":
    main()
