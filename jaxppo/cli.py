"""Command line: ``jaxppo demo`` (and the workflows as they land)."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from jaxppo.obliquity._config_files import out_file, out_folder

_SYNTHETIC = Path(__file__).resolve().parent / "data" / "kepler20_synthetic.toml"
_FIVE_PLANETS = Path(__file__).resolve().parent / "data" / "kepler20_five_planets.toml"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``jaxppo scan: error: argument
    --alpha: ...`` and the exit status 2, without the usage block."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _finite(text: str) -> float:
    """argparse type: a finite number (NaN and infinities would run and
    write NaN results)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not np.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return v


def _seed(text: str) -> int:
    """argparse type: a random seed, an integer in [0, 2**32) (numpy's and
    JAX's generators refuse others with a message that names neither)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if not 0 <= v < 2**32:
        raise argparse.ArgumentTypeError(f"must be an integer in [0, 2**32), got {v}")
    return v


def _on_writer(what: str, fn):
    """``fn()`` in process 0 alone, its value there (None in the others),
    an error there raised in every process (several JAX processes:
    ``jaxppo.model._processes.on_writer``); with one process, ``fn()``.
    Every file a command writes, and every check of a path it writes,
    goes through here: the other processes may run where that folder
    does not exist (another host)."""
    from jaxppo.model._processes import on_writer

    return on_writer(what, fn)


def _not_an_input(targets, config, option="--out") -> None:
    """ValueError when a file of ``targets`` is one the ``config`` reads
    (the TOML, its data, star or transit-times files)."""
    from jaxppo.obliquity._config_files import config_inputs, refuse_overwriting_inputs

    refuse_overwriting_inputs(targets, config_inputs(config), option)


def _enable_x64() -> None:
    """float64 for every command, and JAX's persistent compilation cache:
    a second run does not recompile what the first compiled (the default
    scan's CPU time is mostly compilation). The cache lives in
    $JAXPPO_CACHE_DIR, else $XDG_CACHE_HOME/jaxppo/jax, else
    ~/.cache/jaxppo/jax; JAXPPO_CACHE=0 switches it off (docs/cli.md)."""
    import jax

    from jaxppo.model._cache import compilation_cache

    jax.config.update("jax_enable_x64", True)
    compilation_cache()


def cmd_demo(args) -> int:
    """Light curves of the seven Kepler-20 b + c double transits for a few tilt
    angles, both hemisphere cases; writes a CSV and a figure."""
    _enable_x64()
    from jaxppo.obliquity._demo import double_transit_demo

    out = Path(args.out)
    _on_writer(f"creating {out}", lambda: out_folder(args.out).mkdir(parents=True, exist_ok=True))
    summary = double_transit_demo(out)
    print(f"wrote {out}/kepler20_double_transits.png, .csv and summary.json ({summary['points']} model points, "
          f"{summary['seconds']:.2f} s)")
    return 0


def cmd_scan(args) -> int:
    """Run the obliquity scan, then its figures, the PPO-or-spot verdict of
    its dips and, if asked for, the marginal scan; no config runs the
    bundled default."""
    _enable_x64()
    from jaxppo.obliquity._config import alpha_grid, load_config
    from jaxppo.obliquity._scan import run_scan, scan_products

    if args.alpha is not None:
        alpha_grid(args.alpha, "--alpha")  # named after the option, before any loading
    out = _on_writer(f"checking --out {args.out}", lambda: out_folder(args.out)) or Path(args.out)
    import jax

    from jaxppo.obliquity._worker import Drawer

    with contextlib.ExitStack() as stack:
        # the figures' own process, started first: its imports overlap the
        # loading and the scan (one JAX process only; docs/cli.md)
        drawer = stack.enter_context(Drawer(_enable_x64, use=jax.process_count() == 1))
        cfg = load_config(args.config, alpha=args.alpha)
        draws = args.marginalize if args.marginalize is not None else cfg.marginalize
        t0 = time.perf_counter()
        caught = stack.enter_context(warnings.catch_warnings(record=True))
        warnings.simplefilter("always")
        result = run_scan(cfg, out, restart=args.restart, progress=not args.quiet)
        seconds = time.perf_counter() - t0
        result = scan_products(result, cfg, out, drawer)
    from jaxppo.model._processes import is_writer

    for w in caught if is_writer() else ():  # process 0 of several JAX processes reports
        print(f"jaxppo scan: note: {w.message}", file=sys.stderr)
    from jaxppo.obliquity._report import scan_report

    print(scan_report(result.summary, cfg, out, seconds), end="")
    if draws:
        from jaxppo.obliquity._marginal import marginal_scan

        m = marginal_scan(cfg, draws=draws, out=out, fixed=result, free=cfg.fit_free, restart=args.restart,
                          progress=not args.quiet)
        print("\n".join(m.summary_lines()))
        from jaxppo.obliquity._scan import with_summary

        result = with_summary(out, result, marginal=m.summary)  # marginal.json's layout, beside the fixed scan's
        print(f"wrote {out / 'marginal.csv'}, marginal.json and marginal.png (and the marginal block of summary.json)")
    if args.joint:
        from jaxppo.obliquity._joint import joint_lines, joint_scan
        from jaxppo.obliquity._scan import with_summary

        j = joint_scan(cfg, particles=args.joint, out=out, free=cfg.fit_free, restart=args.restart, fixed=result,
                       progress=not args.quiet)
        print("\n".join(joint_lines(j)))
        keep = {**j, "cases": {c: {k: v for k, v in d.items() if k not in ("particles", "posterior")}
                               for c, d in j["cases"].items()}}
        with_summary(out, result, joint=keep)  # joint.json's result without the particles
        print(f"wrote {out / 'joint.csv'}, joint.json, joint.png (and the joint block of summary.json)")
    return 0


def cmd_init(args) -> int:
    """Write a commented config template (every key, units, defaults)."""
    from jaxppo.obliquity._template import config_template

    def write():
        path = out_file(args.path, "PATH")
        if path.exists() and not args.force:
            raise ValueError(f"{path} exists; choose another PATH or add --force to overwrite it")
        path.write_text(config_template())

    _on_writer(f"writing {args.path}", write)
    path = Path(args.path)
    print(f"wrote {path}; run it with: jaxppo scan {path} --out scan_out")
    return 0


def cmd_plot(args) -> int:
    """Redraw the figures of a finished scan from DIR/scan.csv and the
    config saved beside it (DIR/config.json, data paths resolved against the
    config's absolute folder): works from any working directory."""
    _enable_x64()
    from jaxppo.obliquity._config_files import finished_scan
    from jaxppo.obliquity._figures import scan_figures
    from jaxppo.obliquity._windows import scan_windows

    out = Path(args.dir)
    cfg, summary, table = finished_scan(out)
    files = scan_figures(out, summary, table, cfg.system, scan_windows(cfg), cfg.cases)
    print("wrote " + ", ".join(files))
    return 0


def cmd_simulate(args) -> int:
    """Write synthetic Kepler-20 b + c photometry (the bundled default data)."""
    _enable_x64()
    import jaxppo as jp

    out = _on_writer(f"checking --out {args.out}", lambda: out_file(args.out)) or Path(args.out)
    if not args.noise > 0:
        raise ValueError(f"--noise must be > 0 (relative flux per point), got {args.noise:g}")
    if not args.radius_scale > 0:
        raise ValueError(f"--radius-scale must be > 0, got {args.radius_scale:g}")
    lc = jp.simulate_kepler20(seed=args.seed, noise=args.noise, alpha=args.alpha, case=args.case,
                              radius_scale=args.radius_scale)
    _on_writer(f"writing {out}", lambda: lc.to_csv(out))
    tilt = "untilted (no --alpha)" if args.alpha is None else f"alpha {args.alpha}, case {args.case}"
    print(f"wrote {out}: {len(lc)} points, noise {args.noise}, {tilt}, radius x{args.radius_scale}")
    if args.alpha is not None:
        from jaxppo.model._kepler20 import injection_note

        print(injection_note(jp.kepler20_system(radius_scale=args.radius_scale), lc.time, args.alpha, args.case))
    return 0


_DEFAULT_FREE = "the config's [fit] free, else every planet's t0 (its transit times, tc, where listed) and radius"


def _free_names(args, cfg=None) -> tuple:
    """The --free names of ``fit`` / ``sample``, every option's together;
    without --free the config's [fit] free, else the mid-time (its listed
    transit times "b.tc" where it has them) and radius ratio of every planet
    (b.t0 b.radius c.t0 c.radius for Kepler-20 b + c)."""
    if args.free is None:
        if cfg is None:
            return None
        if cfg.fit_free is not None:
            return tuple(cfg.fit_free)
        # a planet with listed transit times has its times, not t0, free ("b.tc")
        return tuple(f"{pl.name or i}.{k}" for i, pl in enumerate(cfg.system.planets)
                     for k in ("t0" if pl.transit_times is None else "tc", "radius"))
    twice = sorted({n for n in args.free if args.free.count(n) > 1})
    if twice:
        raise ValueError(f"--free names {', '.join(twice)} more than once: {' '.join(args.free)}")
    return tuple(args.free)


def _fit_inputs(args):
    """(config, light curve) of ``fit`` / ``sample``: the config's data, or
    with ``--windows`` the scan's per-window detrended, outlier-cleaned
    points (``scan_windows``: each multi-transit divided by its
    out-of-transit polynomial), so that real data with stellar variability
    are fitted as the scan sees them."""
    from jaxppo.obliquity._config import load_config

    cfg = load_config(args.config)
    lc = cfg.lightcurve
    if args.windows:
        from jaxppo.obliquity._windows import windows_lightcurve

        lc = windows_lightcurve(cfg)
        print(f"data: {len(lc)} points in {lc.report['windows']} (as jaxppo scan sees them)")
    return cfg, lc


def cmd_fit(args) -> int:
    """Least-squares fit of the config's system to its data."""
    _enable_x64()
    import jaxppo as jp

    if args.out:
        _on_writer(f"checking --out {args.out}", lambda: _not_an_input([out_file(args.out)], args.config))
    _free_names(args)  # a repeated name fails before the config loads
    cfg, lc = _fit_inputs(args)
    free = _free_names(args, cfg)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        res = jp.fit(cfg.system, lc, free=free, progress=not args.quiet)
    for w in caught:
        print(f"jaxppo fit: warning: {w.message}", file=sys.stderr)
    print(res.table())
    print(f"{len(lc)} points, {time.perf_counter() - t0:.1f} s")
    if args.out:
        _on_writer(f"writing {args.out}", lambda: res.save(args.out))
        print(f"wrote {args.out} (jaxppo.FitResult.load reads it)")
    return 0 if res.success else 1


def cmd_sample(args) -> int:
    """NUTS over the config's system and data."""
    _enable_x64()
    import jaxppo as jp

    if args.out:
        _on_writer(f"checking --out {args.out}", lambda: _not_an_input([out_file(args.out)], args.config))
    if args.netcdf:
        try:
            import arviz  # noqa: F401
        except ImportError:
            raise ValueError("--netcdf needs arviz: pip install 'jaxppo[arviz]'") from None
        _on_writer(f"checking --netcdf {args.netcdf}",
                   lambda: _not_an_input([out_file(args.netcdf, "--netcdf")], args.config, "--netcdf"))
    for name in ("warmup", "samples", "chains"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name} must be >= 1, got {getattr(args, name)}")
    from jaxppo.inference._coords import priors_from_text

    priors = priors_from_text(args.prior or [])
    _free_names(args)
    cfg, lc = _fit_inputs(args)
    free = _free_names(args, cfg)
    res = jp.sample(cfg.system, lc, free=free, num_warmup=args.warmup, num_samples=args.samples,
                    seed=args.seed, num_chains=args.chains, progress_bar=not args.quiet, priors=priors or None)
    for n, (med, lo, hi) in res.intervals.items():
        d = res.diagnostics[n]
        print(f"{n:12s} {med:.8f} +{hi - med:.2e} -{med - lo:.2e}   r_hat {d['r_hat']:.3f}  "
              f"ess bulk {d['ess_bulk']:.0f} tail {d['ess_tail']:.0f}")
    div = int(np.sum(res.stats["diverging"]))
    print(f"{args.chains} chains x {args.samples} draws, {div} divergent transitions")
    for line in res.problems():
        print(f"warning: {line}")
    if args.out:
        _on_writer(f"writing {args.out}", lambda: res.save(args.out))
        print(f"wrote {args.out} (jaxppo.SampleResult.load reads it)")
    if args.netcdf:
        _on_writer(f"writing {args.netcdf}", lambda: res.to_netcdf(args.netcdf))
        print(f"wrote {args.netcdf} (arviz.from_netcdf reads it)")
    return 0


def cmd_activity(args) -> int:
    """Stellar activity of a light curve (paper Sects. 2.4 and 3.2): rotation
    period, per-quarter variability, brightness map, optional spot inversion."""
    _enable_x64()
    from jaxppo import activity
    from jaxppo.activity._report import report_lines
    from jaxppo.obliquity._config import load_config

    if args.data is not None:
        data = Path(args.data)
        if not data.is_file():
            raise ValueError(f"--data {data}: no such file")
        t, f, q = activity.read_quarters_csv(data)
    else:
        t, f, q = activity.load_kepler20_quarters()
    # the transits of all five known Kepler-20 planets are masked (b-f; d's
    # 0.08 % transits would otherwise remain in the stellar signal)
    system = None if args.no_transit_mask else load_config(_FIVE_PLANETS).system
    if not 1 <= args.spots <= 6:
        raise ValueError(f"--spots must be an integer in 1..6, got {args.spots}")
    if args.bootstrap < 0:
        raise ValueError(f"--bootstrap must be >= 0, got {args.bootstrap}")
    if not 0 < args.period_min < args.period_max:
        raise ValueError(f"--period-min and --period-max must satisfy 0 < min < max [d], got {args.period_min:g} and "
                         f"{args.period_max:g}")
    spot_chunk = args.spot_chunk
    if spot_chunk is not None and spot_chunk != "all":
        try:
            spot_chunk = int(spot_chunk)
        except ValueError:
            raise ValueError(f"--spot-chunk must be a chunk index or 'all', got {args.spot_chunk!r}") from None
    out = _on_writer(f"checking --out {args.out}", lambda: out_folder(args.out)) or Path(args.out)
    rep = activity.activity_report(t, f, out=out, system=system, quarters=q,
                                   period_min=args.period_min, period_max=args.period_max, bootstrap=args.bootstrap,
                                   spot_chunk=spot_chunk, n_spots=args.spots,
                                   mask_transits=not args.no_transit_mask)
    # another file may be of another star: what Kepler-20's mask took is never silent
    print("\n".join(report_lines(rep, kepler20_mask=system is not None and args.data is not None)))
    print(f"wrote {Path(args.out) / 'activity.json'} and figures")
    return 0


def cmd_ttv(args) -> int:
    """Measure every transit time in the config's data; the table, O-C figures."""
    _enable_x64()
    import jaxppo as jp
    from jaxppo.inference._times_report import read_references, summary_lines, write_times_products
    from jaxppo.obliquity._config import load_config

    cfg = load_config(args.config)
    products = ["transit_times.ecsv", "ttv_summary.json"] + [f"oc_{pl.name}.png" for pl in cfg.system.planets]
    out = Path(args.out)
    _on_writer(f"checking --out {out}", lambda: _not_an_input([out_folder(args.out) / n for n in products], args.config,
                                                              f"--out {out}: ttv would write"))
    kw = {k: v for k, v in cfg.ttv.items() if k != "reference"}
    if args.planets:
        kw["planets"] = args.planets
    reference = read_references(cfg.ttv.get("reference", []))
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        table = jp.measure_transit_times(cfg.system, cfg.lightcurve, progress=not args.quiet, **kw)
    for w in caught:
        print(f"jaxppo ttv: warning: {w.message}", file=sys.stderr)
    summary = _on_writer(f"writing the transit times into {out}", lambda: write_times_products(table, out, reference))
    if summary is not None:  # process 0 (of several JAX processes) reports
        print("\n".join(summary_lines(summary, len(table), time.perf_counter() - t0)))
        print(f"wrote {out}/transit_times.ecsv, ttv_summary.json, " + ", ".join(summary["figures"]))
    return 0 if table.meta["success"] else 1


def _draws(text: str) -> int:
    """argparse type of --marginalize: an integer >= 0."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number of draws >= 0, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be a whole number of draws >= 0, got {text!r}")
    return n


def _particles(text: str) -> int:
    """argparse type of --joint: 0 (off) or an integer >= 16."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be 0 or a whole number of particles >= 16, got {text!r}") from None
    if n != 0 and n < 16:
        raise argparse.ArgumentTypeError(f"must be 0 or a whole number of particles >= 16, got {text!r}")
    return n


def _add_scan(sub) -> None:
    """The ``scan`` subcommand."""
    p = sub.add_parser("scan", help="orbital obliquity scan: chi^2(alpha), posterior, geometry probabilities, figures",
                       description="Run (or resume) the obliquity scan of a config; writes scan.csv, scan.ecsv, "
                       "summary.json and five figures into --out. A rerun with the same config and --out resumes "
                       "and recomputes nothing already done.")
    p.add_argument("config", nargs="?", default=None, metavar="CONFIG",
                   help="scan config (TOML; keys in docs/config.md, template from `jaxppo init`); "
                   "default: the bundled scan of the real Kepler-20 long-cadence data")
    p.add_argument("--out", default="scan_out", metavar="DIR",
                   help="output folder, created if missing (default: scan_out)")
    p.add_argument("--alpha", nargs=3, type=_finite, default=None, metavar=("START", "STOP", "STEP"),
                   help="tilt grid [deg]: START, STOP (exclusive), STEP, replacing the config's [scan] alpha; "
                   "must span 360 deg with a STEP that divides 360, e.g. --alpha 0 360 2 "
                   "(default: the config's, usually 0 360 1)")
    p.add_argument("--marginalize", type=_draws, default=None, metavar="N",
                   help="also run the scan marginalised over N NUTS draws of the transit parameters "
                   "([fit] free; docs/marginal.md), writing marginal.csv/.json/.png; 0: off "
                   "(default: the config's [scan] marginalize, usually 0)")
    p.add_argument("--joint", type=_particles, default=0, metavar="N",
                   help="also sample alpha jointly with the transit parameters ([fit] free) by tempered SMC with N "
                   "particles per case and seed (two seeds; docs/marginal.md, 'The joint sampler'): geometry "
                   "probabilities with errors and the cases' evidences, in joint.csv/.json and the joint block of "
                   "summary.json; 0: off (default)")
    p.add_argument("--restart", action="store_true",
                   help="discard earlier results in --out instead of resuming (default: resume)")
    p.add_argument("--quiet", action="store_true", help="no progress bar (default: show it)")
    p.set_defaults(func=cmd_scan)


def _add_fit_sample(sub) -> None:
    """The ``fit`` and ``sample`` subcommands."""
    for name, func, helptext in (("fit", cmd_fit, "least-squares fit (Levenberg-Marquardt, jp.fit) of a config's planets to its data"),
                                 ("sample", cmd_sample, "MCMC (numpyro NUTS) of a config's planets")):
        p = sub.add_parser(name, help=helptext, description=helptext + ". Free parameters: PLANET.t0 [d], "
                           "PLANET.period [d], PLANET.a [R*], PLANET.inc [deg], PLANET.radius [R*]; star.<coefficient> "
                           "(quadratic: u1 u2, or Kipping's q1 q2; nonlinear: c1..c4; power2: c alpha); lc.offset "
                           "(multiplicative flux offset), lc.jitter (error added in quadrature [relative flux]), "
                           "lc.baseline / lc.baseline2 (linear / quadratic trend per data window); N-body systems ([system] orbits = "
                           "\"nbody\"): PLANET.mass [M_sun], PLANET.lnode [deg], star.mass [M_sun], star.radius [R_sun]; "
                           "moons: PLANET.MOON.period, .t0, .a, .inc, .radius, .mass_ratio, .lnode (docs/cli.md).")
        # fit/sample default to the synthetic example: the real default data
        # (64,792 raw long cadences with stellar variability) need the scan's
        # per-window detrending (--windows)
        p.add_argument("config", nargs="?", default=str(_SYNTHETIC), metavar="CONFIG",
                       help="scan config (TOML; docs/config.md) whose system is the start and whose data are fitted "
                       "(default: the bundled synthetic Kepler-20 set)")
        # extend, not store: "--free b.t0 --free c.t0" frees both (a repeated
        # option replaced the earlier ones); None so the default is not extended
        p.add_argument("--free", nargs="+", action="extend", default=None, metavar="NAME",
                       help="free parameters, e.g. b.t0 b.radius b.a b.inc star.q1 star.q2 lc.jitter; "
                       "repeatable (units above; default: " + _DEFAULT_FREE + ")")
        p.add_argument("--windows", action="store_true",
                       help="fit only the multi-transit windows, detrended as by `jaxppo scan` (each divided by its "
                       "out-of-transit polynomial, outliers clipped); needed for real data with stellar variability "
                       "(default: all data as loaded)")
        what = "JSON, read by jaxppo.FitResult.load" if name == "fit" else ".npz, read by jaxppo.SampleResult.load"
        p.add_argument("--out", default=None, metavar="FILE",
                       help=f"write the result ({what}); its folder must exist (default: none)")
        p.add_argument("--quiet", action="store_true",
                       help=("no progress lines on stderr" if name == "fit" else "no progress bar")
                       + " (default: show them)")
        if name == "sample":
            p.add_argument("--warmup", type=int, default=1000, metavar="N",
                           help="NUTS warm-up (adaptation) steps per chain (default: 1000)")
            p.add_argument("--samples", type=int, default=1000, metavar="N",
                           help="draws kept per chain (default: 1000)")
            p.add_argument("--chains", type=int, default=4, metavar="N",
                           help="chains, run vectorised (default: 4)")
            p.add_argument("--seed", type=_seed, default=0, help="random seed, 0 <= SEED < 2**32 (default: 0)")
            p.add_argument("--prior", nargs=4, action="append", default=None, metavar=("NAME", "KIND", "A", "B"),
                           help="replace the default prior of a free parameter, in its units: KIND normal (A mean, "
                           "B sd), uniform or loguniform (A low, B high), e.g. --prior b.t0 normal 131.5 1e-4; "
                           "repeatable (default: the documented defaults of jaxppo.sample)")
            p.add_argument("--netcdf", default=None, metavar="PATH",
                           help="write the posterior, log-likelihood, sample stats and data as arviz netCDF "
                           "(default: none)")
        p.set_defaults(func=func)


def _add_activity(sub) -> None:
    """The ``activity`` subcommand."""
    p = sub.add_parser("activity", help="stellar activity: rotation period, variability, brightness map, spots",
                       description="Rotation period (generalised Lomb-Scargle, astropy), peak-to-peak variability "
                       "per quarter, the rotation-chunk brightness map (paper Fig. 3) and an optional few-spot "
                       "inversion; transits of Kepler-20 b-f masked. Writes activity.json and PNG figures.")
    p.add_argument("--data", default=None, metavar="PATH",
                   help="CSV with time [d], flux [, quarter] columns; .csv.gz ok "
                   "(default: the bundled Kepler-20 Q1-Q17 long-cadence data)")
    p.add_argument("--out", default="activity_out", metavar="DIR",
                   help="output folder, created if missing (default: activity_out)")
    p.add_argument("--period-min", type=_finite, default=2.0, help="shortest period searched [d] (default: 2)")
    p.add_argument("--period-max", type=_finite, default=45.0, help="longest period searched [d] (default: 45)")
    p.add_argument("--bootstrap", type=int, default=50,
                   help="quarter-bootstrap draws for the period spread, 0: none (default: 50)")
    p.add_argument("--spot-chunk", default=None, metavar="N|all",
                   help="map chunk to invert with spots, or 'all' (default: no inversion)")
    p.add_argument("--spots", type=int, default=3, help="spots per chunk, 1..6 (default: 3)")
    p.add_argument("--no-transit-mask", action="store_true",
                   help="keep the planets' transits in (default: mask Kepler-20 b-f)")
    p.set_defaults(func=cmd_activity)


def _add_ttv(sub) -> None:
    p = sub.add_parser("ttv", help="measure every transit's mid-time (exact model, overlaps fitted together); "
                       "writes transit_times.ecsv and an O-C figure per planet")
    p.add_argument("config", metavar="CONFIG", help="config (TOML; docs/config.md) with [star], [[planet]], [data] "
                   "and optionally [ttv]: planets, free, search [d], grid, min_points, reference (docs/ttv.md)")
    p.add_argument("--out", default="ttv_out", metavar="DIR", help="output folder (default: ttv_out)")
    p.add_argument("--planets", nargs="+", default=None, metavar="NAME",
                   help="planets whose times are measured (default: [ttv] planets, else all)")
    p.add_argument("--quiet", action="store_true", help="no progress lines (default: show them)")
    p.set_defaults(func=cmd_ttv)


def _add_tools(sub) -> None:
    """The ``init``, ``plot``, ``simulate`` and ``demo`` subcommands."""
    p = sub.add_parser("init", help="write a commented scan config template (every key, units, defaults)")
    p.add_argument("path", nargs="?", default="jaxppo_scan.toml", metavar="PATH",
                   help="file to write; its folder must exist (default: jaxppo_scan.toml)")
    p.add_argument("--force", action="store_true", help="overwrite an existing file (default: refuse)")
    p.set_defaults(func=cmd_init)
    p = sub.add_parser("plot", help="redraw the figures of a finished scan",
                       description="Redraw the five figures of a finished scan from DIR/scan.csv, DIR/summary.json "
                       "and the config saved in DIR/config.json; works from any folder.")
    p.add_argument("dir", metavar="DIR", help="the scan's output folder (the --out of jaxppo scan)")
    p.set_defaults(func=cmd_plot)
    p = sub.add_parser("simulate", help="write synthetic Kepler-20 b + c data (CSV)",
                       description="Synthetic 1-minute photometry of the seven Kepler-20 b + c double transits "
                       "(paper parameters), white Gaussian noise; columns time [BKJD], flux, flux_err.")
    p.add_argument("--out", required=True, metavar="FILE", help="CSV file to write; its folder must exist (required)")
    p.add_argument("--seed", type=_seed, default=2021,
                   help="random seed of the noise, 0 <= SEED < 2**32 (default: 2021)")
    p.add_argument("--noise", type=_finite, default=4e-4,
                   help="white-noise standard deviation per point [relative flux], > 0 (default: 4e-4)")
    p.add_argument("--alpha", type=_finite, default=None,
                   help="inject this tilt of planet b [deg] (default: untilted, alpha = 0)")
    p.add_argument("--case", default="same", choices=("same", "opposite"),
                   help="hemisphere case of the injected tilt: same (paper case 1) or opposite (case 4) "
                   "(default: same)")
    p.add_argument("--radius-scale", type=_finite, default=1.0,
                   help="multiply both planet radii by this factor, > 0 (paper Sect. 4.3; default: 1)")
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("demo", help="Kepler-20 b + c double-transit light curves for a few tilt angles",
                       description="Model light curves of the seven Kepler-20 b + c double transits for alpha = 0, "
                       "90, 151, 212, 249, 313, 322 deg in both hemisphere cases; transits numbered as by "
                       "`jaxppo scan` of the bundled data.")
    p.add_argument("--out", default="jaxppo_demo", metavar="DIR",
                   help="output folder, created if missing (default: jaxppo_demo)")
    p.set_defaults(func=cmd_demo)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``jaxppo`` (every option documented with its
    unit and default; docs/cli.md)."""
    from jaxppo._version import __version__

    parser = _Parser(prog="jaxppo", description="Planet-planet occultations in JAX: the orbital obliquity scan of "
                     "Mueller, Ioannidis & Schmitt (2021), fits and sampling. Times [d] are on the data's scale "
                     "(BKJD for the bundled Kepler data), angles in degrees.")
    parser.add_argument("--version", action="version", version=f"jaxppo {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (_add_scan, _add_fit_sample, _add_ttv, _add_activity, _add_tools):
        add(sub)
    return parser


def main(argv=None) -> int:
    """The ``jaxppo`` command: parse ``argv`` (default: ``sys.argv[1:]``),
    run the subcommand and return its exit status (0 success, 2 for a
    usage or input error, which is printed as one line)."""
    from jaxppo._version import __version__

    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # named by the subcommand, whose options the user meant
        sub = next(a for a in parser._actions if a.dest == "command").choices[args.command]
        sub.error(f"unrecognized arguments: {' '.join(extra)}")
    name = f"jaxppo {args.command}"
    try:
        from jaxppo.model._processes import is_writer, start_from_environment

        # several JAX processes (JAXPPO_DISTRIBUTED, docs/scale.md): every
        # process computes, process 0 alone writes the files and reports; the
        # others print only an error of their own (below, once the run ended)
        if start_from_environment() and not is_writer():
            if hasattr(args, "quiet"):
                args.quiet = True
            with open(os.devnull, "w") as null, contextlib.redirect_stdout(null), contextlib.redirect_stderr(null):
                return args.func(args)
        return args.func(args)
    except ValueError as err:
        print(f"{name}: error: {_one_line(err)}", file=sys.stderr)
        return 2
    except OSError as err:
        # a folder that cannot be written, a full disk, a file where a folder
        # should be: one line, no traceback
        where = f" ({err.filename})" if getattr(err, "filename", None) else ""
        print(f"{name}: error: cannot read or write{where}: {err.strerror or err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        again = ("a scan resumes where it stopped when rerun with the same --out" if args.command == "scan" else
                 "this command does not resume: run it again")
        print(f"{name}: interrupted ({again})", file=sys.stderr)
        return 130
    except Exception as err:  # a bug: still one line, with what to report
        print(f"{name}: internal error: {type(err).__name__}: {_one_line(err)} (a bug in jaxppo "
              f"{__version__}; please report it with the command line)", file=sys.stderr)
        return 1


def show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as the command's other messages are (``warnings.showwarning``
    of ``run``): one line on stderr, ``jaxppo COMMAND: warning: ...``,
    without Python's file, line and source echo."""
    command = sys.argv[1] if len(sys.argv) > 1 and not sys.argv[1].startswith("-") else ""
    print(f"jaxppo{' ' + command if command else ''}: warning: {_one_line(message)}", file=sys.stderr)


def run() -> int:
    """The installed ``jaxppo`` command (``[project.scripts]``): ``main()``,
    then every object it made frozen (``gc.freeze``), so that the
    interpreter's last garbage collection, which walked all of JAX's and
    matplotlib's objects for half a second at the end of every command,
    has nothing to walk. The files are written and closed by then; ``main``
    itself, called in a test or a notebook, leaves the collector alone.
    Warnings print as one line each (``jaxppo scan: warning: ...``), without
    Python's file, line and source echo."""
    import gc

    warnings.showwarning = show_warning
    status = main()
    gc.freeze()
    return status


def _one_line(err) -> str:
    return " ".join(str(err).split())


if __name__ == "__main__":
    sys.exit(main())
