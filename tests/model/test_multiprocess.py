"""Multi-process JAX (jax.distributed, CPU collectives over gloo): two
processes, one device each, one global mesh; the flux of every path, the
sweep and the marginal scan's chi^2 kernel are the same numbers in every
process as in one process (bit for bit: the frames are split, not the
arithmetic)."""

import os
import socket
import subprocess
import sys
import textwrap

import jax
import numpy as np

WORKER = textwrap.dedent(r"""
    import sys
    import jax
    jax.config.update("jax_enable_x64", True)
    if len(sys.argv) > 3:
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
        jax.distributed.initialize(coordinator_address="127.0.0.1:" + sys.argv[3], num_processes=2,
                                   process_id=int(sys.argv[2]))
    import numpy as np
    sys.path.insert(0, sys.argv[4] if len(sys.argv) > 4 else sys.argv[2])
    import jaxppo as jp
    from test_sharding import draws_grid, scene
    from jaxppo.obliquity._marginal import marginal_chi2

    star = jp.kepler20_star()
    x, y, r = scene(1200)
    out = {"auto": np.asarray(jp.occultation_flux(star, x, y, r, chunk=512)),
           "exact": np.asarray(jp.occultation_flux(star, x, y, r, method="exact", chunk=512))}
    systems, t, alpha = draws_grid()
    out["sweep"] = np.asarray(jp.sweep(systems[0], t, alpha))
    chi2, chi2_null, _ = marginal_chi2(systems, t, 1, np.ones(t.size), np.full(t.size, 1e-4), alpha,
                                       ("same", "opposite"))
    out["chi2"], out["chi2_null"] = chi2, chi2_null
    out["devices"], out["process"] = jax.device_count(), jax.process_index()
    np.savez(sys.argv[1], **out)
""")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_two_processes_equal_one(tmp_path):
    here = os.path.dirname(os.path.abspath(__file__))
    from helpers import one_device_env

    env = one_device_env()
    port = str(_free_port())
    procs = [subprocess.Popen([sys.executable, "-c", WORKER, str(tmp_path / f"p{i}.npz"), str(i), port, here],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
             for i in range(2)]
    logs = [p.communicate(timeout=600)[0] for p in procs]
    assert all(p.returncode == 0 for p in procs), "\n".join(log[-3000:] for log in logs)
    subprocess.run([sys.executable, "-c", WORKER, str(tmp_path / "one.npz"), here], env=env, check=True, timeout=600)
    one = np.load(tmp_path / "one.npz")
    assert int(one["devices"]) == 1
    for i in range(2):
        got = np.load(tmp_path / f"p{i}.npz")
        assert int(got["devices"]) == 2 and int(got["process"]) == i
        for key in ("auto", "exact", "sweep", "chi2", "chi2_null"):
            assert np.array_equal(got[key], one[key]), (i, key, np.max(np.abs(got[key] - one[key])))
    # the scene has planet-planet occultations: the chi^2 depends on alpha
    assert np.ptp(one["chi2"]) > 0 and jax.process_count() == 1
