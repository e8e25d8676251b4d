"""Command line: ``jaxppo demo`` (and the workflows as they land)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def _enable_x64() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)


def cmd_demo(args) -> int:
    """Light curves of the seven Kepler-20 b + c double transits for a few tilt
    angles, both hemisphere cases; writes a CSV and a figure."""
    _enable_x64()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import jaxppo as jp

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from jaxppo._kepler20 import kepler20_system, paper_multi_transits

    system = kepler20_system()
    events = paper_multi_transits(system)
    alphas = np.array([0.0, 90.0, 151.0, 212.0, 249.0, 313.0, 322.0])
    t0 = time.perf_counter()
    rows = []
    fig, axes = plt.subplots(2, len(events), figsize=(3.0 * len(events), 5.5), sharey=True)
    for ci, case in enumerate(("same", "opposite")):
        for ei, ev in enumerate(events):
            t = np.arange(ev.start - 0.05, ev.end + 0.05, 1.0 / 1440.0)
            flux = np.asarray(system.flux(t, alpha=alphas, case=case))
            ax = axes[ci, ei]
            for ai, a in enumerate(alphas):
                ax.plot((t - ev.mid) * 24, (flux[ai] - 1) * 1e6, lw=0.8, label=f"{a:.0f}" if ei == 0 else None)
                rows += [(case, ev.number, a, ti, fi) for ti, fi in zip(t, flux[ai])]
            ax.set_title(f"{case}: BKJD {ev.mid:.2f}", fontsize=8)
            ax.set_xlabel("hours from mid")
    axes[0, 0].set_ylabel("flux - 1 [ppm]")
    axes[1, 0].set_ylabel("flux - 1 [ppm]")
    axes[0, 0].legend(title="alpha [deg]", fontsize=6)
    fig.tight_layout()
    fig.savefig(out / "kepler20_double_transits.png", dpi=110)
    elapsed = time.perf_counter() - t0
    with open(out / "kepler20_double_transits.csv", "w") as fh:
        fh.write("case,event,alpha,time,flux\n")
        for r in rows:
            fh.write(f"{r[0]},{r[1]},{r[2]:.1f},{r[3]:.6f},{r[4]:.12f}\n")
    summary = {"events": [e.as_dict() for e in events], "alphas": alphas.tolist(), "seconds": elapsed,
               "alpha_limits": list(jp.alpha_limits(system))}
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(f"wrote {out}/kepler20_double_transits.png, .csv and summary.json ({len(rows)} model points, {elapsed:.2f} s)")
    return 0


def _print_summary(result) -> None:
    for case, geo in result["probabilities"].items():
        print(f"case {case}: chi2_0 = {result['chi2_0'][case]:.3f}")
        for name, v in geo.items():
            if isinstance(v, dict):
                print(f"   {name:36s} p = {100 * v['probability']:6.2f} %   sum(dchi2 > 0) = {v['sum_positive_delta_chi2']:.2f}")
        print(f"   Bayes factor {geo['bayes_factor']:.3f} for '{geo['favoured']}': {geo['jeffreys']}")


def cmd_scan(args) -> int:
    """Run the obliquity scan; no config runs the bundled default."""
    _enable_x64()
    from jaxppo._config import load_config
    from jaxppo._scan import run_scan

    cfg = load_config(args.config)
    t0 = time.perf_counter()
    result = run_scan(cfg, args.out, restart=args.restart, progress=not args.quiet)
    print(f"scanned {len(cfg.cases)} case(s) x {cfg.alpha.size} alphas over {len(result['multi_transits'])} "
          f"multi-transits ({result['points']} points) in {time.perf_counter() - t0:.2f} s")
    _print_summary(result)
    print(f"wrote {Path(args.out) / 'scan.csv'}, summary.json and {len(result.get('figures', []))} figures")
    return 0


def cmd_plot(args) -> int:
    """Redraw the figures of a finished scan from DIR/scan.csv and its config."""
    _enable_x64()
    from jaxppo._config import load_config
    from jaxppo._figures import scan_figures

    out = Path(args.dir)
    for name in ("summary.json", "scan.csv"):
        if not (out / name).exists():
            raise ValueError(f"{out} holds no finished scan ({name} missing)")
    summary = json.loads((out / "summary.json").read_text())
    cfg = load_config(summary["config"])
    if cfg.digest != summary["config_digest"]:
        raise ValueError(f"the config {summary['config']} changed since the scan in {out}; rerun the scan")
    files = scan_figures(cfg, out, summary)
    print("wrote " + ", ".join(files))
    return 0


def cmd_simulate(args) -> int:
    """Write synthetic Kepler-20 b + c photometry (the bundled default data)."""
    _enable_x64()
    import jaxppo as jp

    lc = jp.simulate_kepler20(seed=args.seed, noise=args.noise, alpha=args.alpha, case=args.case,
                              radius_scale=args.radius_scale)
    lc.to_csv(args.out)
    print(f"wrote {args.out}: {len(lc)} points, noise {args.noise}, alpha {args.alpha}, case {args.case}, radius x{args.radius_scale}")
    return 0


def _fit_inputs(args):
    from jaxppo._config import load_config

    cfg = load_config(args.config)
    lc = cfg.lightcurve
    if args.windows:
        from jaxppo._scan import scan_events

        keep = np.zeros(len(lc), bool)
        for _, s in scan_events(cfg):
            keep |= s
        lc = lc.select(keep)
    return cfg, lc


def cmd_fit(args) -> int:
    """Least-squares fit of the config's system to its data."""
    _enable_x64()
    import jaxppo as jp

    cfg, lc = _fit_inputs(args)
    t0 = time.perf_counter()
    res = jp.fit(cfg.system, lc, free=tuple(args.free))
    print(res.table())
    print(f"{len(lc)} points, {time.perf_counter() - t0:.1f} s")
    if args.out:
        Path(args.out).write_text(json.dumps({
            "names": list(res.names), "values": res.values.tolist(), "errors": res.errors.tolist(),
            "covariance": res.covariance.tolist(), "chi2": res.chi2, "reduced_chi2": res.reduced_chi2,
            "success": res.success, "message": res.message}, indent=2))
        print(f"wrote {args.out}")
    return 0 if res.success else 1


def cmd_sample(args) -> int:
    """NUTS over the config's system and data."""
    _enable_x64()
    import jaxppo as jp

    cfg, lc = _fit_inputs(args)
    if args.netcdf:
        try:
            import arviz  # noqa: F401
        except ImportError:
            raise ValueError("--netcdf needs arviz: pip install 'jaxppo[arviz]'") from None
        if not Path(args.netcdf).resolve().parent.is_dir():
            raise ValueError(f"--netcdf: folder {str(Path(args.netcdf).parent)!r} does not exist")
    res = jp.sample(cfg.system, lc, free=tuple(args.free), num_warmup=args.warmup, num_samples=args.samples,
                    seed=args.seed, num_chains=args.chains, progress_bar=not args.quiet)
    for n, (med, lo, hi) in res.intervals.items():
        d = res.diagnostics[n]
        print(f"{n:12s} {med:.8f} +{hi - med:.2e} -{med - lo:.2e}   r_hat {d['r_hat']:.3f}  "
              f"ess bulk {d['ess_bulk']:.0f} tail {d['ess_tail']:.0f}")
    div = int(np.sum(res.stats["diverging"]))
    print(f"{args.chains} chains x {args.samples} draws, {div} divergent transitions")
    if args.out:
        np.savez(args.out, **{k.replace(".", "_"): v for k, v in res.samples.items()})
        print(f"wrote {args.out}")
    if args.netcdf:
        res.to_netcdf(args.netcdf)
        print(f"wrote {args.netcdf} (arviz.from_netcdf reads it)")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="jaxppo", description="Planet-planet occultations in JAX")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("scan", help="orbital obliquity scan: chi^2(alpha), posterior, geometry probabilities, figures")
    p.add_argument("config", nargs="?", default=None, help="CONFIG.toml (default: the bundled Kepler-20 scan)")
    p.add_argument("--out", default="scan_out", help="output folder (default: scan_out)")
    p.add_argument("--restart", action="store_true", help="discard earlier results in --out instead of resuming")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_scan)
    for name, func, helptext in (("fit", cmd_fit, "least-squares fit (optimistix) of a config's planets to its data"),
                                 ("sample", cmd_sample, "MCMC (numpyro NUTS) of a config's planets")):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("config", nargs="?", default=None, help="CONFIG.toml (default: the bundled Kepler-20 set)")
        p.add_argument("--free", nargs="+", default=["b.t0", "b.radius", "c.t0", "c.radius"],
                       help="free parameters, e.g. b.t0 b.radius b.a b.inc c.t0 star.c1")
        p.add_argument("--windows", action="store_true", help="use only the multi-transit windows of the data")
        p.add_argument("--out", default=None, help="write results (fit: JSON, sample: .npz)")
        if name == "sample":
            p.add_argument("--warmup", type=int, default=1000)
            p.add_argument("--samples", type=int, default=1000)
            p.add_argument("--chains", type=int, default=4, help="chains, run vectorised (default 4)")
            p.add_argument("--seed", type=int, default=0)
            p.add_argument("--quiet", action="store_true")
            p.add_argument("--netcdf", default=None, metavar="PATH",
                           help="write the posterior, log-likelihood, sample stats and data as arviz netCDF")
        p.set_defaults(func=func)
    p = sub.add_parser("plot", help="redraw the figures of a finished scan")
    p.add_argument("dir", help="the scan's output folder")
    p.set_defaults(func=cmd_plot)
    p = sub.add_parser("simulate", help="write synthetic Kepler-20 b + c data (CSV)")
    p.add_argument("--out", required=True)
    p.add_argument("--seed", type=int, default=2021)
    p.add_argument("--noise", type=float, default=4e-4)
    p.add_argument("--alpha", type=float, default=None, help="inject this tilt [deg] (default: untilted)")
    p.add_argument("--case", default="same", choices=("same", "opposite"))
    p.add_argument("--radius-scale", type=float, default=1.0)
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("demo", help="Kepler-20 b + c double-transit light curves for a few tilt angles")
    p.add_argument("--out", default="jaxppo_demo", help="output folder")
    p.set_defaults(func=cmd_demo)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ValueError as err:
        print(f"jaxppo {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
