"""jaxppo.compilation_cache: a Python user's second process loads the
programs the first compiled (the folder holds them; JAX reports the hits),
JAXPPO_CACHE=0 leaves JAX's settings alone."""

import os
import subprocess
import sys

SCRIPT = """
import sys, logging
import jax
import jaxppo as jp
print("folder", jp.compilation_cache(sys.argv[1]))
hits = []
class Hits(logging.Handler):
    def emit(self, record):
        if "cache hit" in record.getMessage().lower():
            hits.append(record.getMessage())
logging.getLogger("jax._src.compiler").addHandler(Hits())
logging.getLogger("jax._src.compiler").setLevel(logging.DEBUG)
jax.config.update("jax_enable_x64", True)
star = jp.Star.quadratic(0.4, 0.26)
print("flux", float(jp.occultation_flux(star, 0.1, 0.2, 0.1)))
print("hits", len(hits))
from jaxppo.model._programs import counts
print("stored", counts["loaded"], counts["compiled"])
print("dir", jax.config.jax_compilation_cache_dir)
if len(sys.argv) > 2:  # a second folder: the programs compiled from now on go there
    print("moved", jp.compilation_cache(sys.argv[2]))
    print("flux2", float(jp.occultation_flux(star, jax.numpy.array([0.3, 0.1]), 0.2, 0.05)))
"""


def _run(tmp_path, *more, **env):
    env = dict(os.environ, JAX_PLATFORMS="cpu", **env)
    run = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "cache"), *more], capture_output=True,
                         text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    return dict(line.split(" ", 1) for line in run.stdout.splitlines())


def test_a_second_process_loads_what_the_first_compiled(tmp_path):
    first = _run(tmp_path, JAXPPO_CACHE="1")
    assert first["folder"] == str(tmp_path / "cache") == first["dir"]
    assert any((tmp_path / "cache").iterdir())
    second = _run(tmp_path, JAXPPO_CACHE="1")  # (the first hits its own cache where it builds a program twice)
    assert int(second["hits"]) > int(first["hits"]) and second["flux"] == first["flux"]
    # jaxppo's stored programs (the star's profile check, the kernels): the
    # second process loads every one the first compiled, and compiles none
    loaded, compiled = (int(v) for v in first["stored"].split())
    assert loaded == 0 and compiled > 0
    assert second["stored"].split() == [str(compiled), "0"]
    moved = _run(tmp_path, "~/../" + str(tmp_path / "other"), JAXPPO_CACHE="1")  # "~" expanded
    assert moved["moved"] == str(tmp_path / "other") and any((tmp_path / "other").iterdir())
    off = _run(tmp_path, JAXPPO_CACHE="0")
    assert off["folder"] == "None" and off["dir"] == "None" and off["flux"] == first["flux"]
