"""The paper's obliquity scan on the bundled data, from the Python API.

    python examples/scan_kepler20.py --out scan_api --step 1
"""

import argparse

import jax

jax.config.update("jax_enable_x64", True)

from jaxppo._config import load_config  # noqa: E402
from jaxppo._scan import run_scan  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="scan_api")
    ap.add_argument("--step", type=float, default=1.0, help="alpha step [deg]")
    args = ap.parse_args(argv)
    cfg = load_config(None)  # the bundled default
    cfg.alpha = cfg.alpha[:: max(1, int(round(args.step / (cfg.alpha[1] - cfg.alpha[0]))))]
    cfg.raw["scan"]["alpha"] = [0.0, 360.0, float(cfg.alpha[1] - cfg.alpha[0])]
    res = run_scan(cfg, args.out, progress=False)
    for case, geo in res["probabilities"].items():
        names = [k for k, v in geo.items() if isinstance(v, dict)]
        print(f"{case}: " + ", ".join(f"{n} {100 * geo[n]['probability']:.1f} %" for n in names)
              + f"; Bayes factor {geo['bayes_factor']:.2f} ({geo['jeffreys']})")
    return res


if __name__ == "__main__":
    main()
