"""Inject a planet-planet occultation into synthetic data and recover its
tilt angle with the scan (noise 1e-4, planets enlarged).

    python examples/injected_ppo.py --alpha 151 --case same --scale 2
"""

import argparse
import tempfile
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxppo as jp  # noqa: E402
from jaxppo._config import load_config  # noqa: E402
from jaxppo._scan import run_scan  # noqa: E402

TEMPLATE = Path(jp.__file__).parent / "data" / "kepler20_synthetic.toml"


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--alpha", type=float, default=151.0)
    ap.add_argument("--case", default="same", choices=("same", "opposite"))
    ap.add_argument("--scale", type=float, default=2.0, help="planet radius scale")
    ap.add_argument("--noise", type=float, default=1e-4)
    ap.add_argument("--step", type=float, default=1.0, help="alpha step [deg] (the grid spans 0..360)")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="jaxppo_inject_"))
    lc = jp.simulate_kepler20(seed=1, noise=args.noise, alpha=args.alpha, case=args.case, radius_scale=args.scale)
    lc.to_csv(work / "data.csv")
    text = TEMPLATE.read_text().replace("kepler20_synthetic_bc.csv", str(work / "data.csv"))
    text = text.replace("radius = 0.01805", f"radius = {0.01805 * args.scale}").replace("radius = 0.02878", f"radius = {0.02878 * args.scale}")
    text = text.replace("alpha = [0.0, 360.0, 1.0]", f"alpha = [0.0, 360.0, {args.step}]")
    (work / "scan.toml").write_text(text)
    res = run_scan(load_config(work / "scan.toml"), work / "out", progress=False, figures=False)
    for case in ("same", "opposite"):
        m = res["cases"][case]["min_delta_chi2"]
        print(f"case {case}: min Delta chi^2 = {m['value']:.1f} at alpha = {m['alpha']:g} deg (injected {args.alpha:g} in case {args.case})")
    return res


if __name__ == "__main__":
    main()
