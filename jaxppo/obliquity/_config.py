"""Scan configuration (TOML, CONVENTIONS.md): parsed and checked before any
work starts, so a bad config fails in milliseconds with the field named."""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import json
import tomllib
from pathlib import Path

import numpy as np

from ..model._lightcurve import COLUMN_ROLES, LightCurve, cadence_warning, is_lightkurve, quality_bitmask
from ..model._phoenix import data_path
from ..model._star import Star
from ..model._cases import CASES, scan_cases
from ..model._planet import Planet
from ..model._system import System, require_keplerian
from ..model._units import from_quantity
from ._config_files import default_config_path, star_file_digest, star_from_table
from ._ttv_config import planet_ttv_dict, transit_times_from, ttv_digest, ttv_settings

__all__ = ["ScanConfig", "require_scan_system", "alpha_grid", "check_alpha_grid", "check_scan_settings", "config_from_arguments",
           "config_from_dict", "finished_scan_config", "load_config", "default_config_path", "synthetic_config_path"]

_PLANET_FIELDS = ("period", "t0", "a", "inc", "radius")
_PLANET_OPTIONAL = {"e": 0.0, "omega": 90.0}  # circular unless given


def synthetic_config_path() -> Path:
    """The bundled synthetic example (1-minute cadence, white noise)."""
    return data_path("kepler20_synthetic.toml")


@dataclasses.dataclass
class ScanConfig:
    """A checked obliquity-scan configuration: the system, the data and the scan settings.

    Built by ``load_config`` from a TOML file (docs/config.md), or by
    ``jaxppo.scan`` and ``jaxppo.marginal_scan`` from their
    arguments; every field has been checked by then, so a bad config fails
    before any work starts, with the field named. Pass it to
    ``jaxppo.scan``, ``jaxppo.scan_windows`` or
    ``jaxppo.marginal_scan``; it carries its own settings, so those
    functions refuse the keyword arguments that would override them.

    Attributes
    ----------
    system : System
        The planets and star; ``system.tilted`` is the planet rotated by the
        tilt angle alpha (``tilted = true`` in the file, else the first).
    lightcurve : LightCurve
        The photometry ([data]): time [d], normalised flux and its errors.
    alpha : numpy.ndarray
        The tilt grid [deg], [n_alpha]: evenly spaced over the whole circle
        with a step that divides 360 ([scan] alpha, default 0, 1, ..., 359).
    cases : tuple of str
        The hemisphere cases scanned: "same" (paper case 1), "opposite"
        (paper case 4), or "+"/"-" signs per untilted planet.
    margin : float
        Out-of-transit data [d] kept in the chi^2 on each side of an event.
    block : int
        Alphas per progress record (how much an interrupted scan can lose).
    raw : dict
        The parsed TOML (for ``jaxppo.scan``: its arguments); what
        ``digest`` hashes.
    source : str
        The config file's path, or ``"<jaxppo.scan>"`` when built from
        Python arguments.
    detrend : int or None
        Order 0..5 of each event's out-of-transit polynomial; None: the flux
        is used as loaded.
    baseline : float
        Baseline [d] fitted on each side of an event (> ``margin``).
    clip : float or None
        Outlier threshold [robust sigmas] for the baseline points; None: no
        clipping.
    events : tuple of float or None
        Mid-times [d] of the multi-transits to use ([scan] multi_transits);
        None: every multi-transit of the tilted planet with data.
    base : str or None
        The absolute folder of the config file; relative paths start there.
    marginalize : int
        [scan] marginalize: draws of the marginalised scan (0: off).
    fit_free : tuple of str or None
        [fit] free: the parameters the marginalised scan samples, such as
        ``"b.t0"``; None: the default set.
    ttv : dict
        The checked [ttv] section (the settings of ``jaxppo ttv``).

    Examples
    --------
    >>> from importlib.resources import files
    >>> import jaxppo as jp
    >>> cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml")
    >>> [pl.name for pl in cfg.system.planets], cfg.system.tilted
    (['b', 'c'], 0)
    >>> cfg.alpha.size, cfg.cases, cfg.margin, cfg.detrend
    (360, ('same', 'opposite'), 0.05, None)
    >>> cfg.lightcurve.time.size
    2926
    >>> len(cfg.digest)  # the hash a resumed scan checks
    16
    """

    system: System
    lightcurve: LightCurve
    alpha: np.ndarray
    cases: tuple[str, ...]
    margin: float
    block: int
    raw: dict
    source: str
    detrend: int | None = 2
    baseline: float = 0.3
    clip: float | None = 5.0
    events: tuple | None = None
    base: str | None = None  # the absolute folder of the config file (relative paths start there)
    marginalize: int = 0  # [scan] marginalize: draws of the marginalised scan (0: off)
    fit_free: tuple | None = None  # [fit] free: the parameters the marginalised scan samples
    ttv: dict = dataclasses.field(default_factory=dict)  # [ttv]: jaxppo ttv's settings (ttv_settings)

    @property
    def digest(self) -> str:
        """Hash of everything that determines the results (not the path):
        the config, the data, the jaxppo version (a release that changes the
        numerics must not resume an older release's progress) and the
        exposure supersampling."""
        return self.digest_without()

    def digest_without(self, *scan_keys: str) -> str:
        """``digest`` leaving out the ``[scan]`` keys ``scan_keys`` too (the
        joint sampler, which never uses the alpha grid or its blocks, leaves
        them out: another grid must not discard its particles)."""
        from .._version import __version__

        nsub = self.lightcurve.supersampled_times()[1] if self.lightcurve.time.size else 1
        # what only the marginalised scan uses stays out: changing the number
        # of draws must not discard the plain scan's progress
        raw = {k: v for k, v in self.raw.items() if k not in ("fit", "ttv")}
        # nor does ``block``: how often progress is saved, not what is computed
        drop = ("marginalize", "block") + tuple(scan_keys)
        if isinstance(raw.get("scan"), dict):
            raw["scan"] = {k: v for k, v in raw["scan"].items() if k not in drop}
        raw.update(ttv_digest(self.system))  # transit times from a file: their values count
        raw.update(star_file_digest(self.raw.get("star"), self.system.star))  # so do a star file's
        payload = json.dumps({"config": raw, "jaxppo": __version__, "supersampling": nsub},
                             sort_keys=True, default=str).encode()
        data = np.concatenate([self.lightcurve.time, self.lightcurve.flux, self.lightcurve.flux_err]).tobytes()
        return hashlib.sha256(payload + data).hexdigest()[:16]


def _err(source, msg):
    return ValueError(f"{source}: {msg}")


# Every key a config may hold (docs/config.md documents each). A key not
# listed is an error naming it, its section and the closest valid key: a
# typo must never run with a default (``tilded = true`` tilting planet 1).
SECTIONS = ("star", "system", "planet", "data", "scan", "fit", "ttv")
STAR_KEYS = {
    "uniform": ("law",), "quadratic": ("law", "coefficients"), "nonlinear": ("law", "coefficients"),
    "power2": ("law", "coefficients"), "tabulated": ("law", "mu", "intensity", "path", "interpolation", "pad_ends"),
    "phoenix": ("law", "path", "limb"),
}
PLANET_KEYS = ("name",) + _PLANET_FIELDS + tuple(_PLANET_OPTIONAL) + ("tilted", "transit_times", "transit_epochs",
                                                                      "lnode", "mass", "moon")
# [system]: the keywords of jaxppo.System that choose and set up the orbits
SYSTEM_KEYS = ("orbits", "epoch", "star_mass", "star_radius", "dt", "span")
# [[planet.moon]]: the parameters of jaxppo.Moon (docs/config.md)
_MOON_FIELDS = ("period", "t0", "a", "inc", "radius")
MOON_KEYS = ("name",) + _MOON_FIELDS + ("mass_ratio", "lnode", "e", "omega")
DATA_KEYS = ("path", "columns", "exposure", "quality_bitmask", "mission")
COLUMN_KEYS = tuple(COLUMN_ROLES)
SCAN_KEYS = ("alpha", "cases", "margin", "block", "detrend", "baseline", "clip", "multi_transits", "marginalize")
FIT_KEYS = ("free", "stellar_density", "stellar_density_source")


def _check_keys(table: dict, valid, where: str, source: str) -> None:
    valid = tuple(valid)
    for key in table:
        if key not in valid:
            close = difflib.get_close_matches(str(key), valid, n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise _err(source, f"{where}: unknown key {key!r}{hint} (valid keys: {', '.join(valid)})")


def _star_from(section: dict, base: Path, source: str) -> Star:
    if "law" not in section:
        raise _err(source, "[star] needs law = quadratic | nonlinear | power2 | uniform | tabulated | phoenix")
    law = str(section["law"]).lower()
    if law in STAR_KEYS:
        _check_keys(section, STAR_KEYS[law], f"[star] (law = {law!r})", source)
    if law in ("phoenix", "tabulated"):
        try:
            return star_from_table(section, law, base)
        except ValueError as e:
            raise _err(source, str(e)) from e
    try:
        return Star.from_law(law, section.get("coefficients", []))
    except ValueError as e:
        raise _err(source, f"[star] {e}") from e


def check_alpha_grid(alpha) -> float:
    """The step [deg] of a valid tilt grid, or ValueError naming ``alpha``.

    The posterior is normalised over the whole circle (uniform prior on
    [0, 360)) and the geometry probabilities integrate it over fixed ranges:
    a partial grid would silently drop the prior mass of the angles it leaves
    out (e.g. "retrograde 100 %"), so the grid must be evenly spaced, span
    360 deg, and have a step that divides 360."""
    a = np.asarray(alpha, float)
    if a.ndim != 1 or a.size < 2 or not np.all(np.isfinite(a)):
        raise ValueError(f"alpha must be a 1D grid of at least 2 finite angles [deg], got shape {a.shape}")
    step = float(a[1] - a[0])
    n = 360.0 / step if step > 0 else 0.0
    if not (step > 0 and np.allclose(np.diff(a), step, rtol=0, atol=1e-9) and abs(n - round(n)) < 1e-9
            and round(n) == a.size):
        raise ValueError(
            f"alpha covers {a[0]:g} .. {a[-1]:g} deg ({a.size} angles): the posterior and the geometry probabilities "
            "need the whole circle, so alpha must be evenly spaced, span 360 deg and have a step that divides 360 "
            "(e.g. [0, 360, 1])")
    return step


MAX_ALPHAS = 360_000
"""The most tilts one scan takes (0.001 deg over the circle): a finer grid
would only exhaust memory (the chi^2 table is cases x alphas x points)."""


def alpha_grid(grid, name: str = "alpha") -> np.ndarray:
    """The tilt grid [deg] of ``[start, stop, step]`` (stop exclusive),
    checked by ``check_alpha_grid``; errors name ``name`` (the config key
    or the command-line option)."""
    if isinstance(grid, (str, bytes)) or not hasattr(grid, "__len__") or len(grid) != 3:
        raise ValueError(f"{name} must be [start, stop, step] in degrees, got {grid!r}")
    try:
        if any(isinstance(v, bool) for v in grid):
            raise TypeError
        start, stop, step = (float(v) for v in grid)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be three numbers [start, stop, step] in degrees, got {list(grid)!r}") from None
    if not all(np.isfinite(v) for v in (start, stop, step)):
        raise ValueError(f"{name} must be finite, got {list(grid)!r}")
    if not step > 0:
        raise ValueError(f"{name} step must be > 0, got {step:g}")
    if (stop - start) / step > MAX_ALPHAS:
        raise ValueError(f"{name} = [{start:g}, {stop:g}, {step:g}] asks for {(stop - start) / step:.3g} tilts; at most "
                         f"{MAX_ALPHAS} (a step of {360.0 / MAX_ALPHAS:g} deg over the circle) are scanned")
    alpha = np.arange(start, stop, step)
    if alpha.size == 0:
        raise ValueError(f"{name} grid [{start:g}, {stop:g}) with step {step:g} is empty")
    try:
        check_alpha_grid(alpha)
    except ValueError as e:
        raise ValueError(f"{name} = [{start:g}, {stop:g}, {step:g}]: {e}") from None
    return alpha


def _is_fits(p: Path) -> bool:
    name = p.name.lower()
    return p.suffix.lower() in (".fits", ".fit", ".fz") or name.endswith((".fits.gz", ".fit.gz"))


def _lightcurve_from(data: dict, base: Path, source: str) -> LightCurve:
    """[data]: path (one file or a list, e.g. one per quarter), columns,
    exposure [d]."""
    _check_keys(data, DATA_KEYS, "[data]", source)
    if isinstance(data.get("columns"), dict):
        _check_keys(data["columns"], COLUMN_KEYS, "[data] columns", source)
    if "path" not in data:
        raise _err(source, "[data] needs path = a CSV (time,flux[,flux_err]) or Kepler light-curve FITS file, or a list of them")
    paths = data["path"] if isinstance(data["path"], list) else [data["path"]]
    if not paths or not all(isinstance(p, str) for p in paths):
        raise _err(source, f"[data] path must be a file name or a non-empty list of file names, got {data['path']!r}")
    columns = data.get("columns", {})
    if not isinstance(columns, dict) or not all(isinstance(v, str) for v in columns.values()):
        raise _err(source, f"[data] columns must be a table of column names, e.g. {{time = 'bjd', flux_err = 'error'}}, got {columns!r}")
    exposure = data.get("exposure")
    instantaneous = exposure == 0 and _is_number(exposure)  # said so: no warning about long cadences
    if instantaneous:
        exposure = None
    elif exposure is not None:
        if not _is_number(exposure):
            raise _err(source, f"[data] exposure must be a number of days, got {exposure!r}")
        exposure = float(exposure)
    bitmask = data.get("quality_bitmask", "default")
    mission = data.get("mission")
    try:
        quality_bitmask(bitmask, mission)
    except ValueError as e:
        raise _err(source, f"[data] {e}") from None
    parts = []
    for p in paths:
        dpath = Path(p)
        if not dpath.is_absolute():
            dpath = base / dpath
        if not dpath.exists():
            raise _err(source, f"[data] file not found: {dpath}")
        if dpath.is_dir():
            raise _err(source, f"[data] path is a folder, not a file: {dpath}")
        try:
            if _is_fits(dpath):
                bad = sorted(set(columns) - {"flux"})
                if bad:
                    raise ValueError(f"columns.{bad[0]} is not used for Kepler / TESS FITS files (only columns.flux, "
                                     "e.g. 'SAP_FLUX')")
                lc = LightCurve.from_fits(dpath, flux_column=columns.get("flux", "PDCSAP_FLUX").upper(),
                                          quality_bitmask=bitmask, mission=mission)
            else:
                lc = LightCurve.from_csv(dpath, exposure=exposure, columns=columns, quality_bitmask=bitmask,
                                         mission=mission)
        except ValueError as e:
            raise _err(source, f"[data] {e}") from e
        parts.append(lc)
    _warn_exposure_override(parts, exposure, source)
    try:
        lc = parts[0] if len(parts) == 1 else LightCurve.concatenate(parts, exposure)
        if exposure is not None and lc.exposure != exposure:
            lc = dataclasses.replace(lc, exposure=exposure)
    except ValueError as e:
        raise _err(source, f"[data] {e}") from e
    if instantaneous:
        lc = dataclasses.replace(lc, exposure=None, instantaneous=True)  # a FITS file's TIMEDEL too
    _warn_instantaneous(lc, source)
    return lc


def _warn_exposure_override(parts, exposure, source: str) -> None:
    """Warn where ``[data] exposure`` replaces one FITS file's own (TIMEDEL):
    a list of files warns in ``LightCurve.concatenate``, one file did not, and
    a 29.4-min Kepler cadence given a TESS config's 2 minutes was modelled
    at 2 minutes without a word."""
    if exposure is None or len(parts) != 1 or parts[0].exposure is None:
        return
    own = parts[0].exposure
    if abs(own - exposure) > 1e-3 * exposure:
        import warnings

        warnings.warn(f"{source}: [data] exposure = {exposure:g} d replaces the file's own exposure (TIMEDEL) "
                      f"{own:g} d ({own * 1440:.3g} min): every point's model is averaged over {exposure * 1440:.3g} "
                      "min; leave exposure out to use the file's", UserWarning, stacklevel=3)


def _warn_instantaneous(lc: LightCurve, source: str) -> None:
    """UserWarning (``cadence_warning``) when points spaced more than
    ``LONG_CADENCE`` apart have no exposure: an instantaneous model of
    29.4-min Kepler points differs from the integrated one by far more than
    their noise in ingress and egress."""
    if cadence_warning(lc) is not None:  # (recorded in lc.report: the API does not say it again)
        import warnings

        spacing = float(np.median(np.diff(lc.time)))
        warnings.warn(f"{source}: [data] exposure is not set, so every point is modelled at one instant, but the "
                      f"points are {spacing * 1440:.1f} min apart (median): if each integrates over that time (Kepler "
                      "long cadence: exposure = 0.0204, 29.4 min), set [data] exposure = its length in days (0 if the "
                      "points are instants)", UserWarning, stacklevel=3)


def load_config(path: str | Path | None = None, alpha=None) -> ScanConfig:
    """Read and check a scan config (TOML); ``None`` gives the bundled default.

    Every section and key is checked before any work starts (docs/config.md):
    an unknown key is an error naming it and the closest valid key, so a typo
    never runs with a default. Relative data paths start at the config
    file's folder.

    Parameters
    ----------
    path : str or pathlib.Path or None, optional
        The config file. None: the bundled default, real Kepler-20
        long-cadence data (``jaxppo/data/kepler20_real_llc.toml``); the
        bundled synthetic example is ``jaxppo/data/kepler20_synthetic.toml``.
    alpha : sequence of 3 float or None, optional
        ``[start, stop, step]`` [deg] (stop exclusive) replacing
        ``[scan] alpha`` (the command line's ``--alpha``); checked the same
        way, and part of the digest. None: the file's grid.

    Returns
    -------
    ScanConfig
        The checked configuration, for ``jaxppo.scan``,
        ``jaxppo.scan_windows`` or ``jaxppo.marginal_scan``.

    Raises
    ------
    ValueError
        When the file does not exist, is a folder or is not valid TOML, or
        when a section or key is missing, unknown or invalid (the message
        names the file and the key), e.g. an alpha grid that does not cover
        the whole circle evenly.

    Examples
    --------
    >>> from importlib.resources import files
    >>> import jaxppo as jp
    >>> path = files("jaxppo") / "data" / "kepler20_synthetic.toml"
    >>> cfg = jp.load_config(path, alpha=[0, 360, 30])
    >>> cfg.alpha
    array([  0.,  30.,  60.,  90., 120., 150., 180., 210., 240., 270., 300., 330.])
    >>> jp.load_config(path, alpha=[0, 180, 1])
    Traceback (most recent call last):
    ...
    ValueError: alpha = [0, 180, 1]: alpha covers 0 .. 179 deg (180 angles): ...
    >>> real = jp.load_config()  # the bundled real Kepler-20 data
    >>> real.lightcurve.time.size, real.detrend
    (64792, 2)
    """
    path = Path(path) if path is not None else default_config_path()
    source = str(path)
    if not path.exists():
        raise ValueError(f"config file not found: {path}")
    if path.is_dir():
        raise ValueError(f"config {path} is a folder, not a TOML file")
    try:
        raw = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{source}: not valid TOML: {e}") from e
    if alpha is not None:
        alpha_grid(alpha, "alpha")  # a clear error naming alpha, before the file's
        new = [float(v) for v in alpha]
        try:
            same = [float(v) for v in raw["scan"]["alpha"]] == new
        except (KeyError, TypeError, ValueError):
            same = False
        # the same grid written differently (ints) keeps the digest, so a
        # finished scan is still recognised; a config without [scan] gets one
        # (unless the grid is the default, which it already scans)
        if "scan" not in raw and new != [0.0, 360.0, 1.0]:
            raw["scan"] = {"alpha": new}
        elif isinstance(raw.get("scan"), dict) and not same:
            raw["scan"] = dict(raw["scan"], alpha=new)
    # absolute: the saved config.json (jaxppo plot) works from any folder
    return config_from_dict(raw, path.resolve().parent, source)


def _is_number(v) -> bool:
    """A real number, not a bool (``True`` is an int to Python, a typo here)."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _none_word(v) -> bool:
    return isinstance(v, str) and v.lower() == "none"


def check_scan_settings(margin=0.05, detrend=2, baseline=0.3, clip=5.0, block=60, multi_transits=None,
                        marginalize=0) -> dict:
    """The scan settings checked and normalised: the one set of rules of
    both the config file (``[scan]``) and the Python API (``jaxppo.scan``,
    ``jaxppo.marginal_scan``).

    Args:
        margin: [d] out-of-transit data in the chi^2 on each side of an
            event, a finite number >= 0.
        detrend: order 0..5 of each event's out-of-transit polynomial (a
            whole number), or "none".
        baseline: [d] baseline fitted on each side of an event, > margin.
        clip: [robust sigmas] outlier threshold >= 2, or "none".
        block: alphas per progress record, a whole number >= 1.
        multi_transits: [d] mid-time(s) of the events to use, or None (all).
        marginalize: draws of the marginalised scan, a whole number >= 0.

    Returns:
        dict with ``margin``, ``baseline`` (float), ``detrend``, ``block``,
        ``marginalize`` (int; detrend None for "none"), ``clip`` (float or
        None) and ``events`` (tuple of float, or None).

    Raises:
        ValueError naming the parameter and the value.
    """
    if not (_is_number(margin) and np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a number of days >= 0, got {margin!r}")
    if _none_word(detrend):
        detrend = None
    elif not (_is_number(detrend) and np.isfinite(detrend) and int(detrend) == detrend and 0 <= detrend <= 5):
        raise ValueError(f"detrend must be a polynomial order 0..5 or \"none\", got {detrend!r}")
    if not (_is_number(baseline) and np.isfinite(baseline) and baseline > margin):
        raise ValueError(f"baseline must be a number of days > margin ({margin} d), got {baseline!r}")
    if _none_word(clip):
        clip = None
    elif not (_is_number(clip) and clip >= 2):
        raise ValueError(f"clip must be a threshold >= 2 (robust sigmas) or \"none\", got {clip!r}")
    for name, v, lo, what in (("block", block, 1, "an integer"), ("marginalize", marginalize, 0, "a number of draws")):
        if not (_is_number(v) and np.isfinite(v) and int(v) == v and v >= lo):
            extra = " (0: off)" if name == "marginalize" else ""
            raise ValueError(f"{name} must be {what} >= {lo}{extra}, got {v!r}")
    events = None
    if multi_transits is not None:
        m = multi_transits if isinstance(multi_transits, (list, tuple, np.ndarray)) else [multi_transits]
        if not (len(m) and np.ndim(m) == 1 and all(_is_number(v) and np.isfinite(v) for v in m)):
            raise ValueError(f"multi_transits must be a mid-time or a non-empty list of mid-times [d], "
                             f"got {multi_transits!r}")
        events = tuple(float(v) for v in m)
    return {"margin": float(margin), "detrend": None if detrend is None else int(detrend),
            "baseline": float(baseline), "clip": None if clip is None else float(clip), "block": int(block),
            "events": events, "marginalize": int(marginalize)}


def config_from_arguments(system, lightcurve, alpha, cases, margin, detrend, baseline, clip, multi_transits,
                          block) -> ScanConfig:
    """A checked ``ScanConfig`` from the arguments of ``jaxppo.scan``
    (the checks of ``check_scan_settings``, as for a config file)."""
    if not isinstance(system, System):
        raise ValueError(f"system must be a jaxppo.System or a ScanConfig, got {type(system).__name__}")
    require_scan_system(system)
    if is_lightkurve(lightcurve) and not isinstance(lightcurve, LightCurve):
        # a lightkurve LightCurve: its default quality bitmask, flux divided
        # by its median, exposure from TIMEDEL; the drops are in the report
        lightcurve = LightCurve.from_lightkurve(lightcurve)
    if not isinstance(lightcurve, LightCurve):
        raise ValueError(f"lightcurve must be a jaxppo.LightCurve or a lightkurve LightCurve, got {type(lightcurve).__name__}")
    # an angle Quantity in degrees (its bare radians were taken as degrees)
    alpha = np.arange(0.0, 360.0, 1.0) if alpha is None else np.asarray(from_quantity("alpha", alpha, "deg"), float)
    try:
        cases = scan_cases(system, cases)
    except ValueError as e:
        raise ValueError(f"cases = {cases!r}: {e}") from None
    # time Quantities (or TimeDeltas) in days; plain values are checked as in a config file
    margin, baseline = (from_quantity(n, v, "d") if hasattr(v, "unit") or hasattr(v, "jd1") else v
                        for n, v in (("margin", margin), ("baseline", baseline)))
    margin, baseline = (float(v) if isinstance(v, np.ndarray) and v.ndim == 0 else v for v in (margin, baseline))
    if multi_transits is not None and (hasattr(multi_transits, "unit") or hasattr(multi_transits, "jd1")):
        multi_transits = np.atleast_1d(from_quantity("multi_transits", multi_transits, "d")).tolist()
    s = check_scan_settings(margin, detrend, baseline, clip, block, multi_transits)
    star = system.star
    # what determines the results goes into the digest (resuming, --restart);
    # detrend and clip as given, so that the digest of earlier runs holds
    raw = {
        "star": {"law": star.law, "params": np.asarray(star.params).tolist(),
                 "mu_nodes": None if star.mu_nodes is None else np.asarray(star.mu_nodes).tolist(),
                 "interpolation": star.interpolation},
        "planet": [{"name": pl.name, **{f: float(getattr(pl, f)) for f in ("period", "t0", "a", "inc", "radius")},
                    **_orientation(pl), **planet_ttv_dict(pl)} for pl in system.planets],
        "tilted": system.tilted,
        "data": {"exposure": lightcurve.exposure, "errors_estimated": lightcurve.errors_estimated},
        "scan": {"alpha": alpha.tolist(), "cases": list(cases), "margin": s["margin"],
                 "detrend": None if s["detrend"] is None else detrend, "baseline": s["baseline"],
                 "clip": None if s["clip"] is None else clip, "multi_transits": s["events"], "block": s["block"]},
    }
    return ScanConfig(system, lightcurve, alpha, cases, s["margin"], s["block"], raw, "<jaxppo.scan>",
                      s["detrend"], s["baseline"], s["clip"], s["events"])


def _orientation(pl: Planet) -> dict:
    """e, omega and lnode of a planet for the digest of a scan from Python
    arguments: only where they differ from the defaults, so that circular,
    unrotated planets keep the digests of earlier runs (a scan of an
    eccentric planet once resumed the circular planet's progress)."""
    out = {} if pl.circular else {"e": float(pl.e), "omega": float(pl.omega)}
    if float(pl.lnode) != 0.0:
        out["lnode"] = float(pl.lnode)
    return out


def require_scan_system(system: System, what: str = "the obliquity scan") -> None:
    """Refuse a system the obliquity scan cannot model, naming why: one
    planet (no pair to tilt against), N-body orbits or moons (its windows
    and masks come from Keplerian ephemerides); fits and sampling take
    every system."""
    require_keplerian(system, what)
    nodes = {float(pl.lnode) for i, pl in enumerate(system.planets) if i != system.tilted}
    if len(nodes) > 1:
        # the hemisphere cases list the tilted planet in one hemisphere only:
        # its mirror image is a tilt of the listed cases when every untilted
        # planet shares one node (a turn of the whole sky then undoes it),
        # not otherwise (half the geometries would be missing, 5e-3 off)
        raise ValueError(f"{what} needs the untilted planets on one node (lnode), got "
                         f"{sorted(nodes)} deg: turn them to a common node, or tilt another planet")
    if len(system.planets) < 2:
        raise ValueError(f"{what} needs at least two planets (one is tilted against the others), got "
                         f"{len(system.planets)}; jaxppo fit / sample (without --windows) and jp.fit / jp.sample "
                         "take a single planet")


def _numbers(table: dict, keys, where: str, source: str) -> dict:
    """The numeric ``keys`` present in ``table`` as floats; a quoted number
    ("0.018") or a bool is a typo, not a value."""
    for f in keys:
        if f in table and (isinstance(table[f], bool) or not isinstance(table[f], (int, float))):
            raise _err(source, f"{where}: {f} must be a number, got {table[f]!r}")
    return {f: float(table[f]) for f in keys if f in table}


def _system_options(raw: dict, source: str) -> dict:
    """[system]: the orbit model and, for orbits = "nbody", its keywords
    (checked by ``System``, which names a missing or bad one)."""
    sec = raw.get("system", {})
    if not isinstance(sec, dict):
        raise _err(source, "[system] must be a table (a [system] section)")
    _check_keys(sec, SYSTEM_KEYS, "[system]", source)
    orbits = sec.get("orbits", "kepler")
    if orbits not in ("kepler", "nbody"):
        raise _err(source, f"[system] orbits must be \"kepler\" or \"nbody\", got {orbits!r}")
    options = dict(orbits=orbits, **_numbers(sec, ("epoch", "star_mass", "star_radius", "dt"), "[system]", source))
    if "span" in sec:
        span = sec["span"]
        if not (isinstance(span, list) and len(span) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in span)):
            raise _err(source, f"[system] span must be [t_min, t_max] in days, got {span!r}")
        options["span"] = (float(span[0]), float(span[1]))
    return options


def _moons_from(p: dict, where: str, source: str) -> tuple:
    """The [[planet.moon]] tables of one planet entry, as ``Moon``s."""
    from ..model._moon import Moon

    entries = p.get("moon", [])
    if isinstance(entries, dict):
        entries = [entries]
    if not (isinstance(entries, list) and all(isinstance(m, dict) for m in entries)):
        raise _err(source, f"{where}: moon must be [[planet.moon]] tables, got {entries!r}")
    moons = []
    for j, m in enumerate(entries):
        at = f"{where} moon #{j + 1} ({m.get('name', 'unnamed')})"
        _check_keys(m, MOON_KEYS, at, source)
        if missing := [f for f in _MOON_FIELDS if f not in m]:
            raise _err(source, f"{at} is missing {missing}")
        if not isinstance(m.get("name", ""), str):
            raise _err(source, f"{at}: name must be a string, got {m['name']!r}")
        values = _numbers(m, MOON_KEYS[1:], at, source)  # names the key itself
        try:
            # unnamed: "" as for jp.Moon, so its parameters are b.moon<k>.* either way
            moons.append(Moon(**values, name=m.get("name", "")))
        except (TypeError, ValueError) as e:
            raise _err(source, f"{at}: {e}") from e
    return tuple(moons)


def _planets_from(raw: dict, star: Star, source: str, base=".") -> System:
    """[system] and the [[planet]] entries (with their [[planet.moon]]
    tables): the system, tilted the one with tilted = true."""
    options = _system_options(raw, source)
    planets, tilted = [], []
    entries = raw["planet"] if isinstance(raw["planet"], list) else [raw["planet"]]
    # N-body planets may leave out a (derived from the masses by Kepler's third law)
    required = tuple(f for f in _PLANET_FIELDS if f != "a" or options["orbits"] == "kepler")
    for i, p in enumerate(entries):
        if not isinstance(p, dict):
            raise _err(source, "[[planet]] entries must be tables ([[planet]] sections)")
        where = f"[[planet]] #{i + 1} ({p.get('name', 'unnamed')})"
        _check_keys(p, PLANET_KEYS, where, source)
        if not isinstance(p.get("tilted", False), bool):
            raise _err(source, f"[[planet]] #{i + 1}: tilted must be true or false, got {p['tilted']!r}")
        if missing := [f for f in required if f not in p]:
            raise _err(source, f"{where} is missing {missing}")
        values = _numbers(p, _PLANET_FIELDS + tuple(_PLANET_OPTIONAL) + ("lnode", "mass"), where, source)
        moons = _moons_from(p, where, source)
        try:
            values = {"a": None, **_PLANET_OPTIONAL, **values, **transit_times_from(p, base)}
            planets.append(Planet(**values, moons=moons, name=str(p.get("name", f"p{i + 1}"))))
        except (TypeError, ValueError) as e:
            raise _err(source, f"[[planet]] #{i + 1}: {e}") from e
        if p.get("tilted", False):
            tilted.append(i)
    if len(tilted) > 1:
        raise _err(source, f"only one planet may have tilted = true, got {len(tilted)}")
    try:
        return System(star, planets, tilted=tilted[0] if tilted else 0, **options)
    except ImportError as e:
        raise _err(source, f"[system] orbits = \"nbody\" needs jnkepler: pip install 'jaxppo[nbody]' ({e})") from e
    except (TypeError, ValueError) as e:
        raise _err(source, f"[system] / [[planet]]: {e}") from e


def _fit_from(raw: dict, system: System, source: str):
    """[fit]: the free parameters of the marginalised scan (or None), with
    the stellar-density prior checked."""
    fit = raw.get("fit", {})
    if not isinstance(fit, dict):
        raise _err(source, "[fit] must be a table (a [fit] section)")
    _check_keys(fit, FIT_KEYS, "[fit]", source)
    free = fit.get("free")
    if free is not None:
        if not (isinstance(free, list) and free and all(isinstance(v, str) for v in free)):
            raise _err(source, f"[fit] free must be a list of parameter names such as \"b.t0\", got {free!r}")
        from ..inference._params import parameter_names

        valid = parameter_names(system)
        bad = [v for v in free if v not in valid]
        if bad:
            raise _err(source, f"[fit] free: unknown parameter(s) {bad}; valid: {list(valid)}")
        if twice := sorted({v for v in free if free.count(v) > 1}):
            raise _err(source, f"[fit] free names {', '.join(twice)} more than once: {free}")
        free = tuple(free)
    rho = fit.get("stellar_density")
    if rho is not None and not (isinstance(rho, list) and len(rho) == 2
                                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in rho)
                                and all(np.isfinite(v) and v > 0 for v in rho)):
        raise _err(source, f"[fit] stellar_density must be [mean, sd] in g/cm^3, both > 0, got {rho!r}")
    if not isinstance(fit.get("stellar_density_source", ""), str):
        raise _err(source, f"[fit] stellar_density_source must be a string, got {fit['stellar_density_source']!r}")
    return free


def config_from_dict(raw: dict, base, source: str = "<dict>") -> ScanConfig:
    """A checked ``ScanConfig`` from the parsed TOML ``raw``; relative
    paths are relative to the folder ``base``. The [scan] settings go through
    ``check_scan_settings``, as the Python API's do."""
    base = Path(base)
    _check_keys(raw, SECTIONS, "top level (sections)", source)
    for sec in ("star", "data", "scan"):
        if sec in raw and not isinstance(raw[sec], dict):
            raise _err(source, f"[{sec}] must be a table (a [{sec}] section)")
    raw = dict(raw)
    raw.setdefault("scan", {})  # every [scan] key has a default (docs/config.md)
    for sec in ("star", "planet", "data"):
        if sec not in raw:
            raise _err(source, f"missing section [{sec}]" if sec != "planet" else "missing [[planet]] entries")
    star = _star_from(raw["star"], base, source)
    system = _planets_from(raw, star, source, base)
    lc = _lightcurve_from(raw["data"], base, source)

    scan = raw["scan"]
    _check_keys(scan, SCAN_KEYS, "[scan]", source)
    try:
        alpha = alpha_grid(scan.get("alpha", [0.0, 360.0, 1.0]), "[scan] alpha")
    except ValueError as e:
        raise _err(source, str(e)) from None
    cases = scan.get("cases", list(CASES))
    try:
        # one planet (a fit or sample config): no cases unless [scan] names some
        cases = scan_cases(system, cases) if len(system.planets) > 1 or "cases" in scan else ()
    except ValueError as e:
        raise _err(source, f"[scan] cases = {cases!r}: {e}") from None
    try:
        s = check_scan_settings(**{k: scan[k] for k in ("margin", "detrend", "baseline", "clip", "block",
                                                         "multi_transits", "marginalize") if k in scan})
    except ValueError as e:
        raise _err(source, f"[scan] {e}") from None
    free = _fit_from(raw, system, source)
    try:
        ttv = ttv_settings(raw.get("ttv", {}), system, base)
    except ValueError as e:
        raise _err(source, f"[ttv] {e}") from None
    return ScanConfig(system, lc, alpha, cases, s["margin"], s["block"], raw, source, s["detrend"], s["baseline"],
                      s["clip"], s["events"], str(base), s["marginalize"], free, ttv)


def finished_scan_config(out) -> tuple[ScanConfig, dict]:
    """(config, summary) of the finished scan in the folder ``out``: the
    config rebuilt from ``out``/config.json (data paths resolved against the
    config's absolute folder, so from any working directory) and checked
    against the digest in ``out``/summary.json."""
    out = Path(out)
    if not out.exists():
        raise ValueError(f"DIR {out}: no such folder")
    if not out.is_dir():
        raise ValueError(f"DIR {out} is a file; give the scan's output folder")
    for name in ("summary.json", "scan.csv"):
        if not (out / name).exists():
            raise ValueError(f"{out} holds no finished scan ({name} missing)")
    try:
        summary = json.loads((out / "summary.json").read_text())
        saved = json.loads((out / "config.json").read_text()) if (out / "config.json").exists() else {}
    except json.JSONDecodeError as err:
        raise ValueError(f"{out}: summary.json or config.json is not valid JSON ({err}); rerun the scan") from None
    if summary.get("config") == "<jaxppo.scan>":
        raise ValueError(f"{out} was written by jaxppo.scan() from Python, without a config file; "
                         "redraw it there with ScanResult.plot()")
    if saved.get("base") and isinstance(saved.get("config"), dict):
        cfg = config_from_dict(saved["config"], saved["base"], saved.get("source", str(out / "config.json")))
    else:  # written before config.json carried the config's folder
        cfg = load_config(summary["config"])
    if cfg.digest != summary.get("config_digest"):
        raise ValueError(f"the data or config of the scan in {out} changed since it ran ({summary['config']}); "
                         "rerun the scan")
    return cfg, summary
