import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

# tests/ mirrors the package (tests/core, tests/model, ...); their shared
# helpers live in tests/helpers.py
sys.path.insert(0, str(Path(__file__).resolve().parent))
