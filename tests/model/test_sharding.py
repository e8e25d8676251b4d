"""Sharding over devices: the same numbers on 4 forced host devices as on one.

"auto" and "exact" place the frame axis of every padded call across all
devices (jaxppo.model._plan._shard); a user's jitted model may shard its own
inputs. A subprocess with XLA_FLAGS=--xla_force_host_platform_device_count=4
computes them, and this process (one device) the same; the sweep's own check
is tests/model/test_sweep.py::test_sharded_equals_unsharded.
"""

import os
import subprocess
import sys
import textwrap

import jax
import numpy as np

import jaxppo as jp

CODE = textwrap.dedent(r"""
    import sys
    import jax, numpy as np
    jax.config.update("jax_enable_x64", True)
    import jaxppo as jp
    import jaxppo.model._plan
    sys.path.insert(0, sys.argv[2])
    from test_sharding import scene, draws_grid, results
    ndev = jax.device_count()
    assert ndev == int(sys.argv[3]), jax.devices()
    np.savez(sys.argv[1], ndev=ndev, **results(sharded=ndev > 1))
""")


def scene(n=3000, seed=0):
    """Overlapping pairs anywhere on and around the star, a third disk
    crossing some of them: every path of "auto" (midpoint, general, three
    lens tiers, union integral)."""
    rng = np.random.default_rng(seed)
    x1, y1 = rng.uniform(-1.0, 1.0, n), rng.uniform(-0.6, 0.6, n)
    r = rng.uniform(0.01, 0.15, (n, 3))
    ang = rng.uniform(0, 2 * np.pi, n)
    sep = rng.uniform(np.abs(r[:, 0] - r[:, 1]), r[:, 0] + r[:, 1] + 0.02)
    x = np.stack([x1, x1 + sep * np.cos(ang), x1 + rng.uniform(-0.3, 0.3, n)], 1)
    y = np.stack([y1, y1 + sep * np.sin(ang), y1 + rng.uniform(-0.3, 0.3, n)], 1)
    return x, y, r


def degenerate():
    """The degenerate classes of tests/model/test_properties.py as a fixed
    grid of pairs: a first disk at each special distance b in {0, p, 1 - p,
    1, 1 + p} (each nudged by 0, +-1e-15, +-1e-9) for radii from 1e-4 to
    1.5, and a second disk tangent, inside, concentric or identical to it."""
    rows = []
    for p in (1e-4, 0.01, 0.1, 0.5, 0.99, 1.0, 1.5):
        for d in (0.0, p, abs(1.0 - p), 1.0, 1.0 + p):
            for nudge in (0.0, 1e-15, -1e-15, 1e-9, -1e-9):
                b = max(d + nudge, 0.0)
                for q, sep in ((0.05, p + 0.05), (0.5 * p, 0.5 * p), (0.3, 0.0), (p, 0.0), (0.01, 7.0)):
                    rows.append(((b, b + sep * 0.6), (0.0, sep * 0.8), (p, q)))
    x, y, r = (np.array([row[k] for row in rows]) for k in range(3))
    return x, y, r


def draws_grid():
    from jaxppo.model._kepler20 import kepler20_system, paper_multi_transits

    system = kepler20_system()
    ev = paper_multi_transits(system)[0]
    t = np.arange(ev.start - 0.05, ev.end + 0.05, 1 / 1440)[::3]
    systems = [system.replace(planets=[p.replace(t0=p.t0 + dt) for p in system.planets]) for dt in (0.0, 3e-4)]
    return systems, t, np.arange(0.0, 360.0, 4.0)


def results(sharded: bool) -> dict:
    import jaxppo.model._plan
    from jaxppo.obliquity._marginal import marginal_chi2

    star = jp.kepler20_star()
    x, y, r = scene()
    saved, jaxppo.model._plan.LENS_MIN_PAIRS = jaxppo.model._plan.LENS_MIN_PAIRS, 0  # the lens path on these small calls too
    try:
        out = {
            "auto": np.asarray(jp.occultation_flux(star, x, y, r, chunk=1024)),
            "exact": np.asarray(jp.occultation_flux(star, x, y, r, method="exact", chunk=1024)),
        }
    finally:
        jaxppo.model._plan.LENS_MIN_PAIRS = saved
    xd, yd, rd = degenerate()
    out["degenerate_auto"] = np.asarray(jp.occultation_flux(star, xd, yd, rd, chunk=1024))
    out["degenerate_exact"] = np.asarray(jp.occultation_flux(star, xd, yd, rd, method="exact", chunk=1024))
    args = (x, y, r)
    if sharded:
        from jax.sharding import Mesh, NamedSharding, PartitionSpec

        spec = NamedSharding(Mesh(np.array(jax.devices()), ("frames",)), PartitionSpec("frames"))
        args = tuple(jax.device_put(v, spec) for v in args)
    out["jitted"] = np.asarray(jax.jit(lambda a, b, c: jp.occultation_flux(star, a, b, c))(*args))
    # vmapped (the batch axis sharded): the union integral, and the device
    # plan's derivatives (jaxppo.model._flux.device_auto)
    batched = tuple(np.reshape(v, (300, 10, 3)) for v in (x, y, r))
    if sharded:
        batched = tuple(jax.device_put(v, spec) for v in batched)
    one = lambda a, b, c: jp.occultation_flux(star, a, b, c)
    out["vmapped"] = np.asarray(jax.jit(jax.vmap(one))(*batched))
    grad = jax.vmap(jax.grad(lambda a, b, c: one(a, b, c).sum()))
    out["vmapped_grad"] = np.asarray(jax.jit(grad)(*(v[:8] for v in batched)))
    systems, t, alpha = draws_grid()
    chi2, chi2_null, _ = marginal_chi2(systems, t, 1, np.ones(t.size), np.full(t.size, 1e-4), alpha, ("same", "opposite"))
    out["chi2"], out["chi2_null"] = chi2, chi2_null
    # the joint sampler's particle batches (mapped_over_devices): the model's
    # kernels per point (their closed-over constants once failed shard_map's
    # varying-axes check); 10 points, padded to 12 on 4 devices
    from jaxppo.inference._mapped import mapped_over_devices

    one_frame = lambda a, b, c: jp.occultation_flux(star, a[None], b[None], c[None])[0]
    out["particles"] = mapped_over_devices(one_frame)(x[:10], y[:10], r[:10])
    return out


def test_four_devices_equal_one(tmp_path):
    from helpers import one_device_env

    # the XLA flags this process runs with (such as .ci/run's optimisation level), and four devices
    env = one_device_env()
    env["XLA_FLAGS"] = (env["XLA_FLAGS"] + " --xla_force_host_platform_device_count=4").strip()
    path = tmp_path / "sharded.npz"
    here = os.path.dirname(os.path.abspath(__file__))
    subprocess.run([sys.executable, "-c", CODE, str(path), here, "4"], check=True, env=env, timeout=600)
    assert jax.device_count() == 1
    one = results(sharded=False)
    got = np.load(path)
    assert int(got["ndev"]) == 4
    for key, ref in one.items():
        np.testing.assert_allclose(got[key], ref, rtol=1e-12, atol=1e-12, err_msg=key)
    # the scene exercised the lens path and the union integral, and the draws
    # grid has planet-planet occultations (chi^2 varies with alpha)
    assert np.max(np.abs(one["auto"] - one["exact"])) > 0
    # vmapped "auto" is the union integral
    np.testing.assert_allclose(one["vmapped"].reshape(-1), one["exact"], rtol=0, atol=1e-15)
    assert np.ptp(one["chi2"]) > 0
