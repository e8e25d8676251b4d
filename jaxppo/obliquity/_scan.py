"""The orbital obliquity scan of Mueller et al. (2021), Sects. 2.1 and 3.3.

chi^2(alpha) over all multi-transits of the tilted planet at once, the ground
level chi^2_0 (median over the alphas at which no planet-planet occultation
occurs in any frame, found from the geometry), Delta chi^2, the posterior
p(alpha | D) ~ exp(-Delta chi^2 / 2) normalised over [0, 360), the geometry
probabilities (Table 6), the Bayes factor with its Jeffreys rating, and the
numbers of the transits in which each alpha produces a PPO.

Long runs write their progress as they go (one checksummed JSON line per
finished (case, alpha) block, flushed and fsynced) and resume without
recomputing; torn or edited lines are recomputed with a note; final outputs
are written atomically; a changed config is detected; ``restart`` removes the
old outputs before writing new ones.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
import warnings
from pathlib import Path

import numpy as np

from ._config import ScanConfig
from ._progress import atomic_write, read_progress, record_line
from ..model._sweep import sweep
from ..model._lightcurve import LightCurve, is_lightkurve
from ..model._overlap import in_transit_mask, ppo_table
from ..model._transits import MultiTransit, multi_transits
from ._tables import table5_rows, write_table5

__all__ = ["scan", "run_scan", "ScanResult", "ScanWindow", "scan_windows", "geometry_probabilities", "jeffreys",
           "scan_events"]

PROGRESS = "scan_progress.jsonl"
# Extra width [d] (15 min) of each transit window in the out-of-transit mask:
# room for ephemeris errors, so no ingress point bends the baseline.
_TRANSIT_PAD = 15.0 / 1440.0
# [scan] multi_transits lists mid-times; an event matches within this [d]
_EVENT_MATCH = 0.1


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


@dataclasses.dataclass(frozen=True)
class ScanWindow:
    """One multi-transit as the chi^2 sees it.

    ``number``: 1-based, as in ``summary["multi_transits"]``; ``event``: the
    :class:`MultiTransit`; ``time`` [d], ``flux``, ``flux_err``: the points
    inside [event.start - margin, event.end + margin] after detrending (each
    window divided by its out-of-transit polynomial) and outlier removal;
    ``exposure`` [d] of each point (None: instantaneous). ``baseline_points``:
    out-of-transit points the trend was fitted to; ``clipped``: points dropped
    as outliers (out of transit only); ``sigma``: the error estimated from the
    out-of-transit scatter (None when the data's own errors are used);
    ``trend``: polynomial coefficients (highest power first) in t - event.mid.
    """

    number: int
    event: MultiTransit
    time: np.ndarray
    flux: np.ndarray
    flux_err: np.ndarray
    exposure: float | None
    baseline_points: int = 0
    clipped: int = 0
    sigma: float | None = None
    trend: tuple = ()

    def as_dict(self) -> dict:
        return dict(self.event.as_dict(), number=self.number, points=int(self.time.size),
                    baseline_points=self.baseline_points, clipped=self.clipped, sigma=self.sigma)


def _robust_sigma(r: np.ndarray) -> float:
    """1.4826 x the median absolute deviation: the Gaussian sigma, unmoved by
    a few outliers."""
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


def _detrend_window(t, f, e, oot, mid, order, clip, estimate):
    """Fit the polynomial to the out-of-transit points, iteratively dropping
    those whose residual exceeds ``clip`` robust sigmas (never in-transit
    points: a PPO bump or a transit cannot be clipped). Returns the kept mask,
    the trend coefficients and the estimated sigma (or None)."""
    keep = np.ones(t.size, bool)
    x = t - mid
    w = None if estimate else 1.0 / e
    for _ in range(10):
        fit_pts = oot & keep
        coef = np.polyfit(x[fit_pts], f[fit_pts], order, w=None if w is None else w[fit_pts])
        res = f / np.polyval(coef, x) - 1.0
        if clip is None:
            break
        s_rob = _robust_sigma(res[fit_pts])
        if not s_rob > 0:  # noise-free data: nothing is an outlier
            break
        new = keep & ~(oot & (np.abs(res) > clip * s_rob))
        # stop when nothing changes, or before the baseline gets too thin
        if new.sum() == keep.sum() or (oot & new).sum() < order + 3:
            break
        keep = new
    fit_pts = oot & keep
    sigma = None
    if estimate:
        # unbiased residual variance of the kept baseline (n - order - 1 dof)
        r = f[fit_pts] / np.polyval(coef, x[fit_pts]) - 1.0
        sigma = float(np.sqrt(np.sum(r**2) / (fit_pts.sum() - order - 1)))
    return keep, coef, sigma


def scan_windows(cfg: ScanConfig) -> list[ScanWindow]:
    """The multi-transits of the tilted planet that have data, each with the
    detrended, outlier-cleaned points the chi^2 uses (paper Sect. 2.2).

    Per event: the baseline is [start - baseline, end + baseline]; its points
    outside every planet's transit (contact times, widened by half an
    exposure) fit a polynomial of order ``detrend``, and the window is divided
    by it. Outliers: baseline points more than ``clip`` x 1.4826 MAD from the
    trend are dropped (iterated); in-transit points are never clipped. When
    the data carry no errors (``lightcurve.errors_estimated``), each window's
    error is the rms of its baseline residuals with n - order - 1 degrees of
    freedom. Events with too few baseline points (fewer than order + 3 in all
    or fewer than 2 on a side) are skipped and listed in ``skipped`` of the
    summary. ``detrend = "none"``: the flux is used as loaded."""
    return windows_and_events(cfg)[0]


def windows_and_events(cfg: ScanConfig):
    sysm, lc = cfg.system, cfg.lightcurve
    tilted_name = sysm.planets[sysm.tilted].name
    tilted_label = tilted_name or str(sysm.tilted)
    events = [e for e in multi_transits(sysm, float(lc.time.min()) - 1.0, float(lc.time.max()) + 1.0)
              if tilted_label in e.planets]
    if cfg.events is not None:
        # only the listed multi-transits (e.g. the paper's seven)
        missing = [m for m in cfg.events if not any(abs(e.mid - m) < _EVENT_MATCH for e in events)]
        if missing:
            raise ValueError(f"{cfg.source}: [scan] multi_transits: no multi-transit of planet {tilted_label!r} "
                             f"within {_EVENT_MATCH} d of {missing}; the data hold {[round(e.mid, 2) for e in events]}")
        events = [e for e in events if any(abs(e.mid - m) < _EVENT_MATCH for m in cfg.events)]
    order, clip = cfg.detrend, cfg.clip
    pad = 0.5 * (lc.exposure or 0.0) + _TRANSIT_PAD
    windows, skipped = [], []
    for e in events:
        lo, hi = e.start - cfg.margin, e.end + cfg.margin
        if order is None:
            sel = (lc.time >= lo) & (lc.time <= hi)
            if sel.any():
                windows.append(ScanWindow(len(windows) + 1, e, lc.time[sel], lc.flux[sel], lc.flux_err[sel], lc.exposure))
            continue
        base = (lc.time >= e.start - cfg.baseline) & (lc.time <= e.end + cfg.baseline)
        chi_sel = (lc.time[base] >= lo) & (lc.time[base] <= hi)
        if not chi_sel.any():
            continue
        t, f, err = lc.time[base], lc.flux[base], lc.flux_err[base]
        oot = ~in_transit_mask(sysm, t, pad)
        n_left, n_right = int((oot & (t < e.start)).sum()), int((oot & (t > e.end)).sum())
        if oot.sum() < order + 3 or (order >= 1 and min(n_left, n_right) < 2):
            skipped.append({"mid": e.mid, "reason": f"{int(oot.sum())} out-of-transit baseline points "
                            f"({n_left} before, {n_right} after); need >= {order + 3} and >= 2 on each side"})
            continue
        keep, coef, sigma = _detrend_window(t, f, err, oot, e.mid, order, clip, lc.errors_estimated)
        trend = np.polyval(coef, t - e.mid)
        use = chi_sel & keep
        fe = np.full(t.size, sigma) if sigma is not None else err / trend
        windows.append(ScanWindow(
            len(windows) + 1, e, t[use], f[use] / trend[use], fe[use], lc.exposure,
            baseline_points=int((oot & keep).sum()), clipped=int((~keep).sum()), sigma=sigma,
            trend=tuple(float(c) for c in coef)))
    if not windows:
        raise ValueError(
            f"{cfg.source}: the data ({lc.time.min():.3f} .. {lc.time.max():.3f}) contain no usable multi-transit "
            f"of planet {tilted_label!r}" + (f" (skipped: {skipped})" if skipped else "")
        )
    return windows, skipped


def scan_events(cfg: ScanConfig):
    """(event, mask of ``cfg.lightcurve``) of the multi-transits the scan
    uses, numbered as :func:`scan_windows` (the mask covers the chi^2 window
    of the raw light curve; the detrended points are in scan_windows)."""
    lc = cfg.lightcurve
    return [(w.event, (lc.time >= w.event.start - cfg.margin) & (lc.time <= w.event.end + cfg.margin))
            for w in scan_windows(cfg)]


def _geometry_names(case: str) -> tuple[str, str]:
    """Names of the prograde and retrograde ranges of a case. With one
    untilted planet, a retrograde tilt puts the tilted planet in the other
    hemisphere (paper Table 6). With more, a mixed case ("+-": the untilted
    planets' hemispheres relative to the tilted planet's before its tilt) is
    named by its signs."""
    if case == "same":
        return "prograde, same hemisphere", "retrograde, different hemispheres"
    if case == "opposite":
        return "prograde, different hemispheres", "retrograde, same hemisphere"
    return f"prograde, hemispheres {case}", f"retrograde, hemispheres {case}"


def _logsumexp(v: np.ndarray) -> float:
    if v.size == 0:
        return -np.inf
    m = float(np.max(v))
    return m + float(np.log(np.sum(np.exp(v - m))))


def geometry_probabilities(alpha, delta_chi2, case) -> dict:
    """Integrate the posterior p(alpha | D) ~ exp(-Delta chi^2 / 2) (uniform
    prior on [0, 360), Eq. 1) over the paper's Table 6 ranges: prograde
    [0, 90] and (270, 360), retrograde (90, 270]; with the sum of positive
    Delta chi^2 in each range and the Bayes factor K = p_favoured / p_other
    (computed in log space: ``log10_bayes_factor`` is always finite;
    ``bayes_factor`` is None where K overflows a float)."""
    alpha = np.mod(np.asarray(alpha, float), 360.0)
    dchi2 = np.asarray(delta_chi2, float)
    pro = (alpha <= 90.0) | (alpha > 270.0)
    names = _geometry_names(case)
    logw = -0.5 * dchi2
    log_pro, log_ret = _logsumexp(logw[pro]), _logsumexp(logw[~pro])
    log_tot = np.logaddexp(log_pro, log_ret)
    p_pro, p_ret = float(np.exp(log_pro - log_tot)), float(np.exp(log_ret - log_tot))
    pos = np.clip(dchi2, 0.0, None)
    favoured = names[0] if log_pro >= log_ret else names[1]
    log10_k = abs(log_pro - log_ret) / np.log(10.0)
    if not np.isfinite(log10_k):
        raise ValueError(f"alpha: the grid leaves the {'retrograde' if np.isinf(log_ret) else 'prograde'} range "
                         "empty; the geometry probabilities need angles in both")
    kk = float(10.0**log10_k) if log10_k < 300 else None
    return {
        names[0]: {"probability": p_pro, "sum_positive_delta_chi2": float(pos[pro].sum()), "alpha_range": "[0, 90] and (270, 360)"},
        names[1]: {"probability": p_ret, "sum_positive_delta_chi2": float(pos[~pro].sum()), "alpha_range": "(90, 270]"},
        "bayes_factor": kk, "log10_bayes_factor": float(log10_k), "favoured": favoured,
        "jeffreys": jeffreys(10.0**min(log10_k, 300.0)),
    }


def _detrend_summary(cfg) -> dict:
    if cfg.detrend is None:
        return {"order": "none", "flux_err": "estimated from the scatter at load time" if cfg.lightcurve.errors_estimated
                else "from the data"}
    return {
        "order": cfg.detrend, "baseline_days": cfg.baseline, "margin_days": cfg.margin,
        "clip_sigma": cfg.clip if cfg.clip is not None else "none",
        "out_of_transit": "outside every planet's first-to-last contact, widened by half an exposure + 15 min",
        "outliers": "out-of-transit points with |residual| > clip x 1.4826 MAD, iterated; in-transit points never clipped",
        "flux_err": ("estimated per window: rms of the out-of-transit residuals (n - order - 1 dof); the data have no errors"
                     if cfg.lightcurve.errors_estimated else "from the data, divided by the trend"),
    }


class ScanResult(dict):
    """A finished scan: the summary (this dict, also written to
    summary.json: chi2_0, geometry probabilities, Bayes factors, the
    multi-transits used, the detrending), ``table`` (the rows of scan.csv),
    ``windows`` (the :class:`ScanWindow` data the chi^2 used) and ``plot()``."""

    table: np.ndarray
    windows: list

    @property
    def summary(self) -> dict:
        return dict(self)

    def delta_chi2(self, case: str) -> tuple[np.ndarray, np.ndarray]:
        """(alpha [deg], Delta chi^2) of one case."""
        if case not in set(self.table["case"]):
            raise ValueError(f"case must be one of {sorted(set(self.table['case']))}, got {case!r}")
        sel = self.table["case"] == case
        return self.table["alpha"][sel], self.table["delta_chi2"][sel]

    def plot(self, ax=None):
        """Delta chi^2(alpha) of every case (paper Fig. 5); returns the axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(8, 3.6))
        for case in dict.fromkeys(self.table["case"]):
            a, d = self.delta_chi2(case)
            geo = self["probabilities"][case]
            fav = geo["favoured"]
            ax.plot(a, d, lw=1, label=f"case {case} ({fav} {100 * geo[fav]['probability']:.1f} %)")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("tilt angle alpha [deg]")
        ax.set_ylabel("Delta chi^2")
        ax.set_xlim(0, 360)
        ax.legend(fontsize=8)
        return ax


_TABLE_DTYPE = [("case", "U16"), ("alpha", float), ("chi2", float), ("delta_chi2", float), ("posterior", float)]


def _write_ecsv(path: Path, table: np.ndarray, cfg, digest: str, chi2_0: dict, points: int, step: float) -> None:
    """scan.ecsv: the rows of scan.csv as an astropy Table with units and
    the provenance in its metadata (config digest and source, jaxppo
    version, cases, alpha grid, chi2_0, number of points), written
    atomically. ``astropy.table.Table.read(path)`` gives it back with units."""
    import astropy.units as u
    from astropy.table import Table

    from .._version import __version__

    t = Table()
    t["case"] = table["case"]
    t["alpha"] = table["alpha"] * u.deg
    t["chi2"] = table["chi2"]
    t["delta_chi2"] = table["delta_chi2"]
    t["posterior"] = table["posterior"] / u.deg
    t["alpha"].description = "tilt of the tilted planet's orbit about the line of sight (Mueller et al. 2021, Sect. 2.1)"
    t["chi2"].description = "chi^2 of the multi-transit windows at this alpha"
    t["delta_chi2"].description = "chi^2 - chi2_0 (chi2_0: median over the alphas without any PPO)"
    t["posterior"].description = "p(alpha | D) ~ exp(-delta_chi2 / 2), uniform prior, normalised over [0, 360) deg"
    t.meta.update({
        "jaxppo_version": __version__, "config_digest": digest, "config": cfg.source, "cases": list(cfg.cases),
        "alpha_grid_deg": {"start": float(cfg.alpha[0]), "stop": float(cfg.alpha[-1] + step), "step": step},
        "chi2_0": {c: float(v) for c, v in chi2_0.items()}, "points": points,
        "tilted_planet": cfg.system.planets[cfg.system.tilted].name,
        "exposure_days": cfg.lightcurve.exposure,
    })
    tmp = path.with_name(path.name + ".tmp")
    t.write(tmp, format="ascii.ecsv", overwrite=True)
    os.replace(tmp, path)


def _clear_outputs(out: Path) -> None:
    """--restart: remove the previous scan's outputs before anything new is
    written, the finished-scan marker (summary.json) first, so an interrupted
    restart never leaves old results beside a new config."""
    figures = []
    summ = out / "summary.json"
    if summ.exists():
        try:
            figures = [Path(f).name for f in json.loads(summ.read_text()).get("figures", [])]
        except (json.JSONDecodeError, OSError, AttributeError, TypeError):
            figures = []
    names = ["summary.json", "scan.csv", "scan.ecsv", "table5.csv", "table5.md", "marginal.csv", "marginal.json",
             "marginal.png", "marginal_draws.json", "marginal_progress.jsonl"] + figures + list(_FIGURE_NAMES) + ["config.json", PROGRESS]
    for name in dict.fromkeys(names):
        p = out / name
        if p.is_file():
            p.unlink()


# The figure files scan_figures writes (also removed by --restart when the old
# summary.json is missing or unreadable).
_FIGURE_NAMES = ("fig4_multitransits.png", "fig5_delta_chi2.png", "fig6_cutout.png", "fig7_paths.png", "probabilities.png")


def _finished_result(out: Path, cfg: ScanConfig, digest: str, figures: bool):
    """The stored result of a scan that already finished in ``out`` with this
    config (same digest, every output present, figures when asked for), or
    None. A rerun then recomputes and redraws nothing."""
    try:
        summary = json.loads((out / "summary.json").read_text())
        if summary.get("config_digest") != digest or set(summary.get("chi2_0", {})) != set(cfg.cases):
            return None
        if not all((out / n).is_file() for n in ("scan.ecsv", "table5.csv", "table5.md")) or "table5" not in summary:
            return None
        if figures and not (summary.get("figures") and all((out / Path(f).name).is_file() for f in summary["figures"])):
            return None
        with open(out / "scan.csv") as fh:
            lines = fh.read().splitlines()
        if lines[0] != "case,alpha,chi2,delta_chi2,posterior":
            return None
        rows = [ln.split(",") for ln in lines[1:] if ln]
        table = np.array([(r[0], float(r[1]), float(r[2]), float(r[3]), float(r[4])) for r in rows], dtype=_TABLE_DTYPE)
    except (OSError, ValueError, IndexError, AttributeError, TypeError):
        return None
    expect = [(c, float(a)) for c in cfg.cases for a in cfg.alpha]
    if [(str(c), float(a)) for c, a in zip(table["case"], table["alpha"])] != [(c, float(f"{a:.10g}")) for c, a in expect]:
        return None
    result = ScanResult(summary)
    result.table = table
    result.windows = windows_and_events(cfg)[0]
    n = len(expect)
    result["resumed"] = {"alphas_done_before": n, "alphas_total": n, "finished_before": True}
    result["progress_notes"] = []
    return result


def _require_x64(what: str) -> None:
    """Refuse to run in float32. Delta chi^2 features are ~0.1-1 against a
    chi^2_0 of ~100-3000, which float32 (7 digits) cannot resolve: with x64 off
    the real Kepler-20 scan gave chi^2_0 146.266 instead of 146.275 and a peak
    of 1.408 instead of 1.419, without a word. The library never flips the
    global switch, so it asks the user to."""
    import jax

    if not jax.config.jax_enable_x64:
        raise ValueError(
            f"{what} needs float64: call jax.config.update('jax_enable_x64', True) before using jaxppo "
            "(float32 shifts Delta chi^2 by ~0.01; the command line enables it itself)"
        )


def run_scan(cfg: ScanConfig, out, restart: bool = False, progress: bool = True, figures: bool = True) -> ScanResult:
    """Run (or resume) the scan and write scan.csv, scan.ecsv, summary.json
    and figures. A scan that already finished in ``out`` with the same config
    is returned as stored (``result["resumed"]["finished_before"]``): nothing
    is recomputed or redrawn."""
    from tqdm import tqdm

    _require_x64("the obliquity scan")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t_begin = time.perf_counter()
    sysm, lc = cfg.system, cfg.lightcurve
    digest = cfg.digest
    prog_path = out / PROGRESS
    if restart:
        _clear_outputs(out)
    done, notes = read_progress(prog_path, digest, out, cfg.source)
    for note in notes:
        warnings.warn(note, stacklevel=2)
    if not prog_path.exists():
        atomic_write(prog_path, json.dumps({"config_digest": digest, "source": cfg.source, "format": 2}) + "\n")
    # keep the config next to the results: jaxppo plot rebuilds it from here
    # (relative paths resolved against the absolute ``base``), from any folder
    atomic_write(out / "config.json", json.dumps({"digest": digest, "source": cfg.source, "base": cfg.base,
                                                   "config": cfg.raw}, indent=2, default=str))
    n_total = len(cfg.cases) * cfg.alpha.size
    n_before = sum((c, round(float(a), 9)) in done for c in cfg.cases for a in cfg.alpha)
    if n_before == n_total and not notes:
        stored = _finished_result(out, cfg, digest, figures)
        if stored is not None:
            return stored

    windows, skipped = windows_and_events(cfg)
    data = LightCurve(np.concatenate([w.time for w in windows]), np.concatenate([w.flux for w in windows]),
                      np.concatenate([w.flux_err for w in windows]), lc.exposure)
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
            fh.write(record_line({"config_digest": digest, "case": case, "alpha": alphas.tolist(), "chi2": chi2.tolist()}))
            fh.flush()
            os.fsync(fh.fileno())
            for a, c2 in zip(alphas, chi2):
                done[(case, round(float(a), 9))] = float(c2)
            bar.update(alphas.size)
    bar.close()

    # ---- analysis -------------------------------------------------------------
    step = float(cfg.alpha[1] - cfg.alpha[0]) if cfg.alpha.size > 1 else 360.0
    times_per_event = [LightCurve(w.time, w.flux, w.flux_err, w.exposure).supersampled_times()[0] for w in windows]
    null = sweep(sysm, tm, np.zeros(1), cases=(cfg.cases[0],), no_overlap=True)[0, 0].reshape(-1, nsub).mean(-1)
    chi2_null = float(np.sum(((y - null) / sig) ** 2))
    rows, summary_cases, table = [], {}, []
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
        geo = geometry_probabilities(cfg.alpha, dchi2, case)
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
            table.append((case, float(a), float(c2), float(dc), float(p)))
    atomic_write(out / "scan.csv", "case,alpha,chi2,delta_chi2,posterior\n" + "\n".join(rows) + "\n")
    table_arr = np.array(table, dtype=_TABLE_DTYPE)
    _write_ecsv(out / "scan.ecsv", table_arr, cfg, digest, {c: summary_cases[c]["chi2_0"] for c in cfg.cases},
                int(data.time.size), step)
    result = ScanResult(
        config=cfg.source, config_digest=digest, chi2_0={c: summary_cases[c]["chi2_0"] for c in cfg.cases},
        probabilities={c: summary_cases[c]["geometries"] for c in cfg.cases},
        cases=summary_cases,
        multi_transits=[w.as_dict() for w in windows], skipped_multi_transits=skipped,
        points=int(data.time.size), supersampling=nsub, exposure=lc.exposure,
        detrending=_detrend_summary(cfg),
        alpha={"start": float(cfg.alpha[0]), "stop": float(cfg.alpha[-1] + step), "step": step},
        tilted=sysm.planets[sysm.tilted].name, progress_notes=notes, seconds=None,
        data={"loaded": lc.report_line(), "report": lc.report},
        resumed={"alphas_done_before": n_before, "alphas_total": n_total, "finished_before": False},
    )
    result.table = table_arr
    result.windows = windows
    # Table 5 of the paper: the peaks and dips of Delta chi^2 (and cases 3/2 by Eq. 2)
    by_case = {c: {k: result.table[k][result.table["case"] == c] for k in ("alpha", "chi2", "delta_chi2", "posterior")}
               for c in cfg.cases}
    result["table5"] = table5_rows(by_case, result, cfg.cases)
    result["table5_files"] = write_table5(out, by_case, result, cfg.cases)
    if figures:
        from ._figures import scan_figures

        result["figures"] = scan_figures(out, result, by_case, sysm, windows, cfg.cases)
    # each negative dip: a spot-crossing bump against the PPO (failure-safe)
    from ..activity._ppo_or_spot import scan_hook

    result["ppo_or_spot"] = scan_hook(result, sysm, out if figures else None)
    result["seconds"] = time.perf_counter() - t_begin
    # strict JSON (no NaN / Infinity): a value that cannot be written is a bug, not a file
    atomic_write(out / "summary.json", json.dumps(result, indent=2, allow_nan=False))
    return result


def scan(system, lightcurve=None, *, alpha=None, cases=("same", "opposite"), out=None, margin: float = 0.05,
         detrend: int | str | None = 2, baseline: float = 0.3, clip: float | str | None = 5.0,
         multi_transits=None, block: int = 60, restart: bool = False, progress: bool = False,
         figures: bool = False) -> ScanResult:
    """The orbital obliquity scan (Mueller et al. 2021, Sects. 2.1 and 3.3).

    ``jp.scan(system, lightcurve, alpha=np.arange(0, 360, 1.0))`` or
    ``jp.scan(jp.load_config(path))`` (a config carries its own settings).

    Args:
        system: :class:`System` (``system.tilted`` is rotated by alpha), or a
            :class:`ScanConfig` from :func:`load_config`.
        lightcurve: :class:`LightCurve`, or a lightkurve ``LightCurve``
            (converted by :meth:`LightCurve.from_lightkurve`); not with a config.
        alpha: tilt grid [deg]; evenly spaced over 360 deg with a step that
            divides 360 (default 0, 1, ..., 359).
        cases: hemisphere cases, "same" (paper case 1) and/or "opposite" (4).
        out: folder for scan.csv, summary.json, the progress file (resumes)
            and, with ``figures``, the figures; None: a temporary folder.
        margin [d], detrend (order or "none"), baseline [d], clip (robust
            sigmas or "none"), multi_transits (mid-times [d]), block: as the
            config keys of the same names (docs/config.md).

    Returns:
        :class:`ScanResult`: the summary dict with ``table``, ``windows`` and
        ``plot()``.
    """
    import tempfile

    from ._config import ScanConfig, check_alpha_grid

    if isinstance(system, ScanConfig):
        if lightcurve is not None:
            raise ValueError("lightcurve must not be given with a ScanConfig (the config names its data)")
        cfg = system
    else:
        cfg = config_from_arguments(system, lightcurve, alpha, cases, margin, detrend, baseline, clip, multi_transits, block)
        check_alpha_grid(cfg.alpha)
    if out is None:
        with tempfile.TemporaryDirectory(prefix="jaxppo_scan_") as tmp:
            return run_scan(cfg, tmp, restart=restart, progress=progress, figures=False)
    return run_scan(cfg, out, restart=restart, progress=progress, figures=figures)


def config_from_arguments(system, lightcurve, alpha, cases, margin, detrend, baseline, clip, multi_transits, block):
    from ._config import ScanConfig
    from ..model._system import System, scan_cases

    if not isinstance(system, System):
        raise ValueError(f"system must be a jaxppo.System or a ScanConfig, got {type(system).__name__}")
    if is_lightkurve(lightcurve) and not isinstance(lightcurve, LightCurve):
        # a lightkurve LightCurve: its default quality bitmask, flux divided
        # by its median, exposure from TIMEDEL; the drops are in the report
        lightcurve = LightCurve.from_lightkurve(lightcurve)
    if not isinstance(lightcurve, LightCurve):
        raise ValueError(f"lightcurve must be a jaxppo.LightCurve or a lightkurve LightCurve, got {type(lightcurve).__name__}")
    alpha = np.arange(0.0, 360.0, 1.0) if alpha is None else np.asarray(alpha, float)
    try:
        cases = scan_cases(system, cases)
    except ValueError as e:
        raise ValueError(f"cases = {cases!r}: {e}") from None
    if not (np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be >= 0 days, got {margin!r}")
    if isinstance(detrend, str):
        if detrend.lower() != "none":
            raise ValueError(f"detrend must be a polynomial order 0..5 or 'none', got {detrend!r}")
        detrend = None
    if detrend is not None and (isinstance(detrend, bool) or int(detrend) != detrend or not 0 <= detrend <= 5):
        raise ValueError(f"detrend must be a polynomial order 0..5 or 'none', got {detrend!r}")
    if not baseline > margin:
        raise ValueError(f"baseline must be > margin ({margin} d), got {baseline!r}")
    if isinstance(clip, str):
        if clip.lower() != "none":
            raise ValueError(f"clip must be a threshold >= 2 or 'none', got {clip!r}")
        clip = None
    if clip is not None and not clip >= 2:
        raise ValueError(f"clip must be a threshold >= 2 or 'none', got {clip!r}")
    if int(block) < 1:
        raise ValueError(f"block must be >= 1, got {block!r}")
    events = None if multi_transits is None else tuple(float(m) for m in np.atleast_1d(multi_transits))
    star = system.star
    # what determines the results goes into the digest (resuming, --restart)
    raw = {
        "star": {"law": star.law, "params": np.asarray(star.params).tolist(),
                 "mu_nodes": None if star.mu_nodes is None else np.asarray(star.mu_nodes).tolist(),
                 "interpolation": star.interpolation},
        "planet": [{"name": pl.name, **{f: float(getattr(pl, f)) for f in ("period", "t0", "a", "inc", "radius")}}
                   for pl in system.planets],
        "tilted": system.tilted,
        "data": {"exposure": lightcurve.exposure, "errors_estimated": lightcurve.errors_estimated},
        "scan": {"alpha": alpha.tolist(), "cases": list(cases), "margin": float(margin), "detrend": detrend,
                 "baseline": float(baseline), "clip": clip, "multi_transits": events, "block": int(block)},
    }
    return ScanConfig(system, lightcurve, alpha, cases, float(margin), int(block), raw, "<jaxppo.scan>",
                      detrend, float(baseline), clip, events)
