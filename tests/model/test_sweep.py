"""Batched [case, alpha, time] sweeps: auto equals exact, chunking and
sharding change nothing."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.model._kepler20 import kepler20_system


@pytest.fixture(scope="module")
def grid():
    system = kepler20_system()
    ev = [e for e in jp.multi_transits(system, 800, 900)][0]
    t = np.arange(ev.start - 0.05, ev.end + 0.05, 2.0 / 1440.0)
    alpha = np.arange(60.0, 120.0, 1.0)
    return system, t, alpha


def test_sweep_equals_exact(grid):
    system, t, alpha = grid
    flux, stats = jp.sweep(system, t, alpha, return_stats=True)
    assert flux.shape == (2, alpha.size, t.size)
    assert stats.union > 0  # the grid contains PPOs
    for ci, case in enumerate(("same", "opposite")):
        exact = np.asarray(system.flux(t, alpha, case=case, method="exact"))
        assert np.max(np.abs(flux[ci] - exact)) < 1e-13


def test_only_ppo_frames_depend_on_alpha(grid):
    system, t, alpha = grid
    flux = jp.sweep(system, t, alpha)
    varies = np.any(flux != flux[:, :1, :], axis=1)
    x, y, r = (np.asarray(v) for v in system.positions(t[None, :], alpha[:, None], "same"))
    overlap = (np.hypot(x[..., 0] - x[..., 1], y[..., 0] - y[..., 1]) < r.sum(-1)).any(0)
    assert np.all(~varies[0] | overlap)


def test_chunking_gives_same_numbers(grid):
    system, t, alpha = grid
    a = jp.sweep(system, t, alpha)
    b = jp.sweep(system, t, alpha, chunk=7)
    # the same numbers up to the last bit that XLA's code for another batch
    # size may round differently
    np.testing.assert_allclose(a, b, rtol=0, atol=4e-16)


def test_sharded_equals_unsharded(grid, tmp_path):
    system, t, alpha = grid
    ref = jp.sweep(system, t, alpha)
    np.save(tmp_path / "t.npy", t)
    np.save(tmp_path / "a.npy", alpha)
    code = textwrap.dedent(f"""
        import jax, numpy as np
        jax.config.update("jax_enable_x64", True)
        assert jax.device_count() == 4, jax.devices()
        import jaxppo as jp
        from jaxppo.model._kepler20 import kepler20_system
        t = np.load(r"{tmp_path / 't.npy'}"); a = np.load(r"{tmp_path / 'a.npy'}")
        np.save(r"{tmp_path / 'out.npy'}", jp.sweep(kepler20_system(), t, a, chunk=33))
    """)
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4", JAX_PLATFORMS="cpu")
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=600)
    np.testing.assert_allclose(np.load(tmp_path / "out.npy"), ref, atol=1e-15, rtol=0)


def test_auto_gradients_finite(grid):
    import jax
    import jax.numpy as jnp

    system, t, _ = grid

    def f(radius):
        pl = system.planets[0].replace(radius=radius)
        return jnp.sum(system.replace(planets=(pl, system.planets[1])).flux(jnp.asarray(t), 90.0))

    # under jit: the same device plan as an eager grad (the positions are
    # tracers either way), one compilation instead of one per primitive and
    # control-flow branch (22 s eager, 7 s jitted); the eager grad of
    # System.flux is tests/model/test_system.py::test_system_flux_gradient
    g = jax.jit(jax.grad(f))(jnp.asarray(0.018))
    assert np.isfinite(float(g))


def test_bad_sweep_inputs(grid):
    system, t, alpha = grid
    with pytest.raises(ValueError, match="case"):
        jp.sweep(system, t, alpha, cases=("same", "upside-down"))
    with pytest.raises(ValueError, match="finite"):
        jp.sweep(system, np.array([np.nan]), alpha)


def test_one_million_frames_stay_under_2gb():
    code = textwrap.dedent("""
        import jax, numpy as np
        jax.config.update("jax_enable_x64", True)
        import jaxppo as jp
        from jaxppo.model._kepler20 import kepler20_system, paper_multi_transits
        system = kepler20_system()
        t = np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1 / 1440) for e in paper_multi_transits(system)])[:1400]
        out = jp.sweep(system, t, np.arange(0.0, 360.0), chunk=16384)
        assert out.size >= 1_000_000
        # VmHWM: this process image's peak resident memory (ru_maxrss would
        # also count the forked parent's memory before exec)
        hwm = [l for l in open("/proc/self/status") if l.startswith("VmHWM")][0]
        print(int(hwm.split()[1]))
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=True)
    peak_kb = int(proc.stdout.strip().splitlines()[-1])
    assert peak_kb < 2 * 1024 * 1024, f"peak resident memory {peak_kb / 1024:.0f} MB"


def test_sweep_stats_is_a_frozen_dataclass():
    """SweepStats has fields; dict access still works this release, with a
    DeprecationWarning, and an unknown key is a KeyError."""
    import dataclasses
    import warnings

    from jaxppo.model._sweep import SweepStats

    stats = SweepStats(frames=6, single=2, union=1)
    assert (stats.frames, stats.single, stats.union) == (6, 2, 1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        stats.union = 3
    with pytest.warns(DeprecationWarning, match="stats.union"):
        assert stats["union"] == 1
    with pytest.raises(KeyError):
        stats["diverging"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        assert dataclasses.asdict(stats) == {"frames": 6, "single": 2, "union": 1}


def test_sweep_mirrors_a_planet_with_a_node_as_system_flux_does():
    """A scan of case "opposite" with an untilted planet of nonzero lnode
    mirrored the node-turned position (y' -> -y') while System.flux mirrors
    before turning: the two light curves differed by 0.011 (the config's
    lnode key reaches the scan). Also an untilted pair that meets only in
    the mirrored case, with nodes."""
    star = jp.Star.quadratic(0.4, 0.25)
    b = jp.Planet(3.0, 0.0, 10.0, 89.0, 0.1, name="b")
    c = jp.Planet(10.0, 0.0, 20.0, 89.5, 0.1, name="c", lnode=30.0)
    d = jp.Planet(14.0, 0.004, 25.0, 89.7, 0.08, name="d", lnode=-50.0)
    t = np.linspace(-0.08, 0.08, 41)
    alpha = np.arange(0.0, 360.0, 20.0)
    for system in (jp.System(star, [b, c], tilted="b"), jp.System(star, [b, c, d], tilted="b")):
        cases = ("same", "opposite") if len(system.planets) == 2 else ("same", "opposite", "+-", "-+")
        for case in cases:
            got = jp.sweep(system, t, alpha, cases=case)[0]
            want = np.asarray(system.flux(t, alpha, case=case))
            assert np.abs(got - want).max() < 1e-14, (len(system.planets), case, np.abs(got - want).max())


def test_no_overlap_holds_for_every_method_and_a_spotted_star():
    """sweep(no_overlap=True) with method "exact" or "raster", or on a star
    with spots (whose flux takes the non-"auto" path), returned the full
    model with the planet-planet overlap (1.2e-2 off at the overlap); the
    PPO-or-spot verdict of a spotted star then compared the PPO model with
    itself. Now every path gives the model without overlaps: the star's
    own flux plus each disk's own dip."""
    b = jp.Planet(period=3.0, t0=0.0, a=10.0, inc=90.0, radius=0.1, name="b")
    c = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=90.0, radius=0.1, name="c")
    star = jp.Star.quadratic(0.4, 0.25)
    system = jp.System(star, [b, c], tilted="b")
    t = np.array([-0.03, 0.0, 0.02])
    auto = np.asarray(jp.sweep(system, t, [0.0, 90.0], cases=("same", "opposite"), no_overlap=True))
    with_overlap = np.asarray(jp.sweep(system, t, [0.0], cases="same"))
    assert with_overlap[0, 0, 1] - auto[0, 0, 1] > 0.01  # the overlap at t = 0 (two disks, concentric)
    # without overlaps: 1 - the two planets' own dips, whatever the tilt and case
    alone = [1.0 - np.asarray(jp.System(star, [p]).flux(t, method="exact")) for p in (b, c)]
    np.testing.assert_allclose(auto, np.broadcast_to(1.0 - alone[0] - alone[1], auto.shape), atol=1e-13)
    exact = np.asarray(jp.sweep(system, t, [0.0, 90.0], cases=("same", "opposite"), method="exact", no_overlap=True))
    np.testing.assert_allclose(exact, auto, atol=1e-13)
    raster = np.asarray(jp.sweep(system, t, [0.0, 90.0], cases=("same", "opposite"), method="raster",
                                 no_overlap=True))
    np.testing.assert_allclose(raster, auto, atol=1e-6)
    # a tiny spot on the far side changes the no-overlap model by ~1e-7, not by the overlap
    spotted = star.with_spots(lat=[80.0], lon=[180.0], radius=[1.0], contrast=[0.01], period=25.0, inc=90.0)
    far = np.asarray(jp.sweep(jp.System(spotted, [b, c], tilted="b"), t, [0.0], cases="same", no_overlap=True))
    np.testing.assert_allclose(far, auto[:1, :1], atol=1e-6)
