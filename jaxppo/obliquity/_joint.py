"""The obliquity posterior sampled jointly with the transit parameters:
per hemisphere case, adaptive tempered SMC over (transit parameters, alpha)
(:func:`jaxppo.inference._smc.tempered_smc`), run with two seeds; each
geometry's probability is its posterior mass, with an error from the
particles' ESS and the spread over the seeds; Bayes factors between cases
from the evidences. docs/marginal.md, "Joint sampling"."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..inference._smc import joint_case_smc
from ..model._lightcurve import LightCurve
from ._config import ScanConfig
from ._marginal import centre_epochs, default_free, density_prior, quiet_alpha
from ._progress import atomic_write
from ._stats import geometry_names, jeffreys
from ._windows import windows_and_events

__all__ = ["joint_scan", "prograde"]


def prograde(alpha) -> np.ndarray:
    """The paper's prograde range: alpha in [0, 90] or (270, 360) deg."""
    a = np.mod(np.asarray(alpha, float), 360.0)
    return (a <= 90.0) | (a > 270.0)


def _data(cfg: ScanConfig) -> LightCurve:
    windows, _ = windows_and_events(cfg)
    if not windows:
        raise ValueError(f"{cfg.source}: no multi-transit of the tilted planet with data: nothing to sample")
    t = np.concatenate([w.time for w in windows])
    _, first = np.unique(t, return_index=True)
    return LightCurve(t[first], np.concatenate([w.flux for w in windows])[first],
                      np.concatenate([w.flux_err for w in windows])[first], cfg.lightcurve.exposure)


def _case_summary(case: str, runs: list[dict]) -> dict:
    """Geometry probabilities (mean over seeds; error from the ESS and the
    seeds' spread), the alpha peak and 68 % interval, log Z of one case."""
    names = geometry_names(case)
    pro = np.array([float(np.sum(r["weights"][prograde(r["alpha"])])) for r in runs])
    ess = np.array([r["ess"] for r in runs])
    p = float(pro.mean())
    err = float(np.sqrt(np.mean(p * (1 - p) / ess) / len(runs) + (pro.var(ddof=1) if len(runs) > 1 else 0.0)))
    a = np.concatenate([r["alpha"] for r in runs])
    wts = np.concatenate([r["weights"] for r in runs]) / len(runs)
    hist, edges = np.histogram(a, bins=360, range=(0.0, 360.0), weights=wts)
    peak = float(0.5 * (edges[np.argmax(hist)] + edges[np.argmax(hist) + 1]))
    # a 68 % interval about the peak, on the circle
    d = (a - peak + 180.0) % 360.0 - 180.0
    order = np.argsort(np.abs(d))
    inside = order[: int(np.searchsorted(np.cumsum(wts[order]), 0.6827)) + 1]
    log_z = np.array([r["log_z"] for r in runs])
    k = p / (1 - p) if p < 1 else np.inf
    return {"geometries": {names[0]: {"probability": p, "error": err},
                           names[1]: {"probability": 1 - p, "error": err}},
            "bayes_factor": float(k if k >= 1 else 1 / k) if np.isfinite(k) and k > 0 else None,
            "favoured": names[0] if p >= 0.5 else names[1],
            "rating": jeffreys(k if k >= 1 else 1 / k) if np.isfinite(k) and k > 0 else "decisive",
            "alpha_peak": peak, "alpha_68": [float(peak + d[inside].min()), float(peak + d[inside].max())],
            "log_z": float(log_z.mean()), "log_z_error": float(log_z.std(ddof=1) / np.sqrt(2)) if len(runs) > 1
            else None, "ess": ess.tolist(), "steps": [r["steps"] for r in runs], "calls": [r["calls"] for r in runs],
            "seconds": [r["seconds"] for r in runs], "max_log_gamma": [r.get("max_log_gamma") for r in runs],
            "log_z_per_seed": log_z.tolist(), "prograde_per_seed": pro.tolist()}


def _guides(cfg: ScanConfig) -> dict:
    """Per case, -Delta chi^2 / 2 of the fixed-parameter scan on 360
    one-degree bins (circular linear interpolation of the config's grid):
    where the joint sampler's independent alpha draws look first."""
    import tempfile

    from ._scan import run_scan

    with tempfile.TemporaryDirectory(prefix="jaxppo_joint_") as tmp:
        res = run_scan(cfg, tmp, progress=False)
    out = {}
    centres = np.arange(360) + 0.5
    for case in cfg.cases:
        rows = res.table[res.table["case"] == case]
        a, d = np.asarray(rows["alpha"], float), np.asarray(rows["delta_chi2"], float)
        out[case] = -0.5 * np.interp(centres, a, d, period=360.0)
    return out


def joint_scan(cfg: ScanConfig, *, particles: int = 256, seeds=(0, 1), free=None, stellar_density=None,
               out=None, progress: bool = True, cess: float = 0.5, n_moves: int = 6) -> dict:
    """The joint (alpha, transit parameters) posterior of each case of the
    config, by tempered SMC with ``particles`` particles, once per seed.

    Returns (and with ``out``, writes ``joint.json`` there, each case and
    seed as it finishes; a rerun with the same settings resumes) {"cases":
    {case: {"geometries": {name: {"probability", "error"}}, "favoured",
    "bayes_factor", "rating", "alpha_peak", "alpha_68", "log_z",
    "log_z_error", "ess", ...}}, "case_bayes_factors": {"a/b": Z_a / Z_b},
    "method", "free", "seconds"}."""
    if int(particles) != particles or particles < 16:
        raise ValueError(f"particles must be an integer >= 16, got {particles!r}")
    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be distinct integers, got {seeds!r}")
    t_begin = time.perf_counter()
    data = _data(cfg)
    tm, _ = data.supersampled_times()
    sysm = centre_epochs(cfg.system, 0.5 * (float(tm.min()) + float(tm.max())))
    free = default_free(sysm) if free is None else tuple(free)
    density, density_source = density_prior(cfg, sysm, free, None, stellar_density)
    settings = {"particles": int(particles), "free": list(free), "density": density, "config": cfg.digest,
                "cess": float(cess), "n_moves": int(n_moves)}
    path = Path(out) / "joint.json" if out is not None else None
    done = {}
    if path is not None and path.exists():
        rec = json.loads(path.read_text())
        if rec.get("settings") == settings:
            done = rec.get("runs", {})
    say = (lambda m: print(f"joint: {m}", flush=True)) if progress else None
    cases = {}
    for case in cfg.cases:
        a_ref = quiet_alpha(sysm, tm, case)
        runs, found = [], None
        for seed in seeds:
            key = f"{case}#{seed}"
            if key not in done:
                r = joint_case_smc(sysm, data, free, density, case, a_ref, n_particles=particles, seed=seed,
                                   found=found, cess=cess, n_moves=n_moves, progress=(lambda m, c=case, s=seed: say(f"{c} seed {s}: {m}")) if say else None)
                found = r["found"]
                done[key] = {"modes": r["modes"], "alpha": r["alpha"].tolist(), "weights": r["weights"].tolist(), "log_z": r["log_z"],
                             "max_log_gamma": float(np.max(r["log_gamma"])),
                             "ess": r["ess"], "steps": r["steps"], "calls": r["calls"], "seconds": r["seconds"]}
                if path is not None:
                    atomic_write(path, json.dumps({"settings": settings, "runs": done}))
            rec = done[key]
            runs.append({**rec, "alpha": np.asarray(rec["alpha"]), "weights": np.asarray(rec["weights"])})
        cases[case] = _case_summary(case, runs)
    factors = {}
    names = list(cases)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            factors[f"{a}/{b}"] = float(np.exp(cases[a]["log_z"] - cases[b]["log_z"]))
    result = {"method": f"adaptive tempered SMC, {particles} particles, seeds {seeds}", "free": list(free),
              "density_prior": density, "density_prior_source": density_source, "cases": cases,
              "case_bayes_factors": factors, "seconds": time.perf_counter() - t_begin}
    if path is not None:
        atomic_write(path, json.dumps({"settings": settings, "runs": done, "result": result}, indent=1))
    return result
