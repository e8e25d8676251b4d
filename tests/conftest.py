import os
import sys
import tempfile
from pathlib import Path

import jax

# The CLI turns on JAX's persistent compilation cache (~/.cache/jaxppo/jax) for
# the whole process; tests that call it must not read executables that other
# runs and other code versions left there (a stale entry aborted the process
# in jax's cache reader). Each test session gets a cache of its own.
os.environ.setdefault("JAXPPO_CACHE_DIR", tempfile.mkdtemp(prefix="jaxppo_test_cache_"))

jax.config.update("jax_enable_x64", True)

# tests/ mirrors the package (tests/core, tests/model, ...); their shared
# helpers live in tests/helpers.py
sys.path.insert(0, str(Path(__file__).resolve().parent))
