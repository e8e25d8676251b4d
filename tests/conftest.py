import os
import sys
import tempfile
from pathlib import Path

import jax

# The CLI turns on JAX's persistent compilation cache for the whole process.
# Tests call the CLI in-process, and later tests then wrote every executable
# to that cache: jax 0.10.2's cache reader aborted and its writer segfaulted
# in such long processes (two CI runs, different tests each time). The suite
# runs without it; test_persistent_compilation_cache switches it on in its
# own subprocesses, with a folder of its own.
os.environ["JAXPPO_CACHE"] = "0"
os.environ.setdefault("JAXPPO_CACHE_DIR", tempfile.mkdtemp(prefix="jaxppo_test_cache_"))

# `jaxppo scan` draws its figures in a second process (obliquity/_worker.py);
# the tests' in-process scans draw them here (each second process would
# import JAX again beside the other xdist worker), except
# tests/obliquity/test_worker.py, which compares both ways byte for byte
os.environ["JAXPPO_DRAW_PROCESS"] = "0"

jax.config.update("jax_enable_x64", True)

# tests/ mirrors the package (tests/core, tests/model, ...); their shared
# helpers live in tests/helpers.py
sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_configure(config):
    """In the controlling process (not in an xdist worker): import arviz once,
    so that its once-a-day warning stamp (~/.cache/arviz/daily_warning) is
    written before the workers start; two workers importing it at the same
    moment on a new day race on the stamp's atomic rename and one fails to
    collect (seen in CI at midnight)."""
    if hasattr(config, "workerinput"):
        return
    try:
        import arviz  # noqa: F401
    except Exception:  # arviz missing or broken: the tests that need it say so themselves
        pass



def pytest_collection_modifyitems(config, items):
    """Mark each test under tests/inference ``inference``: .ci/run runs
    those at XLA's optimisation level 0 except the ones marked
    ``runs_programs`` or ``default_codegen``, which it runs with the
    workflows at XLA's defaults (``-m "not inference or runs_programs or
    default_codegen"``)."""
    for item in items:
        if Path(str(item.fspath)).resolve().parent.name == "inference":
            item.add_marker("inference")
