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


# The slowest tests (seconds on this project's 2-core CI machine, from
# pytest --durations): started first, dealt alternately to the two halves of
# the collection that pytest-xdist's work-stealing scheduler gives its two
# workers, so that no long test starts last and runs alone while the other
# worker idles. Tests not listed keep their order after them.
SLOW_FIRST = Path(__file__).with_name("slow_tests.txt")


def pytest_collection_modifyitems(session, config, items):
    """Order ``items`` longest first, alternating between the workers'
    halves (``SLOW_FIRST``); a no-op outside pytest-xdist."""
    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT") or getattr(config.option, "numprocesses", None)
    if not workers or not SLOW_FIRST.is_file():
        return
    seconds = {}
    for line in SLOW_FIRST.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            s, nodeid = line.split(maxsplit=1)
            seconds[nodeid.strip()] = seconds.get(nodeid.strip(), 0.0) + float(s)  # setup + call
    slow = sorted((it for it in items if it.nodeid in seconds), key=lambda it: -seconds[it.nodeid])
    rest = [it for it in items if it.nodeid not in seconds]
    k = int(workers) if str(workers).isdigit() else 2
    halves = [slow[i::k] + rest[i::k] for i in range(k)]
    items[:] = [it for h in halves for it in h]
