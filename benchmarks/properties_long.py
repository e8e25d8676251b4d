"""The property-based tests (tests/model/test_properties.py) in their long
profile: K times the CI's examples (default 20), fresh random draws each run
instead of CI's fixed ones (--scale 1 is the CI's run itself, fixed draws).
Run before a release or after a change to the flux engine, the raster or the
unit handling:

    python benchmarks/properties_long.py [--scale 20]

Prints pytest's summary; exit status that of pytest (0: every property held).
"""

import argparse
import os
import subprocess
import sys
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=int, default=20, help="examples per test, times the CI's (default 20; 1: the CI's fixed draws)")
    args = ap.parse_args(argv)
    if args.scale < 1:
        raise SystemExit(f"--scale must be >= 1, got {args.scale}")
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, JAXPPO_HYPOTHESIS_SCALE=str(args.scale))
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(root / "tests" / "model" / "test_properties.py")]
    return subprocess.call(cmd, env=env, cwd=root)


if __name__ == "__main__":
    sys.exit(main())
