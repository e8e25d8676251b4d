"""The paper's obliquity scan on the bundled real Kepler-20 long-cadence
data, from the public Python API.

    python examples/scan_kepler20.py --out scan_api --step 1
"""

import argparse

import jax

jax.config.update("jax_enable_x64", True)


import jaxppo as jp  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="scan_api")
    ap.add_argument("--step", type=float, default=1.0, help="alpha step [deg] (must divide 360)")
    args = ap.parse_args(argv)
    # the bundled default: real Kepler-20 long cadence, Table 3 "This work", with its [scan] settings (the
    # eight clean double transits: multi_transits leaves out the b + c + e triple at BKJD 160.33)
    cfg = jp.load_config(alpha=[0.0, 360.0, args.step])
    res = jp.scan(cfg, out=args.out, figures=True)
    print(f"{res.summary['points']} points in {len(res.summary['multi_transits'])} multi-transits, chi2_0 = {res.chi2_0['same']:.1f}")
    for case, geo in res.probabilities.items():
        names = [k for k, v in geo.items() if isinstance(v, dict)]
        print(f"{case}: " + ", ".join(f"{n} {100 * geo[n]['probability']:.2f} %" for n in names)
              + f"; Bayes factor 10^{geo['log10_bayes_factor']:.3f} ({geo['jeffreys']})")
    res.plot().figure.savefig(f"{args.out}/delta_chi2_api.png", dpi=110)
    return res


if __name__ == "__main__":
    main()
