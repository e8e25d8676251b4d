"""The orbital obliquity scan of Mueller et al. (2021), Sects. 2.1 and 3.3:
the driver (``run_scan``, ``scan``), its outputs and restart.

chi^2(alpha) over all multi-transits of the tilted planet at once (the
windows of ``._windows``), the ground level chi^2_0 (median over the
alphas at which no planet-planet occultation occurs in any frame, found from
the geometry), Delta chi^2, the posterior p(alpha | D) ~ exp(-Delta chi^2 / 2)
normalised over [0, 360), the geometry probabilities (Table 6, ``._stats``),
the Bayes factor with its Jeffreys rating, and the numbers of the transits in
which each alpha produces a PPO.

The scan computes and writes; it draws nothing and judges nothing: the
figures (``draw_figures``, ``jaxppo.scan(..., figures=True)``) and the
PPO-or-spot verdict (``jaxppo.activity.ppo_or_spot``) come after it, on
the finished ``ScanResult`` (the command line runs all of them).

Long runs write their progress as they go (one checksummed JSON line per
finished (case, alpha) block, flushed and fsynced) and resume without
recomputing; torn or edited lines are recomputed with a note; final outputs
are written atomically; a changed config is detected; ``restart`` removes the
old outputs before writing new ones.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
import warnings
from pathlib import Path

import numpy as np

from ._config import ScanConfig, require_scan_system
from ._keywords import Default, refuse_with_config, resolved
from ._pairs import PAIRS_HEADER, pair_reports, partners_of
from ._progress import atomic_write, read_progress, record_line
from ._chi2 import analyse_case, grid_chi2, resolution_check
from ._stats import guard_cases, plot_range, withhold_cases
from ._summary import DeprecatedSummaryAccess
from ._tables import table5_rows, write_table5
from ._windows import ScanWindow, windows_and_events, windows_data
from ..model._lightcurve import LightCurve
from ..model._overlap import no_ppo_model
from ..model._processes import is_writer, on_writer, process_info, read_once, share

__all__ = ["scan", "run_scan", "ScanResult", "draw_figures", "start_figures", "scan_products", "with_summary",
           "write_summary", "figures_current", "PROGRESS"]

PROGRESS = "scan_progress.jsonl"


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



@dataclasses.dataclass(frozen=True, eq=False)
class ScanResult(DeprecatedSummaryAccess):
    """A finished obliquity scan (immutable), as ``jaxppo.scan`` returns it.

    Delta chi^2(alpha) = chi^2(alpha) - chi^2_0 per hemisphere case, with the
    ground level chi^2_0 the median chi^2 over the alphas without a
    planet-planet occultation (PPO) in any frame; the posterior
    p(alpha | D) ~ exp(-Delta chi^2 / 2) (uniform prior, normalised over
    [0, 360) deg); the geometry probabilities, Bayes factor and Jeffreys
    rating (Mueller et al. 2021, Table 6); the peaks and dips (Table 5).

    ``result["key"]``, ``result.get(key)`` and ``key in result`` still read
    ``summary`` (the result used to be that dict) but warn: deprecated, gone
    in 1.0.

    Attributes
    ----------
    summary : dict
        What summary.json holds: ``chi2_0`` and ``probabilities`` per case,
        ``cases`` (per case: ground level, geometries, Delta chi^2 extremes
        [deg], ``ppo_transits``), the ``multi_transits`` used,
        ``detrending``, ``alpha`` [deg], ``table5``, ``resumed``, ``seconds``
        [s] of the scan; after the figures also ``figures`` (paths), after
        the command line's verdict ``ppo_or_spot``. Treat it as read-only:
        ``with_summary`` gives a new result.
    table : numpy.ndarray
        The rows of scan.csv, a structured array [n_cases * n_alpha] with
        ``case``, ``alpha`` [deg], ``chi2``, ``delta_chi2`` and
        ``posterior`` [1/deg].
    windows : tuple of ScanWindow
        The detrended multi-transit windows the chi^2 used.

    Examples
    --------
    >>> from importlib.resources import files
    >>> import jaxppo as jp
    >>> cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 1])
    >>> result = jp.scan(cfg)
    >>> result.table.dtype.names
    ('case', 'alpha', 'chi2', 'delta_chi2', 'posterior')
    >>> print(f"{result.chi2_0['same']:.3f}")
    2869.108
    >>> alpha, dchi2 = result.delta_chi2("same")
    >>> print(alpha[151], f"{dchi2[151]:.2f}")
    151.0 -3.95
    >>> geo = result.probabilities["same"]
    >>> print(geo["favoured"], f"K = {geo['bayes_factor']:.2f}", f"({geo['jeffreys']})")
    retrograde, different hemispheres K = 1.18 (barely worth mentioning)
    >>> len(result.windows), result.resumed["finished_before"]
    (7, False)

    A 30-deg grid steps over the 1-3 deg features (it gave K = 2.15): no
    probability then, and the reason:

    >>> coarse = jp.scan(jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 30]))
    >>> print(coarse.probabilities["same"]["favoured"], coarse.summary["alpha_grid_check"]["cases"]["same"]["ok"])
    None False
    """

    summary: dict
    table: np.ndarray
    windows: tuple[ScanWindow, ...]

    @property
    def config_digest(self) -> str:
        """Hash of the config and data the scan ran on (``ScanConfig.digest``)."""
        return self.summary["config_digest"]

    @property
    def chi2_0(self) -> dict:
        """The ground level chi^2_0 per case."""
        return self.summary["chi2_0"]

    @property
    def probabilities(self) -> dict:
        """Per case: the geometry probabilities, Bayes factor and rating (Table 6)."""
        return self.summary["probabilities"]

    @property
    def table5(self) -> list:
        """The peaks and dips of Delta chi^2 (paper Table 5), rows as dicts."""
        return self.summary["table5"]

    @property
    def resumed(self) -> dict:
        """How much was done before this call (``finished_before``: all of it)."""
        return self.summary["resumed"]

    def by_case(self) -> dict:
        """The columns of ``table`` per case.

        Returns
        -------
        dict
            ``{case: {"alpha", "chi2", "delta_chi2", "posterior"}}``, each an
            array [n_alpha] (alpha [deg], posterior [1/deg]), cases in scan
            order.
        """
        t = self.table
        return {str(c): {k: t[k][t["case"] == c] for k in ("alpha", "chi2", "delta_chi2", "posterior")}
                for c in dict.fromkeys(t["case"])}

    def delta_chi2(self, case: str) -> tuple[np.ndarray, np.ndarray]:
        """The Delta chi^2 curve of one hemisphere case.

        Parameters
        ----------
        case : str
            A case the scan ran, e.g. "same" or "opposite".

        Returns
        -------
        alpha : numpy.ndarray
            The tilt grid [deg], [n_alpha].
        delta_chi2 : numpy.ndarray
            chi^2(alpha) - chi^2_0, [n_alpha].

        Raises
        ------
        ValueError
            When ``case`` is not one of the scanned cases.
        """
        if case not in set(self.table["case"]):
            raise ValueError(f"case must be one of {sorted(set(self.table['case']))}, got {case!r}")
        sel = self.table["case"] == case
        return self.table["alpha"][sel], self.table["delta_chi2"][sel]

    def plot(self, ax=None):
        """Plot Delta chi^2(alpha) of every case (paper Fig. 5).

        Each case is labelled with its favoured geometry and that
        geometry's probability.

        Parameters
        ----------
        ax : matplotlib.axes.Axes or None, optional
            The axes to draw into; None: a new 8 x 3.6 inch figure.

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn into.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(8, 3.6))
        for case in dict.fromkeys(self.table["case"]):
            a, d = self.delta_chi2(case)
            geo = self.probabilities[case]
            fav = geo["favoured"]
            what = "probabilities withheld" if fav is None else f"{fav} {100 * geo[fav]['probability']:.1f} %"
            ax.plot(a, d, lw=1, label=f"case {case} ({what})")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("tilt angle alpha [deg]")
        ax.set_ylabel("Delta chi^2")
        ax.set_xlim(*plot_range(self.table["alpha"][self.table["case"] == self.table["case"][0]]))
        ax.legend(fontsize=8)
        return ax


def write_summary(out, result: ScanResult) -> None:
    """summary.json of ``result`` in the folder ``out``, atomically; strict
    JSON (no NaN / Infinity): a value that cannot be written is a bug, not a
    file."""
    path = Path(out) / "summary.json"
    text = json.dumps(result.summary, indent=2, allow_nan=False)
    on_writer(f"writing {path}", lambda: atomic_write(path, text))  # an error there stops every process


def with_summary(out, result: ScanResult, **entries) -> ScanResult:
    """A new result whose summary also holds ``entries`` (e.g. ``figures``,
    ``ppo_or_spot``), written to ``out``/summary.json (None: not written)."""
    new = dataclasses.replace(result, summary={**result.summary, **entries})
    if out is not None:
        write_summary(out, new)
    return new


def draw_figures(result: ScanResult, cfg: ScanConfig, out) -> ScanResult:
    """Draw the scan's figures (paper Figs. 4-7 and the Table 6 bars;
    ``jaxppo.obliquity._figures.scan_figures``) of a finished scan into
    ``out`` and record their paths in summary.json (``figures``)."""
    from ._worker import Drawer

    return start_figures(result, cfg, out, Drawer(use=False))(result)


# Where the command's drawing process draws these, this process draws the
# rest after its PPO-or-spot fits (the two then take about as long).
_DRAWN_APART = ("fig4", "fig6")


def start_figures(result: ScanResult, cfg: ScanConfig, out, drawer):
    """``draw_figures`` begun in ``drawer`` (a ``Drawer``: the command's
    drawing process, or this one): returns a callable that draws what the
    drawing process does not (``_DRAWN_APART``), waits for the rest and
    returns the result with the paths of all recorded in summary.json
    (``figures``, in the order of ``FIGURES``), as ``draw_figures`` does."""
    from ._figures import FIGURES, scan_figures

    args = (Path(out), result.summary, result.by_case(), cfg.system, result.windows, tuple(cfg.cases))
    apart = _DRAWN_APART if drawer.separate else FIGURES
    wait = drawer.run(scan_figures, *args, apart)

    def finish(res):
        rest = [f for f in FIGURES if f not in apart]
        here = dict(zip(rest, scan_figures(*args, rest))) if rest else {}
        drawn = {**here, **dict(zip(apart, wait()))}
        return with_summary(out, res, figures=[drawn[f] for f in FIGURES])

    return finish


def figures_current(result: ScanResult, out) -> bool:
    """Whether the figures summary.json names are all in ``out`` (a rerun
    of a finished scan then redraws nothing)."""
    files = result.summary.get("figures")
    return bool(files) and all((Path(out) / Path(f).name).is_file() for f in files)


def scan_products(result: ScanResult, cfg: ScanConfig, out, drawer) -> ScanResult:
    """After the scan: its figures (begun in ``drawer``, the command's
    drawing process), meanwhile the PPO-or-spot verdict of each negative
    dip (written into summary.json as ``ppo_or_spot``; a failure there is
    reported in the block, never fails the finished scan). What a finished
    scan already holds is not redone."""
    from ..activity import ppo_or_spot

    finish, redone = None, []
    if not share(figures_current(result, out)):  # process 0's files decide (several JAX processes)
        finish = start_figures(result, cfg, out, drawer)
        redone.append("the figures")
    block = None
    if "ppo_or_spot" not in result.summary:
        redone.append("the PPO-or-spot verdicts")
        try:
            block = ppo_or_spot(result, cfg.system, out=out)
        except Exception as exc:  # noqa: BLE001 - a summary block, not the scan's result
            block = {"error": f"{type(exc).__name__}: {exc}"}
    if finish is not None:
        result = finish(result)
    if block is not None:
        result = with_summary(out, result, ppo_or_spot=block)
    if redone and result.resumed.get("finished_before"):  # what the report says was made again
        result = with_summary(out, result, resumed=dict(result.resumed, redone=redone))
    return result


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
    if is_writer():
        tmp = path.with_name(path.name + ".tmp")
        t.write(tmp, format="ascii.ecsv", overwrite=True)
        os.replace(tmp, path)


def _clear_outputs(out: Path) -> None:
    """--restart: remove the previous scan's outputs before anything new is
    written, the finished-scan marker (summary.json) first, so an interrupted
    restart never leaves old results beside a new config."""
    for name in _output_names(out):
        p = out / name
        if p.is_file():
            p.unlink()


def _refuse_foreign_files(out: Path, cfg: ScanConfig) -> None:
    """ValueError when ``out`` holds files a scan would write over that are
    not an earlier scan's (no progress file beside them: the user's own
    files, which jaxppo never overwrites, --restart or not), or that are
    inputs of this scan (its config, data, star or transit-times files)."""
    from ._config_files import config_inputs, refuse_overwriting_inputs

    # the plain scan's own outputs (a marginal or joint run's files, which
    # such runs write beside their own progress, are not the scan's to judge)
    present = [n for n in _output_names(out) if (out / n).exists() and not n.startswith(("marginal", "joint"))]
    src = Path(cfg.source)
    refuse_overwriting_inputs([out / n for n in present], config_inputs(src, cfg.raw) if src.is_file() else set(),
                              f"--out {out}: a scan there would write")
    if present and not (out / PROGRESS).is_file():
        raise ValueError(
            f"{out} holds {', '.join(present[:6])}{' and more' if len(present) > 6 else ''} but no scan progress "
            f"({PROGRESS}): not an earlier scan's results, and a scan there would overwrite them; use another --out "
            "folder (or move those files away)")


def _output_names(out: Path) -> list:
    """The files a scan (and its marginal and joint runs) writes into
    ``out``: the finished-scan marker (summary.json) first."""
    figures = []
    summ = out / "summary.json"
    if summ.exists():
        try:
            figures = [Path(f).name for f in json.loads(summ.read_text()).get("figures", [])]
        except (json.JSONDecodeError, OSError, AttributeError, TypeError):
            figures = []
    names = ["summary.json", "scan.csv", "pairs.csv", "scan.ecsv", "table5.csv", "table5.md", "marginal.csv", "marginal.json",
             "marginal.png", "marginal_draws.json", "marginal_progress.jsonl", "ppo_or_spot.png", "joint.json",
             "joint.csv", "joint.png"] + figures + list(_FIGURE_NAMES) + ["config.json", PROGRESS]
    return list(dict.fromkeys(n for n in names if n and "/" not in n and n not in (".", "..")))


# The figure files scan_figures writes (also removed by --restart when the old
# summary.json is missing or unreadable).
_FIGURE_NAMES = ("fig4_multitransits.png", "fig5_delta_chi2.png", "fig6_cutout.png", "fig7_paths.png", "probabilities.png")


def _analysed_as_now(summary: dict) -> bool:
    """Whether a finished scan's summary has what this release's analysis
    gives: the goodness-of-fit and grid checks, the goodness of fit of each
    case (``ruled_out``: a case that fits at no tilt was rated before), the
    grid check's numbers named for their grid (``*_on_grid``), and Table
    5's intervals to the first angle beyond each run (rows with
    ``lower_open``; older ones spanned the run alone, 0 wide for a
    one-point feature)."""
    if not {"goodness_of_fit", "alpha_grid_check"} <= set(summary) or "ruled_out" not in summary["goodness_of_fit"]:
        return False
    grid = summary["alpha_grid_check"].get("cases", {})
    return (all("probabilities_on_grid" in c for c in grid.values())
            and all("lower_open" in r for r in summary.get("table5", [])))


def _finished_result(out: Path, cfg: ScanConfig, digest: str):
    """The stored result of a scan that already finished in ``out`` with this
    config (same digest, every output present), or None. A rerun then
    recomputes nothing (the command line redraws the figures only when they
    are missing)."""
    try:
        summary = json.loads((out / "summary.json").read_text())
        if summary.get("config_digest") != digest or set(summary.get("chi2_0", {})) != set(cfg.cases):
            return None
        if not all((out / n).is_file() for n in ("scan.ecsv", "table5.csv", "table5.md")) or "table5" not in summary:
            return None
        if not _analysed_as_now(summary):
            return None  # analysed by an older release: analyse again (chi^2 from the progress)
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
    windows = tuple(windows_and_events(cfg)[0])
    if partners_of(cfg.system, windows) > 1 and not ("pairs" in summary and (out / "pairs.csv").is_file()):
        return None  # finished before the scan reported pairs (or pairs.csv removed): analyse again
    n = len(expect)
    summary["resumed"] = {"alphas_done_before": n, "alphas_total": n, "finished_before": True}
    summary["progress_notes"] = []
    return ScanResult(summary, table, windows)


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


def what_changed(out: Path, cfg: ScanConfig) -> str:
    """What differs between the configuration whose results ``out`` holds
    (its config.json) and ``cfg``: the config keys (TOML tables and keys,
    the --alpha grid included), else the data or jaxppo's version."""
    try:
        before = json.loads((out / "config.json").read_text())["config"]
    except (OSError, ValueError, KeyError, TypeError):
        return "no config.json there to compare with"

    def flat(d, prefix=""):
        items = {}
        for k, v in (d.items() if isinstance(d, dict) else ()):
            key = f"{prefix}{k}"
            if isinstance(v, list) and v and all(isinstance(x, dict) for x in v):  # [[planet]] tables
                for i, x in enumerate(v):
                    items.update(flat(x, f"{key}[{i}]."))
                items[key + " count"] = str(len(v))
            else:
                items.update(flat(v, key + ".") if isinstance(v, dict) else {key: json.dumps(v, default=str)})
        return items

    a, b = flat(before), flat(json.loads(json.dumps(cfg.raw, default=str)))
    keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    if keys:
        return "changed: " + ", ".join(keys[:8]) + (f" and {len(keys) - 8} more" if len(keys) > 8 else "")
    return "the config's keys are the same: the data's contents, a star or transit-times file or jaxppo's version changed"


def _open_progress(cfg: ScanConfig, out: Path, digest: str, restart: bool):
    """Clear the old outputs (restart), read the progress (done, notes) and
    write the progress header and config.json."""
    prog_path = out / PROGRESS
    if restart:
        _clear_outputs(out)
    done, notes = read_progress(prog_path, digest, out, cfg.source, explain=lambda: what_changed(out, cfg))
    if not prog_path.exists():
        atomic_write(prog_path, json.dumps({"config_digest": digest, "source": cfg.source, "format": 2}) + "\n")
    # keep the config next to the results: jaxppo plot rebuilds it from here
    # (relative paths resolved against the absolute ``base``), from any folder
    atomic_write(out / "config.json", json.dumps({"digest": digest, "source": cfg.source, "base": cfg.base,
                                                   "config": cfg.raw}, indent=2, default=str))
    return done, notes


def _compute_chi2(cfg: ScanConfig, prog_path: Path, digest: str, data: LightCurve, done: dict, progress: bool) -> None:
    """chi^2 of every (case, alpha) not yet in ``done``, in blocks of
    ``cfg.block`` alphas, each block appended to the progress file (flushed,
    fsynced; by process 0 of several JAX processes, all of which compute
    every block together) and entered into ``done``."""
    from tqdm import tqdm

    todo = [(c, a) for c in cfg.cases for a in cfg.alpha if (c, round(float(a), 9)) not in done]
    blocks = []
    for c in cfg.cases:
        alphas = np.array([a for cc, a in todo if cc == c])
        for i in range(0, alphas.size, cfg.block):
            blocks.append((c, alphas[i:i + cfg.block]))
    bar = tqdm(total=len(cfg.cases) * cfg.alpha.size, initial=len(cfg.cases) * cfg.alpha.size - len(todo),
               desc="scan", unit="alpha", disable=not progress, leave=False)
    fh = on_writer(f"opening {prog_path}", lambda: open(prog_path, "a"))  # process 0's; None elsewhere

    def append(rec):
        fh.write(record_line(rec))
        fh.flush()
        os.fsync(fh.fileno())

    try:
        for case, alphas in blocks:
            chi2 = grid_chi2(cfg.system, data, alphas, case)
            rec = {"config_digest": digest, "case": case, "alpha": alphas.tolist(), "chi2": chi2.tolist()}
            on_writer(f"appending to {prog_path}", lambda: append(rec))  # a full disk stops every process
            for a, c2 in zip(alphas, chi2):
                done[(case, round(float(a), 9))] = float(c2)
            bar.update(alphas.size)
    finally:
        if fh is not None:
            fh.close()
    bar.close()


def _analyse(cfg: ScanConfig, done: dict, windows, data: LightCurve, step: float):
    """Per case: chi^2_0, Delta chi^2, the posterior, the geometry
    probabilities and the PPO transits (``analyse_case``). Returns (csv
    rows, table rows, summary per case)."""
    sysm = cfg.system
    tm, nsub = data.supersampled_times()
    rows, summary_cases, table, best = [], {}, [], {}
    for case in cfg.cases:  # untilted planets that overlap each other may do so in one case only
        null = no_ppo_model(sysm, tm, case).reshape(-1, nsub).mean(-1)
        chi2_null = float(np.sum(((data.flux - null) / data.flux_err) ** 2))
        chi2 = np.array([done[(case, round(float(a), 9))] for a in cfg.alpha])
        best[case] = float(np.min(chi2))
        summ, dchi2, post = analyse_case(sysm, windows, data, cfg.alpha, chi2, case, step)
        summary_cases[case] = {"chi2_0": summ.pop("chi2_0"), "chi2_null_model": chi2_null, **summ}
        for a, c2, dc, p in zip(cfg.alpha, chi2, dchi2, post):
            rows.append(f"{case},{a:.10g},{c2:.17g},{dc:.17g},{p:.17g}")
            table.append((case, float(a), float(c2), float(dc), float(p)))
    check = guard_cases(summary_cases, best, int(data.time.size))
    return rows, np.array(table, dtype=_TABLE_DTYPE), summary_cases, check


def _withhold_posterior(table, cases: dict, pairs: dict, rows: list, pair_rows: list):
    """(scan.csv rows, pairs.csv rows) with the posterior NaN (in ``table``
    too, in place) for every case whose geometries are withheld: no
    p(alpha | D) where no probability is given."""
    gone = {c for c, v in cases.items() if v["geometries"].get("withheld")}
    if gone:
        table["posterior"][np.isin(table["case"], sorted(gone))] = np.nan
        rows = [f"{r['case']},{r['alpha']:.10g},{r['chi2']:.17g},{r['delta_chi2']:.17g},{r['posterior']:.17g}"
                for r in table]
    out = []
    for row in pair_rows:
        key, case = row.split(",", 2)[:2]
        if pairs.get(key, {}).get("cases", {}).get(case, {}).get("geometries", {}).get("withheld"):
            row = row.rsplit(",", 1)[0] + ",nan"
        out.append(row)
    return rows, out


def run_scan(cfg: ScanConfig, out, restart: bool = False, progress: bool = True) -> ScanResult:
    """Run (or resume) the scan and write scan.csv, scan.ecsv, table5.csv,
    table5.md and summary.json into ``out``; no figures, no verdict (see
    ``draw_figures``, ``jaxppo.activity.ppo_or_spot``). A scan that
    already finished in ``out`` with the same config is returned as stored
    (``result.resumed["finished_before"]``): nothing is recomputed."""
    _require_x64("the obliquity scan")
    require_scan_system(cfg.system)
    out = Path(out)
    t_begin = time.perf_counter()
    digest = cfg.digest
    done, notes, stored = _read_state(cfg, out, digest, restart)
    for note in notes:
        warnings.warn(note, stacklevel=2)
    n_total = len(cfg.cases) * cfg.alpha.size
    n_before = sum((c, round(float(a), 9)) in done for c in cfg.cases for a in cfg.alpha)
    if stored is not None:
        return stored

    windows, skipped = windows_and_events(cfg)
    data = windows_data(windows, cfg.lightcurve.exposure)
    _compute_chi2(cfg, out / PROGRESS, digest, data, done, progress and is_writer())
    step = float(cfg.alpha[1] - cfg.alpha[0]) if cfg.alpha.size > 1 else 360.0
    rows, table, summary_cases, check = _analyse(cfg, done, windows, data, step)
    pairs, pair_rows = pair_reports(cfg, windows, step)
    grid = None
    if check["ok"]:  # does the grid resolve the features? (chi^2 at its midpoints)
        chi2 = {c: np.array([done[(c, round(float(a), 9))] for a in cfg.alpha]) for c in cfg.cases}
        grid = resolution_check(cfg.system, data, cfg.alpha, chi2, {c: summary_cases[c]["chi2_0"] for c in cfg.cases},
                                cfg.block, windows=windows)
        for case, g in grid["cases"].items():  # a case whose numbers move with the step, and its pairs' case
            if not g["ok"]:
                withhold_cases({case: summary_cases[case]}, g["reason"])
                for pr in pairs.values():
                    withhold_cases({case: pr["cases"][case]}, g["reason"])
    rows, pair_rows = _withhold_posterior(table, summary_cases, pairs, rows, pair_rows)
    chi2_0 = {c: summary_cases[c]["chi2_0"] for c in cfg.cases}
    summary = dict(
        config=cfg.source, config_digest=digest, chi2_0=chi2_0,
        probabilities={c: summary_cases[c]["geometries"] for c in cfg.cases}, cases=summary_cases, goodness_of_fit=check,
        alpha_grid_check=grid,
        multi_transits=[w.as_dict() for w in windows], skipped_multi_transits=skipped,
        points=int(data.time.size), supersampling=data.supersampled_times()[1], exposure=cfg.lightcurve.exposure,
        detrending=_detrend_summary(cfg),
        alpha={"start": float(cfg.alpha[0]), "stop": float(cfg.alpha[-1] + step), "step": step},
        tilted=cfg.system.planets[cfg.system.tilted].name, progress_notes=notes, seconds=None,
        data={"loaded": cfg.lightcurve.report_line(), "report": cfg.lightcurve.report},
        resumed={"alphas_done_before": n_before, "alphas_total": n_total, "finished_before": False},
        **process_info(),
    )
    if pairs:
        summary["pairs"] = pairs
    # Table 5 of the paper: the peaks and dips of Delta chi^2 (and cases 3/2 by Eq. 2)
    result = ScanResult(summary, table, tuple(windows))
    by_case = result.by_case()
    summary["table5"] = table5_rows(by_case, summary, cfg.cases)

    def write():  # process 0's files; every process returns once they are written (or all raise its error)
        atomic_write(out / "scan.csv", "case,alpha,chi2,delta_chi2,posterior\n" + "\n".join(rows) + "\n")
        if pairs:
            atomic_write(out / "pairs.csv", PAIRS_HEADER + "\n" + "\n".join(pair_rows) + "\n")
        elif (out / "pairs.csv").is_file():  # an earlier config's pairs
            (out / "pairs.csv").unlink()
        _write_ecsv(out / "scan.ecsv", table, cfg, digest, chi2_0, int(data.time.size), step)
        summary["table5_files"] = write_table5(out, by_case, summary, cfg.cases)
        summary["seconds"] = time.perf_counter() - t_begin
        write_summary(out, result)  # result holds this summary
        return {k: summary[k] for k in ("table5_files", "seconds")}

    summary.update(share(on_writer(f"writing the scan's tables into {out}", write)))  # process 0's paths and time
    return result


def _read_state(cfg: ScanConfig, out: Path, digest: str, restart: bool):
    """(done, notes, stored result or None) of the folder ``out``: read (and
    its progress header written) by process 0 alone and shared with the
    other JAX processes, so that all of them compute the same blocks."""

    def read():
        out.mkdir(parents=True, exist_ok=True)
        _refuse_foreign_files(out, cfg)
        done, notes = _open_progress(cfg, out, digest, restart)
        complete = all((c, round(float(a), 9)) in done for c in cfg.cases for a in cfg.alpha)
        return done, notes, _finished_result(out, cfg, digest) if complete and not notes else None

    def encode(state):
        done, notes, stored = state
        return {"done": [[c, a, v] for (c, a), v in done.items()], "notes": notes,
                "stored": None if stored is None else {"summary": stored.summary, "table": stored.table.tolist()}}

    def decode(state):
        got = state["stored"]
        stored = None if got is None else ScanResult(
            got["summary"], np.array([tuple(r) for r in got["table"]], dtype=_TABLE_DTYPE),
            tuple(windows_and_events(cfg)[0]))
        return {(c, a): v for c, a, v in state["done"]}, state["notes"], stored

    return read_once(read, out, encode, decode)


def scan(system, lightcurve=None, *, alpha=Default(None), cases=Default(("same", "opposite")), out=None,
         margin: float = Default(0.05), detrend: int | str | None = Default(2), baseline: float = Default(0.3),
         clip: float | str | None = Default(5.0), multi_transits=Default(None), block: int = Default(60),
         restart: bool = False, progress: bool = False, figures: bool = False) -> ScanResult:
    """Run the orbital obliquity scan (Mueller et al. 2021, Sects. 2.1 and 3.3).

    chi^2(alpha) of every tilt of the tilted planet's orbit about the line of
    sight, over all its multi-transits with data at once (the detrended
    windows of ``jaxppo.scan_windows``), for each hemisphere case; then
    the ground level chi^2_0, Delta chi^2, the posterior p(alpha | D), the
    geometry probabilities with the Bayes factor and its Jeffreys rating, and
    the peaks and dips of Delta chi^2 (paper Table 5).

    ``jp.scan(system, lightcurve, alpha=np.arange(0, 360, 1.0))`` or
    ``jp.scan(jp.load_config(path))``. A config carries its own settings:
    with one, alpha, cases, margin, detrend, baseline, clip, multi_transits
    and block are refused (ValueError naming them; set them in the file, the
    alpha grid also by ``jp.load_config(path, alpha=[start, stop, step])``).
    With a System, ``margin``, ``detrend``, ``baseline``, ``clip``,
    ``multi_transits`` and ``block`` are the config keys of the same names
    (docs/config.md), checked by the same rules (``check_scan_settings``).

    The scan writes its progress as it goes and resumes in the same ``out``
    without recomputing; a scan that already finished there with the same
    config and data is returned as stored (``result.resumed["finished_before"]``).
    Needs float64 (``jax.config.update("jax_enable_x64", True)``).

    Parameters
    ----------
    system : System or ScanConfig
        The system (``system.tilted`` is rotated by alpha), or a
        ``ScanConfig`` from ``load_config``.
    lightcurve : LightCurve or lightkurve.LightCurve, optional
        The data; a lightkurve ``LightCurve`` is converted by
        ``LightCurve.from_lightkurve``. Not with a config.
    alpha : array_like or Quantity, optional
        Tilt grid [deg] (an angle Quantity is converted), [n_alpha]; evenly spaced over 360 deg with a step
        that divides 360 (default 0, 1, ..., 359).
    cases : str or sequence of str, optional
        Hemisphere cases: "same" (paper case 1) and/or "opposite" (paper
        case 4), "+"/"-" signs per untilted planet, or "all" (default
        ``("same", "opposite")``).
    out : str or pathlib.Path or None, optional
        Folder for scan.csv, scan.ecsv, table5.csv, table5.md, summary.json,
        the progress file (resumes) and, with ``figures``, the figures;
        None: a temporary folder, removed afterwards.
    margin : float or Quantity, optional
        Out-of-transit data [d] (a time Quantity is converted) in the chi^2 on each side of an event
        (default 0.05).
    detrend : int or "none", optional
        Order 0..5 of each event's out-of-transit polynomial (default 2);
        "none" uses the flux as loaded.
    baseline : float or Quantity, optional
        Baseline [d] (a time Quantity is converted) fitted on each side of an event, > ``margin``
        (default 0.3).
    clip : float or "none", optional
        Outlier threshold [robust sigmas] >= 2 for the baseline points
        (default 5).
    multi_transits : float or sequence of float or None, optional
        Mid-times [d] of the multi-transits to use (each matched within
        0.1 d); None: all of them.
    block : int, optional
        Alphas per progress record (default 60).
    restart : bool, optional
        Remove the previous outputs in ``out`` first and start afresh.
    progress : bool, optional
        Show a progress bar.
    figures : bool, optional
        With ``out``, draw the figures of ``jaxppo scan`` after the scan has
        finished (``draw_figures``; skipped when a finished scan's
        figures are all there). The PPO-or-spot verdict of the command line
        is ``jaxppo.activity.ppo_or_spot`` (result, system, out=out).

    Returns
    -------
    ScanResult
        ``summary`` (summary.json), ``table`` (scan.csv), ``windows`` and
        ``plot()``.

    Raises
    ------
    ValueError
        When ``lightcurve`` or a scan setting is given with a
        ``ScanConfig``, when a setting is invalid (named with its
        value), when the alpha grid does not cover the whole circle evenly,
        when the data hold no usable multi-transit of the tilted planet, or
        when float64 is not enabled.

    Examples
    --------
    Inject a planet-planet occultation at alpha = 150 deg into synthetic
    Kepler-20 b + c photometry and scan a coarse grid:

    >>> import jax
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> jax.config.update("jax_enable_x64", True)
    >>> system = jp.kepler20_system()
    >>> lc = jp.simulate_kepler20(seed=1, alpha=150.0, noise=1e-4)
    >>> result = jp.scan(system, lc, alpha=np.arange(0.0, 360.0, 30.0), cases="same")
    >>> alpha, dchi2 = result.delta_chi2("same")
    >>> print(alpha[np.argmin(dchi2)], f"{dchi2.min():.2f}")
    150.0 -18.36
    >>> print(result.probabilities["same"]["favoured"])
    retrograde, different hemispheres
    """
    import tempfile

    from ._config import check_alpha_grid, config_from_arguments

    kw = dict(alpha=alpha, cases=cases, margin=margin, detrend=detrend, baseline=baseline, clip=clip,
              multi_transits=multi_transits, block=block)
    if isinstance(system, ScanConfig):
        if lightcurve is not None:
            raise ValueError("lightcurve must not be given with a ScanConfig (the config names its data)")
        refuse_with_config(kw, system, "jaxppo.scan")
        cfg = system
    else:
        cfg = config_from_arguments(system, lightcurve, **resolved(kw))
        check_alpha_grid(cfg.alpha)
    if out is None:
        with tempfile.TemporaryDirectory(prefix="jaxppo_scan_") as tmp:
            return run_scan(cfg, tmp, restart=restart, progress=progress)
    result = run_scan(cfg, out, restart=restart, progress=progress)
    if figures and not share(figures_current(result, out)):  # process 0's files decide
        result = draw_figures(result, cfg, out)
    return result
