"""The orbital obliquity scan of Mueller et al. (2021), Sects. 2.1 and 3.3.

chi^2(alpha) over all multi-transits of the tilted planet at once, the ground
level chi^2_0 (median over the alphas at which no planet-planet occultation
occurs in any frame, found from the geometry), Delta chi^2, the posterior
p(alpha | D) ~ exp(-Delta chi^2 / 2) normalised over [0, 360), the geometry
probabilities (Table 6), the Bayes factor with its Jeffreys rating, and the
numbers of the transits in which each alpha produces a PPO.

Long runs write their progress as they go (one JSON line per finished
(case, alpha) block, flushed and fsynced) and resume without recomputing;
final outputs are written atomically; a changed config is detected.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from ._config import ScanConfig
from ._sweep import sweep
from ._system import multi_transits

__all__ = ["run_scan", "ScanResult", "geometry_probabilities", "jeffreys", "scan_events", "ppo_table"]

PROGRESS = "scan_progress.jsonl"


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def jeffreys(k: float) -> str:
    """Jeffreys (1961) rating of a Bayes factor K >= 1."""
    if k < 10**0.5:
        return "barely worth mentioning"
    if k < 10:
        return "substantial"
    if k < 10**1.5:
        return "strong"
    if k < 100:
        return "very strong"
    return "decisive"


def scan_events(cfg: ScanConfig):
    """Multi-transits of the tilted planet that have data, with their data."""
    sysm, lc = cfg.system, cfg.lightcurve
    tilted_name = sysm.planets[sysm.tilted].name
    events = [e for e in multi_transits(sysm, float(lc.time.min()) - 1.0, float(lc.time.max()) + 1.0)
              if tilted_name in e.planets]
    used = []
    for e in events:
        sel = (lc.time >= e.start - cfg.margin) & (lc.time <= e.end + cfg.margin)
        if sel.sum() > 0:
            used.append((e, sel))
    if not used:
        raise ValueError(
            f"{cfg.source}: the data ({lc.time.min():.3f} .. {lc.time.max():.3f}) contain no multi-transit of planet {tilted_name!r}"
        )
    return used


def ppo_table(system, times_per_event, alpha, case) -> np.ndarray:
    """[alpha, event]: does the tilted planet overlap another planet on the
    star in any of the event's frames?"""
    k = len(system.planets)
    out = np.zeros((alpha.size, len(times_per_event)), bool)
    for ei, t in enumerate(times_per_event):
        x, y, r = system.positions(t[None, :], np.asarray(alpha)[:, None], case, xp=np)
        on = np.hypot(x, y) - r < 1
        i = system.tilted
        for j in range(k):
            if j == i:
                continue
            d = np.hypot(x[..., i] - x[..., j], y[..., i] - y[..., j])
            out[:, ei] |= (on[..., i] & on[..., j] & (d < r[..., i] + r[..., j]) & (r[..., i] > 0) & (r[..., j] > 0)).any(-1)
    return out


def _geometry_names(case: str) -> tuple[str, str]:
    if case == "same":
        return "prograde, same hemisphere", "retrograde, different hemispheres"
    return "prograde, different hemispheres", "retrograde, same hemisphere"


def geometry_probabilities(alpha, posterior, delta_chi2, case, step) -> dict:
    """Integrate the posterior over the paper's Table 6 ranges: prograde
    [0, 90] and (270, 360), retrograde (90, 270]; with the sum of positive
    Delta chi^2 in each range, and the Bayes factor."""
    alpha = np.mod(np.asarray(alpha, float), 360.0)
    pro = (alpha <= 90.0) | (alpha > 270.0)
    names = _geometry_names(case)
    p_pro = float(np.sum(posterior[pro]) * step)
    p_ret = float(np.sum(posterior[~pro]) * step)
    pos = np.clip(delta_chi2, 0.0, None)
    favoured = names[0] if p_pro >= p_ret else names[1]
    hi, lo = max(p_pro, p_ret), min(p_pro, p_ret)
    kk = hi / lo if lo > 0 else float("inf")  # a grid covering one range only
    return {
        names[0]: {"probability": p_pro, "sum_positive_delta_chi2": float(pos[pro].sum()), "alpha_range": "[0, 90] and (270, 360)"},
        names[1]: {"probability": p_ret, "sum_positive_delta_chi2": float(pos[~pro].sum()), "alpha_range": "(90, 270]"},
        "bayes_factor": float(kk), "favoured": favoured, "jeffreys": jeffreys(kk),
    }


class ScanResult(dict):
    """Summary of a finished scan (also written to summary.json)."""


def _read_progress(path: Path, digest: str, restart: bool, out: Path):
    done = {}
    if not path.exists():
        return done
    lines = path.read_text().splitlines()
    if not lines:
        return done
    try:
        head = json.loads(lines[0])
    except json.JSONDecodeError:
        head = {}
    if head.get("config_digest") != digest:
        if not restart:
            raise ValueError(
                f"{out} holds results of a different configuration (digest {head.get('config_digest')}, now {digest}); "
                "use another --out folder or --restart to discard them"
            )
        path.unlink()
        return done
    for line in lines[1:]:
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut by an interruption: recomputed
        for a, c2 in zip(rec["alpha"], rec["chi2"]):
            done[(rec["case"], round(float(a), 9))] = float(c2)
    return done


def run_scan(cfg: ScanConfig, out, restart: bool = False, progress: bool = True, figures: bool = True) -> ScanResult:
    """Run (or resume) the scan and write scan.csv, summary.json and figures."""
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t_begin = time.perf_counter()
    sysm, lc = cfg.system, cfg.lightcurve
    digest = cfg.digest
    prog_path = out / PROGRESS
    if restart and prog_path.exists():
        prog_path.unlink()
    done = _read_progress(prog_path, digest, restart, out)
    if not prog_path.exists():
        _atomic_write(prog_path, json.dumps({"config_digest": digest, "source": cfg.source}) + "\n")
    # keep the config next to the results (jaxppo plot re-reads it)
    _atomic_write(out / "config.json", json.dumps({"digest": digest, "source": cfg.source, "config": cfg.raw}, indent=2, default=str))

    used = scan_events(cfg)
    sel = np.zeros(lc.time.size, bool)
    for _, s in used:
        sel |= s
    data = lc.select(sel)
    tm, nsub = data.supersampled_times()
    y, sig = data.flux, data.flux_err

    todo = [(c, a) for c in cfg.cases for a in cfg.alpha if (c, round(float(a), 9)) not in done]
    blocks = []
    for c in cfg.cases:
        alphas = np.array([a for cc, a in todo if cc == c])
        for i in range(0, alphas.size, cfg.block):
            blocks.append((c, alphas[i:i + cfg.block]))
    bar = tqdm(total=len(cfg.cases) * cfg.alpha.size, initial=len(cfg.cases) * cfg.alpha.size - len(todo),
               desc="scan", unit="alpha", disable=not progress, leave=False)
    with open(prog_path, "a") as fh:
        for case, alphas in blocks:
            model = sweep(sysm, tm, alphas, cases=(case,))[0]
            model = model.reshape(alphas.size, -1, nsub).mean(-1)
            chi2 = np.sum(((y[None, :] - model) / sig[None, :]) ** 2, axis=1)
            fh.write(json.dumps({"case": case, "alpha": alphas.tolist(), "chi2": chi2.tolist()}) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
            for a, c2 in zip(alphas, chi2):
                done[(case, round(float(a), 9))] = float(c2)
            bar.update(alphas.size)
    bar.close()

    # ---- analysis -------------------------------------------------------------
    step = float(cfg.alpha[1] - cfg.alpha[0]) if cfg.alpha.size > 1 else 360.0
    times_per_event = []
    for e, _ in used:
        s = (data.time >= e.start - cfg.margin) & (data.time <= e.end + cfg.margin)
        t_ev, _ = data.select(s).supersampled_times() if s.any() else (np.zeros(0), 1)
        times_per_event.append(t_ev)
    null = sweep(sysm, tm, np.zeros(1), cases=(cfg.cases[0],), no_overlap=True)[0, 0].reshape(-1, nsub).mean(-1)
    chi2_null = float(np.sum(((y - null) / sig) ** 2))
    rows, summary_cases = [], {}
    for case in cfg.cases:
        chi2 = np.array([done[(case, round(float(a), 9))] for a in cfg.alpha])
        ppo = ppo_table(sysm, times_per_event, cfg.alpha, case)
        quiet = ~ppo.any(1)
        # Ground level: the median over alphas with no PPO in any frame; when
        # the grid has none, the chi^2 of the no-PPO model itself (the sum of
        # one-disk terms, which is what every quiet alpha computes).
        chi2_0 = float(np.median(chi2[quiet])) if quiet.any() else chi2_null
        dchi2 = chi2 - chi2_0
        w = np.exp(-0.5 * (dchi2 - dchi2.min()))
        post = w / (np.sum(w) * step)
        geo = geometry_probabilities(cfg.alpha, post, dchi2, case, step)
        transits = [[int(i + 1) for i in np.nonzero(ppo[ai])[0]] for ai in range(cfg.alpha.size)]
        summary_cases[case] = {
            "chi2_0": chi2_0, "chi2_null_model": chi2_null, "alphas_without_ppo": int(quiet.sum()),
            "geometries": geo,
            "min_delta_chi2": {"alpha": float(cfg.alpha[np.argmin(dchi2)]), "value": float(dchi2.min())},
            "max_delta_chi2": {"alpha": float(cfg.alpha[np.argmax(dchi2)]), "value": float(dchi2.max())},
            "ppo_transits": {f"{a:g}": tr for a, tr in zip(cfg.alpha, transits) if tr},
        }
        for a, c2, dc, p in zip(cfg.alpha, chi2, dchi2, post):
            rows.append(f"{case},{a:.10g},{c2:.17g},{dc:.17g},{p:.17g}")
        # Cases 3 and 2 (paper Eq. 2): the same geometry at 360 - alpha.
        mirror = np.mod(360.0 - cfg.alpha, 360.0)
        label = {"same": "case 3 (= case 1 at 360 - alpha)", "opposite": "case 2 (= case 4 at 360 - alpha)"}[case]
        summary_cases[case]["mirror"] = {
            "label": label,
            "geometries": geometry_probabilities(mirror, post, dchi2, "opposite" if case == "same" else "same", step),
        }
    _atomic_write(out / "scan.csv", "case,alpha,chi2,delta_chi2,posterior\n" + "\n".join(rows) + "\n")
    result = ScanResult(
        config=cfg.source, config_digest=digest, chi2_0={c: summary_cases[c]["chi2_0"] for c in cfg.cases},
        probabilities={c: summary_cases[c]["geometries"] for c in cfg.cases},
        cases=summary_cases,
        multi_transits=[dict(e.as_dict(), number=i + 1, points=int(s.sum())) for i, (e, s) in enumerate(used)],
        points=int(data.time.size), supersampling=nsub,
        alpha={"start": float(cfg.alpha[0]), "stop": float(cfg.alpha[-1] + step), "step": step},
        tilted=sysm.planets[sysm.tilted].name, seconds=None,
    )
    if figures:
        from ._figures import scan_figures

        result["figures"] = scan_figures(cfg, out, result)
    result["seconds"] = time.perf_counter() - t_begin
    _atomic_write(out / "summary.json", json.dumps(result, indent=2))
    return result
