"""The obliquity posterior sampled jointly with the transit parameters:
per hemisphere case, adaptive tempered SMC over (transit parameters, alpha)
(:func:`jaxppo.inference._smc.tempered_smc`) from a reference built on the
joint posterior's modes (:func:`jaxppo.inference._posterior.joint_modes`),
run once per seed; each geometry's probability is its posterior mass, with
an error from the particles' ESS and the spread over the seeds; Bayes
factors between cases from the evidences. docs/marginal.md, "The joint
sampler"."""

from __future__ import annotations

import json
import numbers
import time
import warnings
from pathlib import Path

import numpy as np

from ..inference._smc import joint_case_smc
from ._joint_figure import plot_joint
from ..model._processes import is_writer, on_writer, process_info, read_once, share
from ._config import ScanConfig
from ._keywords import Default
from ._marginal import centre_epochs, config_of, default_free, density_prior, quiet_alpha
from ._progress import atomic_write
from ..model._strict_json import strict_jsonable
from ._stats import case_ruled_out, geometry_names, goodness_of_fit, jeffreys, reach_check
from ._windows import windows_and_events, windows_data

__all__ = ["joint_scan", "prograde", "joint_lines"]

JOINT = "joint.json"
JOINT_CSV = "joint.csv"


def prograde(alpha) -> np.ndarray:
    """The paper's prograde range: alpha in [0, 90] or (270, 360) deg."""
    a = np.mod(np.asarray(alpha, float), 360.0)
    return (a <= 90.0) | (a > 270.0)


def _case_summary(case: str, runs: list[dict]) -> dict:
    """Geometry probabilities (mean over seeds; error from the binomial
    variance at each seed's effective particle count and the seeds' spread),
    the alpha peak and the 68 % arc about it, log Z of one case."""
    names = geometry_names(case)
    pro = np.array([float(np.sum(r["weights"][prograde(r["alpha"])])) for r in runs])
    # effective particles: the weights' ESS, and no more than the distinct
    # particles (resampling copies particles; moves that are refused keep them)
    n_eff = np.array([min(r["ess"], float(np.unique(r["alpha"]).size)) for r in runs])
    p = float(pro.mean())
    n_tot = float(n_eff.sum())
    spread = float(pro.var(ddof=1) / len(runs)) if len(runs) > 1 else 0.0
    err = float(np.sqrt(np.mean(p * (1 - p) / n_eff) / len(runs) + spread))
    a = np.concatenate([r["alpha"] for r in runs])
    wts = np.concatenate([r["weights"] for r in runs]) / len(runs)
    hist = np.histogram(a, bins=360, range=(0.0, 360.0), weights=wts)[0]
    peak = float(np.argmax(hist) + 0.5)
    # the arc about the peak, of the smallest radius, holding 68 % of the mass
    d = (a - peak + 180.0) % 360.0 - 180.0
    order = np.argsort(np.abs(d))
    inside = order[: int(np.searchsorted(np.cumsum(wts[order]), 0.6827)) + 1]
    log_z = np.array([r["log_z"] for r in runs])
    pos = [r["weights"] > 0 for r in runs]
    has_pro = any(np.any(prograde(r["alpha"]) & m) for r, m in zip(runs, pos))
    has_retro = any(np.any(~prograde(r["alpha"]) & m) for r, m in zip(runs, pos))
    if has_pro and has_retro:
        k = max(p, 1 - p) / min(p, 1 - p)
        bayes, rating, bound = float(k), jeffreys(k), None
    else:
        # every particle in one geometry: the other's mass is below a 95 %
        # upper bound from the effective particles (0 successes in n_tot)
        p = 1.0 if has_pro else 0.0
        bound = float(1.0 - 0.05 ** (1.0 / n_tot))
        k = (1.0 - bound) / bound
        bayes, rating = None, f"{jeffreys(k)} at least (the other geometry's mass < {bound:.2g}, 95 %)"
        err = max(err, bound)
    return {"geometries": {names[0]: {"probability": p, "error": err},
                           names[1]: {"probability": 1 - p, "error": err}},
            "favoured": names[0] if p >= 0.5 else names[1],
            "bayes_factor": bayes, "jeffreys": rating, "upper_bound_other": bound,
            "alpha_peak": peak,
            "alpha_68": [float((peak + d[inside].min()) % 360.0), float((peak + d[inside].max()) % 360.0)],
            "log_z": float(log_z.mean()),
            "log_z_error": float(log_z.std(ddof=1) / np.sqrt(len(runs))) if len(runs) > 1 else None,
            "ess": [float(e) for e in n_eff], "steps": [r["steps"] for r in runs],
            "calls": [r["calls"] for r in runs], "seconds": [r["seconds"] for r in runs],
            "log_z_per_seed": log_z.tolist(), "prograde_per_seed": pro.tolist(), "modes": runs[0].get("modes"),
            "posterior": hist.tolist(), "particles": {"alpha": a.tolist(), "weight": wts.tolist()}}


_WHERE = "at the best point the sampler reached (the no-PPO mode, the modes, the densest particle)"


def _goodness_of_fit(runs: list[dict], points: int, fixed, k: int) -> dict:
    """``goodness_of_fit`` of the least chi^2 the runs reached (each run's
    "chi2_best": the no-PPO mode, the modes, the densest particle; None in
    joint.json where it was not finite) for ``points`` points, and
    ``reach_check`` of it against the fixed scan ``fixed`` (``k`` free
    parameters; "ok" False with its reason where it fails). Runs
    recorded by a jaxppo that kept no chi^2 (no such key) leave it
    unchecked: "ok" True, "checked" False, with a caution."""
    if any("chi2_best" not in r for r in runs):
        return {"ok": True, "checked": False, "points": int(points), "reason": None, "caution": (
            "goodness of fit not checked: joint.json holds runs of an earlier jaxppo without their chi^2 "
            "(restart=True / --restart samples again and checks it)")}
    best = np.array([np.nan if r["chi2_best"] is None else float(r["chi2_best"]) for r in runs])
    least = float(np.min(best)) if np.all(np.isfinite(best)) else float("nan")  # any NaN run: not rated
    fit = {**goodness_of_fit(least, points, _WHERE), "checked": True}
    # did the sampled model reach the configuration's own fit (the fixed scan's best)?
    fit["reach"] = reach_check(fit, fixed.summary["goodness_of_fit"], k, "sampler's particles")
    if fit["ok"] and not fit["reach"]["ok"]:
        fit.update(ok=False, reason=fit["reach"]["reason"])
    return fit


def _guard(cases: dict, fit: dict, runs: dict, points: int) -> None:
    """Every case ``_withhold``-en (in place) where the model does not fit
    (``fit``, ``_goodness_of_fit``); where it fits, each case the data rule
    out (``case_ruled_out``: its least chi^2 over its runs, ``runs``: case
    -> its runs, fits at no particle where another case's does): its
    probabilities assume it (the case Bayes factors, which compare the
    cases, stay)."""
    if not fit["ok"]:
        for c in cases.values():
            _withhold(c, fit["reason"])
        return
    if not fit.get("checked"):
        return
    least = {c: float(np.min([np.nan if r["chi2_best"] is None else r["chi2_best"] for r in rs]))
             for c, rs in runs.items()}  # NaN where a run's was not finite
    for c in cases:
        why = case_ruled_out(c, least[c], least, points, "particle")
        if why is not None:
            _withhold(cases[c], why)


def _withhold(case: dict, reason: str) -> None:
    """A case's probabilities, rating, peak and posterior withheld (in
    place): the model does not fit the data (``reason``)."""
    case["geometries"] = {n: dict(g, probability=None, error=None) for n, g in case["geometries"].items()}
    case.update(favoured=None, bayes_factor=None, jeffreys="not rated", upper_bound_other=None, alpha_peak=None,
                alpha_68=None, posterior=[float("nan")] * len(case["posterior"]), withheld=reason)


def _check(particles, seeds, cess, n_moves):
    """The sampler settings checked; (particles, seeds) as ints."""
    if not isinstance(particles, numbers.Integral) or isinstance(particles, bool) or particles < 16:
        raise ValueError(f"particles must be an integer >= 16, got {particles!r}")
    ok = not isinstance(seeds, (str, bytes)) and hasattr(seeds, "__iter__")
    seeds = list(seeds) if ok else []
    if not seeds or not all(isinstance(s, numbers.Integral) and not isinstance(s, bool) and s >= 0 for s in seeds) \
            or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be a sequence of distinct integers >= 0, got {seeds if ok else repr(seeds)}")
    if not isinstance(cess, numbers.Real) or isinstance(cess, bool) or not 0.0 < cess < 1.0:
        raise ValueError(f"cess must be a number in (0, 1), got {cess!r}")
    if not isinstance(n_moves, numbers.Integral) or isinstance(n_moves, bool) or n_moves < 1:
        raise ValueError(f"n_moves must be an integer >= 1, got {n_moves!r}")
    return int(particles), [int(s) for s in seeds]


def joint_scan(system, lightcurve=None, *, particles: int = 256, seeds=(0, 1), out=None, free=None,
               stellar_density=None, restart: bool = False, progress: bool = True, cess: float = 0.5,
               n_moves: int = 4, fixed=None, figures: bool = True, alpha=Default(np.arange(0.0, 360.0, 1.0)), cases=Default(("same", "opposite")),
               margin: float = Default(0.05), detrend=Default(2), baseline: float = Default(0.3),
               clip=Default(5.0), multi_transits=Default(None)) -> dict:
    """Sample the tilt alpha jointly with the transit parameters, per case.

    The obliquity posterior p(alpha, theta | D) of each hemisphere case by
    adaptive tempered sequential Monte Carlo with ``particles`` particles,
    once per seed, with the model at the sampled alpha (the exact overlap
    integral wherever two disks can meet). It is what the marginal scan's
    importance average estimates, without resting on the few no-PPO draws
    that happen to fall where the PPO signal is: the particles start from
    the posterior's own modes (found by joint Levenberg-Marquardt fits of
    alpha and theta) and the no-PPO plateau, and move by Metropolis kernels
    in (theta, alpha). Each geometry's probability is its posterior mass
    within the case, with an error (binomial from the particles' ESS and
    the spread over the seeds); each case has its evidence log Z (with the
    seeds' spread), and the Bayes factors between cases are their ratios.
    Transit parameters and priors as ``jaxppo.marginal_scan`` (t0, P, p,
    b / (1 + p) per planet; every free a/R* tied to one stellar density).

    Parameters
    ----------
    system : ScanConfig or System
        A ``ScanConfig`` (its own scan settings), or a ``System`` with
        ``lightcurve``.
    lightcurve : LightCurve, optional
        The data, with a System; not with a config.
    particles : int, optional
        SMC particles per case and seed (>= 16; default 256).
    seeds : sequence of int, optional
        Distinct seeds; one run per seed and case (default (0, 1): two
        runs give the seeds' spread in the errors).
    out : str or pathlib.Path or None, optional
        Folder for joint.json (every run as it finishes; a rerun with the
        same settings resumes) and joint.csv (case, alpha, posterior
        density per degree); None: nothing written.
    free : sequence of str or None, optional
        The sampled transit parameters (default: t0, period, a, inc and
        radius of every planet).
    stellar_density : sequence of 2 float or None, optional
        (mean, sd) [g/cm^3] of the Gaussian prior on rho* when an a/R* is
        free; default: a config's ``[fit] stellar_density``, else the
        density the system's a/R* imply, 10 % wide.
    restart : bool, optional
        Discard joint.json in ``out`` first.
    progress : bool, optional
        Print one line per tempering step.
    cess : float, optional
        The conditional-ESS fraction kept per tempering step (0, 1).
    n_moves : int, optional
        Rounds of the Metropolis kernels per step (>= 1).
    fixed : ScanResult or None, optional
        The fixed-parameter scan of the same config, for the figure and for
        the check that the particles reach its fit (``goodness_of_fit``
        "reach"); else it is computed (one plain scan, after the sampler).
    figures : bool, optional
        With ``out``, draw joint.png: per case the joint posterior of alpha
        against the fixed-parameter scan's (default True).
    alpha, cases, margin, detrend, baseline, clip, multi_transits : optional
        As ``jaxppo.scan``; only with a System (a ScanConfig's own settings
        are used). ``alpha`` sets nothing here but the check of the
        config: alpha is sampled continuously.

    Returns
    -------
    dict
        {"cases": {case: {"geometries": {name: {"probability", "error"}},
        "favoured", "bayes_factor", "jeffreys", "alpha_peak" [deg],
        "alpha_68" [deg], "log_z", "log_z_error", "ess", "steps",
        "calls", "seconds", "modes", "posterior" (360 one-degree bins),
        "particles"}}, "case_bayes_factors" {"a/b": Z_a / Z_b} (None beyond a
        float), "case_log_bayes_factors" {"a/b": log Z_a - log Z_b}, "method",
        "free", "density_prior", "goodness_of_fit" (the least chi^2 the runs
        reached, for the number of points: "ok", "reason", "caution", as the
        fixed scan's), "seconds", and with the figure "figures" (its
        path)}; joint.json holds it under "result". Where the model does
        not fit the data, every case's probabilities, "favoured", the
        Bayes factors, "alpha_peak", "alpha_68" and "posterior" are
        withheld (None, NaN; "jeffreys" "not rated", "withheld" the
        reason).

    Raises
    ------
    ValueError
        For a bad ``particles``, ``seeds``, ``cess``, ``n_moves``,
        ``stellar_density`` or scan setting; when the data hold no
        multi-transit of the tilted planet; when ``out`` holds a joint run
        of other settings (use ``restart=True``); when ``fixed`` is a scan
        of another configuration.

    Examples
    --------
    The bundled real Kepler-20 scan (minutes on 2 CPU cores):

    >>> import jaxppo as jp
    >>> res = jp.joint_scan(jp.load_config(), out="joint_out")  # doctest: +SKIP
    >>> res["cases"]["same"]["geometries"]  # doctest: +SKIP

    Settings are checked before anything runs:

    >>> try:
    ...     jp.joint_scan(jp.load_config(), particles=8)
    ... except ValueError as err:
    ...     print(err)
    particles must be an integer >= 16, got 8
    """
    import jax

    if not jax.config.jax_enable_x64:
        raise ValueError("joint_scan needs float64: jax.config.update('jax_enable_x64', True) first")
    particles, seeds = _check(particles, seeds, cess, n_moves)
    cfg = config_of(system, lightcurve, dict(alpha=alpha, cases=cases, margin=margin, detrend=detrend,
                                           baseline=baseline, clip=clip, multi_transits=multi_transits),
                  "jaxppo.joint_scan", "the joint obliquity sampler")
    if fixed is not None and fixed.config_digest != cfg.digest:
        raise ValueError(f"fixed: a scan of another configuration (digest {fixed.config_digest}, this one "
                         f"{cfg.digest}; the digest covers the alpha grid too: give joint_scan the scan's alpha=)")
    t_begin = time.perf_counter()
    windows, _ = windows_and_events(cfg)
    if not windows:
        raise ValueError(f"{cfg.source}: no multi-transit of the tilted planet with data: nothing to sample")
    data = windows_data(windows, cfg.lightcurve.exposure)
    tm, _ = data.supersampled_times()
    sysm = centre_epochs(cfg.system, 0.5 * (float(tm.min()) + float(tm.max())))
    free = default_free(sysm) if free is None else tuple(free)
    density, density_source = density_prior(cfg, sysm, free, None, stellar_density)
    settings = {"particles": particles, "free": list(free), "density": density,
                "config": cfg.digest_without("alpha", "block"),
                "cess": float(cess), "n_moves": int(n_moves)}
    path = Path(out) / JOINT if out is not None else None
    done = read_once(lambda: _open(path, settings, restart), path.parent) if path is not None else {}
    say = (lambda m: print(f"joint: {m}", flush=True)) if progress and is_writer() else None
    cases = {}
    for case in cfg.cases:
        a_ref = quiet_alpha(sysm, tm, case)
        runs, found = [], None
        for seed in seeds:
            key = f"{case}#{seed}"
            if key not in done:
                r = joint_case_smc(sysm, data, free, density, case, a_ref, n_particles=particles, seed=seed,
                                   found=found, cess=cess, n_moves=n_moves,
                                   progress=(lambda m, c=case, s=seed: say(f"{c} seed {s}: {m}")) if say else None)
                found = r["found"]
                done[key] = {"modes": r["modes"], "alpha": r["alpha"].tolist(), "weights": r["weights"].tolist(),
                             "log_z": r["log_z"], "max_log_gamma": float(np.max(r["log_gamma"])),
                             "chi2_best": r["chi2_best"],
                             "ess": r["ess"], "steps": r["steps"], "calls": r["calls"], "seconds": r["seconds"]}
                if path is not None:
                    on_writer(f"writing {path}", lambda: atomic_write(path, _strict_json({"settings": settings,
                                                                                           "runs": done})))
            rec = done[key]
            runs.append({**rec, "alpha": np.asarray(rec["alpha"]), "weights": np.asarray(rec["weights"])})
        cases[case] = _case_summary(case, runs)
        if not is_writer():  # process 0 of several says what follows
            continue
        if min(cases[case]["ess"]) < 0.25 * particles:
            warnings.warn(f"joint_scan: case {case}: only {min(cases[case]['ess']):.0f} of {particles} particles are "
                          "effective (weights or copies); the errors given are rough: use more particles",
                          stacklevel=2)
        if len(seeds) < 2:
            warnings.warn(f"joint_scan: case {case}: one seed; the errors leave out the spread between runs "
                          "(seeds=(0, 1) gives it)", stacklevel=2)
    fixed = _fixed_scan(cfg) if fixed is None else fixed  # in every process: the reach check, the figure
    fit = _goodness_of_fit([done[f"{c}#{s}"] for c in cfg.cases for s in seeds], len(data), fixed, len(free))
    factors, log_factors = {}, {}
    names = list(cases)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            lk = cases[a]["log_z"] - cases[b]["log_z"]
            log_factors[f"{a}/{b}"] = float(lk) if fit["ok"] else None
            factors[f"{a}/{b}"] = float(np.exp(lk)) if abs(lk) < 700.0 and fit["ok"] else None  # None: beyond a float
    _guard(cases, fit, {c: [done[f"{c}#{s}"] for s in seeds] for c in cfg.cases}, len(data))
    result = {"method": f"adaptive tempered SMC from the posterior's modes, {particles} particles, seeds {seeds}",
              "free": list(free), "density_prior": density, "density_prior_source": density_source,
              "cases": cases, "case_bayes_factors": factors, "case_log_bayes_factors": log_factors,
              "goodness_of_fit": fit, "seconds": time.perf_counter() - t_begin, **process_info()}
    if path is not None:
        _write(cfg, Path(out), {"settings": settings, "runs": done, "result": result}, figures, fixed)
    return result


def _write(cfg: ScanConfig, out: Path, rec: dict, figures: bool, fixed) -> None:
    """joint.json (``rec``), joint.csv and joint.png (against ``fixed``, the
    fixed scan, computed when None) in ``out``, by process 0; every process
    returns once it has written (or each raises its error)."""
    result = rec["result"]
    if figures:
        fixed = _fixed_scan(cfg) if fixed is None else fixed  # in every process (its kernels are collective)
        result["figures"] = share([str((out / "joint.png").resolve())])  # process 0's path

    def write():
        if figures:
            plot_joint(out, result, fixed)
        atomic_write(out / JOINT, _strict_json(rec, indent=1))
        rows = ["case,alpha,posterior"] + [f"{c},{k + 0.5},{v['posterior'][k]:.17g}" for c, v in result["cases"].items()
                                           for k in range(360)]
        atomic_write(out / JOINT_CSV, "\n".join(rows) + "\n")

    on_writer(f"writing joint.json, joint.csv and joint.png in {out}", write)


def _open(path: Path, settings: dict, restart: bool) -> dict:
    """The runs joint.json at ``path`` already holds for these settings
    (none with ``restart``, which also removes an old joint.png)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if restart and (path.parent / "joint.png").is_file():
        (path.parent / "joint.png").unlink()  # never an old run's figure beside new results
    if not path.exists() or restart:
        return {}
    try:
        rec = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{path} is not a joint run's record ({err}); use restart=True (--restart) or another "
                         "folder") from None
    if not isinstance(rec, dict) or not isinstance(rec.get("runs", {}), dict):
        raise ValueError(f"{path} is not a joint run's record (a JSON object with settings and runs); use "
                         "restart=True (--restart) or another folder")
    if rec.get("settings") != settings:
        raise ValueError(f"{path} holds a joint run of other settings ({rec.get('settings')}); "
                         "use restart=True (--restart) or another folder")
    return rec.get("runs", {})


def _fixed_scan(cfg: ScanConfig):
    """The fixed-parameter scan of ``cfg`` (in a temporary folder), which
    joint.png is drawn against when the caller gives none."""
    import tempfile

    from ._scan import run_scan

    with tempfile.TemporaryDirectory(prefix="jaxppo_fixed_") as tmp:
        return run_scan(cfg, tmp, progress=False)


def _strict_json(obj, indent=None) -> str:
    """JSON with every non-finite float written as null (strict JSON)."""
    return json.dumps(strict_jsonable(obj), indent=indent, allow_nan=False)


def joint_lines(result: dict) -> list[str]:
    """The command line's report of a :func:`joint_scan` result."""
    lines = [f"joint (alpha, transit parameters) posterior: {result['method']}, {result['seconds']:.0f} s"]
    fit = result.get("goodness_of_fit") or {}
    if fit.get("caution"):
        lines.append(f"  caution: {fit['caution']}")
    if not fit.get("ok", True):  # every case withheld, for one reason
        lines.append(f"  no probability, peak or rating in any case: {fit['reason']}")
        lines += [f"  case {case}: log Z {c['log_z']:.2f}, not rated" for case, c in result["cases"].items()]
        lines += [f"  Bayes factor {k}: withheld" for k in result["case_log_bayes_factors"]]
        return lines
    for case, c in result["cases"].items():
        geo = "; ".join(f"{n}: {100 * g['probability']:.2f} +- {100 * g['error']:.2f} %"
                        for n, g in c["geometries"].items())
        err = f" +- {c['log_z_error']:.2f}" if c["log_z_error"] is not None else ""
        lines.append(f"  case {case}: {geo}; favoured {c['favoured']} ({c['jeffreys']}); alpha peak "
                     f"{c['alpha_peak']:.1f} deg, 68 % {c['alpha_68'][0]:.1f}-{c['alpha_68'][1]:.1f}; "
                     f"log Z {c['log_z']:.2f}{err}; ESS {', '.join(f'{e:.0f}' for e in c['ess'])}")
    lines.append("  (calibration over 20 moderate-SNR injections: the 68 % intervals covered the truth 60 +- 10 % "
                 "of the time, the 95 % intervals 100 +- 5 %; the errors given are the sampler's own and the seeds' "
                 "spread: docs/marginal.md, 'The joint sampler')")
    for k, v in result["case_log_bayes_factors"].items():
        lines.append(f"  Bayes factor {k}: exp({v:.2f})" + (f" = {np.exp(v):.3g}" if abs(v) < 700 else ""))
    return lines
