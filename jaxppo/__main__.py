"""``python -m jaxppo``: the ``jaxppo`` command (``jaxppo.cli.run``), for an
environment whose scripts folder is not on the PATH."""

import sys

from jaxppo.cli import run

if __name__ == "__main__":
    sys.exit(run())
