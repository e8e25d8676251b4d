"""LightCurve: photometry with errors, from CSV, Kepler / TESS FITS files,
lightkurve objects or astropy Time / Quantity arrays."""

from __future__ import annotations

import csv
import dataclasses
import gzip
import warnings
from pathlib import Path

import numpy as np


SUB_EXPOSURE = 0.5 / 1440.0  # [d] longest sub-exposure of the default exposure average

__all__ = ["LightCurve", "QUALITY_FLAGS", "QUALITY_BITMASKS", "quality_bitmask"]

# Column roles and the names looked up when the user does not name them.
COLUMN_ROLES = {
    "time": ("time", "time_bkjd", "bkjd", "t"),
    "flux": ("flux", "pdcsap_flux", "f"),
    "flux_err": ("flux_err", "pdcsap_flux_err", "err", "sigma"),
    "quality": ("quality", "sap_quality"),
    "quarter": ("quarter",),
}

# Quality flag bits of the missions' light-curve files: Kepler Archive Manual
# (KDMC-10008-006, Table 2-3, SAP_QUALITY) and TESS Science Data Products
# Description Document (EXP-TESS-ARC-ICD-0014, Table 28, QUALITY).
QUALITY_FLAGS = {
    "kepler": {
        1: "attitude tweak", 2: "safe mode", 4: "coarse point", 8: "Earth point", 16: "zero crossing",
        32: "desaturation event", 64: "Argabrightening", 128: "cosmic ray in optimal aperture",
        256: "manual exclude", 1024: "sudden sensitivity dropout", 2048: "impulsive outlier",
        4096: "Argabrightening on CCD", 8192: "cosmic ray in collateral data", 16384: "detector anomaly",
        32768: "no fine point", 65536: "no data", 131072: "rolling band in optimal aperture",
        262144: "rolling band in full mask", 524288: "possible thruster firing", 1048576: "thruster firing",
    },
    "tess": {
        1: "attitude tweak", 2: "safe mode", 4: "coarse point", 8: "Earth point", 16: "Argabrightening",
        32: "desaturation event", 64: "cosmic ray in optimal aperture", 128: "manual exclude",
        256: "discontinuity", 512: "impulsive outlier", 1024: "cosmic ray in collateral data",
        2048: "straylight (manual)", 4096: "straylight (automatic)", 8192: "planet search exclude",
        16384: "bad calibration exclude", 32768: "insufficient targets",
    },
}


def _bits(mission: str, names) -> int:
    inv = {v: k for k, v in QUALITY_FLAGS[mission].items()}
    return int(sum(inv[n] for n in names))


# The named bitmasks (the same sets as lightkurve's KeplerQualityFlags and
# TessQualityFlags). "default": cadences that are certainly unusable
# (spacecraft not in fine point, no data, manual excludes, desaturations,
# thruster firings; TESS also impulsive outliers and bad calibration);
# cosmic-ray and rolling-band flags are kept because the pipeline already
# corrected those cadences. "hard" adds them; "hardest": every bit.
_KEPLER_DEFAULT = _bits("kepler", ("attitude tweak", "safe mode", "coarse point", "Earth point", "desaturation event",
                                   "manual exclude", "detector anomaly", "no data", "thruster firing"))
_TESS_DEFAULT = _bits("tess", ("attitude tweak", "safe mode", "coarse point", "Earth point", "Argabrightening",
                               "desaturation event", "manual exclude", "impulsive outlier", "bad calibration exclude"))
QUALITY_BITMASKS = {
    "kepler": {"none": 0, "default": _KEPLER_DEFAULT,
               "hard": _KEPLER_DEFAULT | _bits("kepler", ("sudden sensitivity dropout", "cosmic ray in optimal aperture",
                                                          "cosmic ray in collateral data", "possible thruster firing")),
               "hardest": 2**21 - 1 - 512},  # every defined bit (512 is unused by Kepler)
    "tess": {"none": 0, "default": _TESS_DEFAULT,
             "hard": _TESS_DEFAULT | _bits("tess", ("cosmic ray in optimal aperture", "cosmic ray in collateral data",
                                                    "straylight (manual)", "straylight (automatic)")),
             "hardest": 2**16 - 1},
}
# The time systems of the missions' files: TIME = BJD_TDB - zero [d].
_TIME_ZERO = {"kepler": (2454833.0, "BKJD"), "tess": (2457000.0, "BTJD")}


def _mission(name) -> str | None:
    if name is None:
        return None
    m = str(name).strip().lower()
    if m in ("kepler", "k2"):
        return "kepler"
    if m == "tess":
        return "tess"
    raise ValueError(f"mission must be 'kepler', 'k2' or 'tess', got {name!r}")


def quality_bitmask(bitmask="default", mission: str | None = None) -> tuple[int, str]:
    """(integer bitmask, description) of ``bitmask``: a name ("none",
    "default", "hard", "hardest", see :data:`QUALITY_BITMASKS`) or an
    integer; a point is dropped when ``quality & bitmask != 0``. Without a
    mission (a CSV file) the flag bits have no known meaning: the names other
    than "none" then drop every flagged point (bitmask -1, all bits)."""
    m = _mission(mission)
    if isinstance(bitmask, (bool, np.bool_)) or not isinstance(bitmask, (str, int, np.integer)):
        raise ValueError(f"quality_bitmask must be 'none', 'default', 'hard', 'hardest' or an integer, got {bitmask!r}")
    if isinstance(bitmask, str):
        name = bitmask.strip().lower()
        if name not in ("none", "default", "hard", "hardest"):
            raise ValueError(f"quality_bitmask must be 'none', 'default', 'hard', 'hardest' or an integer, got {bitmask!r}")
        if m is None:
            return (0, "none: flags ignored") if name == "none" else (-1, f"{name}: mission unknown, every flagged point dropped")
        return QUALITY_BITMASKS[m][name], f"{name} ({m}: {QUALITY_BITMASKS[m][name]})"
    if int(bitmask) < -1:
        raise ValueError(f"quality_bitmask must be >= 0 (or -1 for all bits), got {bitmask!r}")
    return int(bitmask), f"{int(bitmask)}"


# the methods' argument of the same name shadows the function
_resolve_bitmask = quality_bitmask


def _plain(x, what: str, unit=None):
    """A float array from a list, array, astropy Quantity or masked array
    (masked entries become NaN, so that they are counted as dropped). A
    Quantity is converted to ``unit``; with ``unit=None`` its unit is
    returned for the caller to judge."""
    import astropy.units as u

    mask = None
    if hasattr(x, "unmasked") and hasattr(x, "mask"):  # astropy Masked / MaskedQuantity
        mask, x = np.asarray(x.mask, bool), x.unmasked
    elif np.ma.isMaskedArray(x):
        mask, x = np.ma.getmaskarray(x), x.data if not isinstance(x, u.Quantity) else x
    xunit = None
    if isinstance(x, u.Quantity):
        if unit is not None:
            try:
                x = x.to_value(unit)
            except u.UnitConversionError as err:
                raise ValueError(f"{what} has unit {x.unit}, which does not convert to {unit}") from None
        else:
            xunit, x = x.unit, x.value
    v = np.array(x, dtype=float)
    if mask is not None and mask.shape == v.shape:
        v[mask] = np.nan
    return (v, xunit) if unit is None else v


def _days(t, time_zero=None) -> tuple[np.ndarray, str | None]:
    """Times [d] and a statement of their zero point.

    An astropy ``Time`` becomes BJD_TDB - ``time_zero`` [d], computed from the
    two-double (jd1, jd2) representation so that no precision is lost. Its
    zero point defaults to the one of its format: 2454833 for "bkjd"
    (Kepler, lightkurve), 2457000 for "btjd" (TESS); any other format needs
    ``time_zero`` (the planets' t0 must be on the same scale, and guessing it
    would shift every transit by years). NOTE: the scale is converted to TDB;
    a barycentric correction is not applied (give barycentric times). A time
    Quantity is converted to days; plain numbers are taken as days."""
    if _is_plain(t):
        return np.asarray(t, float), None
    from astropy.time import Time
    import astropy.units as u

    if isinstance(t, Time):
        fmt = t.format
        if time_zero is None:
            zeros = {"bkjd": _TIME_ZERO["kepler"], "btjd": _TIME_ZERO["tess"]}
            if fmt not in zeros:
                raise ValueError(
                    f"time is an astropy Time in format {fmt!r}: set time_zero [JD] (e.g. 2454833.0 for BKJD, "
                    "2457000.0 for BTJD), the zero point of the planets' t0")
            zero, label = zeros[fmt]
        else:
            zero = float(time_zero)
            label = {v[0]: v[1] for v in _TIME_ZERO.values()}.get(zero)
        tdb = t.tdb
        days = (np.asarray(tdb.jd1, float) - zero) + np.asarray(tdb.jd2, float)
        note = f"BJD_TDB - {zero:.1f} [d]" + (f" ({label})" if label else "") + f", from astropy Time ({fmt}, {t.scale})"
        return np.atleast_1d(days), note
    if isinstance(t, u.Quantity) or (hasattr(t, "unmasked") and isinstance(getattr(t, "unmasked"), u.Quantity)):
        return _plain(t, "time", u.day), None
    return _plain(t, "time", None)[0], None


def _is_plain(x) -> bool:
    """A list or a bare numpy array (not a Quantity, Time or masked array):
    no astropy import needed."""
    return type(x) is np.ndarray or isinstance(x, (list, tuple, float, int))


def is_lightkurve(x) -> bool:
    return hasattr(x, "flux") and hasattr(x, "time") and hasattr(x, "meta")


def _flux_values(f, e, normalize):
    """(flux, flux_err, normalize) as floats; a flux Quantity with a physical
    unit (e.g. e-/s) must be normalised, a dimensionless one is taken as is."""
    if _is_plain(f) and (e is None or _is_plain(e)):
        return np.asarray(f, float), None if e is None else np.asarray(e, float), normalize
    import astropy.units as u

    fv, funit = _plain(f, "flux")
    ev = None
    if e is not None:
        ev = _plain(e, "flux_err", funit) if funit is not None else _plain(e, "flux_err")[0]
    if funit is not None and funit.physical_type == "dimensionless":
        scale = funit.to(u.dimensionless_unscaled)
        fv = fv * scale
        ev = None if ev is None else ev * scale
    elif funit is not None:
        if normalize is False:
            raise ValueError(f"flux has unit {funit}: a LightCurve holds relative flux; LightCurve.from_arrays(..., "
                             "normalize=True) divides it by its median")
        normalize = True
    return fv, ev, normalize


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _diff_sigma(f: np.ndarray) -> float:
    """Robust white-noise sigma from successive differences: 1.4826 x the
    median absolute deviation of diff(f), / sqrt(2). Slow trends and a few
    jumps (transits, gaps) barely move it."""
    if f.size < 3:
        return float("nan")
    d = np.diff(f)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def _kepler_exposure(hdr) -> float | None:
    """The window [d] over which one Kepler cadence integrates the flux.

    Kepler Archive Manual (KDMC-10008) keywords: INT_TIME is the photon
    accumulation time of ONE frame (6.02 s), READTIME its readout (0.52 s),
    FRAMETIM = INT_TIME + READTIME, NUM_FRM the frames co-added per cadence
    (270 long, 9 short) and TIMEDEL the cadence length [d]. The 270 frames
    are spread evenly over the whole cadence, so the light curve is the flux
    averaged over TIMEDEL = FRAMETIM x NUM_FRM (29.4 min), not over the
    summed photon time INT_TIME x NUM_FRM (27.1 min, which the readout gaps
    interleave and which is TIMEDEL x DEADC)."""
    if "TIMEDEL" in hdr:
        return float(hdr["TIMEDEL"])
    if "FRAMETIM" in hdr and "NUM_FRM" in hdr:
        return float(hdr["FRAMETIM"]) * float(hdr["NUM_FRM"]) / 86400.0
    if "INT_TIME" in hdr and "READTIME" in hdr and "NUM_FRM" in hdr:
        return (float(hdr["INT_TIME"]) + float(hdr["READTIME"])) * float(hdr["NUM_FRM"]) / 86400.0
    return None


@dataclasses.dataclass(frozen=True)
class LightCurve:
    """Time [d], relative flux and its 1-sigma error; ``exposure`` [d] is the
    integration time of each point (e.g. 0.0204 for Kepler long cadence), used
    to average the model over the exposure. ``report`` says what loading
    dropped (:meth:`report_line` in words). ``errors_estimated``: the file had
    no errors and ``flux_err`` is an estimate from the scatter (the scan
    re-estimates it per window).

    ``time`` may be an astropy ``Time`` (converted to BJD_TDB - ``time_zero``
    [d]; formats "bkjd" and "btjd" carry their own zero point, 2454833 and
    2457000) or a time Quantity; ``flux`` and ``flux_err`` may be
    dimensionless Quantities (raw fluxes in e-/s: :meth:`from_arrays` with
    ``normalize=True``). The constructor is strict: every value finite,
    errors > 0, no repeated time stamp (it would count twice in chi^2); the
    loaders drop such points and say so in ``report``."""

    time: np.ndarray
    flux: np.ndarray
    flux_err: np.ndarray
    exposure: float | None = None
    report: dict = dataclasses.field(default_factory=dict)
    errors_estimated: bool = False
    time_zero: float | None = None

    def __post_init__(self):
        if is_lightkurve(self.time):
            raise ValueError("a lightkurve LightCurve goes through LightCurve.from_lightkurve(lc)")
        t, note = _days(self.time, self.time_zero)
        f, e, _ = _flux_values(self.flux, self.flux_err, False)
        if t.ndim != 1 or f.shape != t.shape or e.shape != t.shape:
            raise ValueError(f"time, flux and flux_err must be 1D of equal length, got {t.shape}, {f.shape}, {e.shape}")
        if t.size == 0:
            raise ValueError("the light curve has no points")
        for name, v in (("time", t), ("flux", f), ("flux_err", e)):
            if not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be finite, found {int(np.sum(~np.isfinite(v)))} non-finite values "
                                 "(LightCurve.from_arrays drops them and reports it)")
        if np.any(e <= 0):
            raise ValueError(f"flux_err must be > 0, found {e[e <= 0][0]}")
        if self.exposure is not None and not (np.isfinite(self.exposure) and self.exposure > 0):
            raise ValueError(f"exposure must be > 0 days, got {self.exposure}")
        order = np.argsort(t, kind="stable")
        t = t[order]
        dup = np.diff(t) == 0
        if dup.any():
            raise ValueError(f"time has {int(dup.sum())} repeated time stamps (first at {t[1:][dup][0]!r}); each would "
                             "count twice in chi^2 (LightCurve.from_arrays keeps the first and reports it)")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "flux", f[order])
        object.__setattr__(self, "flux_err", e[order])
        if note is not None and "time" not in self.report:
            object.__setattr__(self, "report", dict(self.report, time=note))

    def __len__(self) -> int:
        return self.time.size

    def report_line(self) -> str:
        """What loading kept and dropped, in one line (also in the scan summary)."""
        r = self.report
        parts = r.get("sources", [r]) if r else []
        if not parts or "points" not in parts[0]:
            return f"{len(self)} points (given as arrays; nothing dropped)"
        tot = {k: sum(int(p.get(k, 0)) for p in parts) for k in ("points", "flagged", "non_finite", "duplicated",
                                                                 "flags_kept")}
        masks = sorted({str(p.get("quality_bitmask_name", "none")) for p in parts})
        src = parts[0]["source"] if len(parts) == 1 else f"{len(parts)} files"
        s = (f"{len(self)} of {tot['points']} points kept from {src}; dropped: {tot['flagged']} flagged "
             f"(quality bitmask {', '.join(masks)}), {tot['non_finite']} non-finite or with error <= 0, "
             f"{tot['duplicated']} repeated time stamps")
        if tot["flags_kept"]:
            s += f"; {tot['flags_kept']} points with flags outside the bitmask kept"
        if r.get("time"):
            s += f"; time: {r['time']}"
        return s

    # ---- loading ----------------------------------------------------------------
    @classmethod
    def _from_columns(cls, t, f, e, q, exposure, source, normalize=True, segment=None, bitmask=(-1, "any flag"),
                      time_note=None, extra=None) -> "LightCurve":
        """Drop flagged (``q & bitmask != 0``; a missing flag counts as
        flagged), non-finite and repeated-time points (the first of each
        repeated stamp is kept), counting each in ``report``; divide each
        segment (e.g. a Kepler quarter, each with its own flux level) by its
        median flux when ``normalize``; ``e=None`` (no errors in the file):
        estimate one error per segment from the point-to-point scatter."""
        t, f = np.asarray(t, float), np.asarray(f, float)
        has_err = e is not None
        e = np.asarray(e, float) if has_err else np.ones_like(f)
        mask_int, mask_name = bitmask
        if q is None:
            flagged = np.zeros(t.size, bool)
            flags_kept = 0
            mask_name = "none: no quality column"
        else:
            qf = np.asarray(q, float)
            qnan = ~np.isfinite(qf)
            qi = np.where(qnan, 0, qf).astype(np.int64)
            flagged = qnan | ((qi & mask_int) != 0)
            flags_kept = int(((qi != 0) & ~flagged).sum())
        bad = ~(np.isfinite(t) & np.isfinite(f) & np.isfinite(e)) | (e <= 0)
        keep = ~flagged & ~bad
        # repeated time stamps (the same cadence twice, e.g. overlapping
        # downloads): keep the first in file order, count the rest
        idx = np.nonzero(keep)[0]
        _, first = np.unique(t[idx], return_index=True)
        dup_idx = np.setdiff1d(idx, idx[first])
        keep[dup_idx] = False
        report = {"source": str(source), "points": int(t.size), "flagged": int(flagged.sum()),
                  "quality_bitmask": int(mask_int), "quality_bitmask_name": mask_name, "flags_kept": flags_kept,
                  "non_finite": int((bad & ~flagged).sum()), "duplicated": int(dup_idx.size), "kept": int(keep.sum())}
        if time_note:
            report["time"] = time_note
        report.update(extra or {})
        if not keep.any():
            raise ValueError(f"{source}: no usable points ({report['flagged']} flagged, {report['non_finite']} non-finite of {t.size})")
        seg = np.zeros(t.size) if segment is None else np.asarray(segment, float)
        t, f, e, seg = t[keep], f[keep], e[keep], seg[keep]
        flux, err = f.copy(), e.copy()
        divided = {}
        estimated = {}
        for s in np.unique(seg):
            m = seg == s
            med = np.median(f[m]) if normalize else 1.0
            if not np.isfinite(med) or med == 0:
                raise ValueError(f"{source}: cannot normalise flux with median {med}")
            flux[m] = f[m] / med
            err[m] = e[m] / abs(med)
            divided[f"{s:g}"] = float(med)
            if not has_err:
                sig = _diff_sigma(flux[m][np.argsort(t[m])])
                if not (np.isfinite(sig) and sig > 0):
                    raise ValueError(f"{source}: the file has no flux_err column and the scatter of "
                                     f"segment {s:g} ({int(m.sum())} points) gives no error estimate")
                err[m] = sig
                estimated[f"{s:g}"] = float(sig)
        report["divided_by"] = divided["0"] if segment is None else divided
        if not has_err:
            report["flux_err"] = ("estimated: no error column; 1.4826 MAD of successive differences / sqrt(2), "
                                  "per segment")
            report["flux_err_estimate"] = estimated["0"] if segment is None else estimated
        return cls(t, flux, err, exposure=exposure, report=report, errors_estimated=not has_err)

    @classmethod
    def from_arrays(cls, time, flux, flux_err=None, quality=None, *, exposure: float | None = None,
                    normalize: bool | None = None, quality_bitmask="default", mission: str | None = None,
                    time_zero: float | None = None, source: str = "arrays") -> "LightCurve":
        """A light curve from arrays as they come, cleaned and reported.

        ``time``: days, a time Quantity, or an astropy ``Time`` (BJD_TDB -
        ``time_zero`` [d]; "bkjd" / "btjd" formats need no ``time_zero``).
        ``flux``, ``flux_err``: numbers or Quantities (a physical unit such as
        e-/s means raw flux: divided by its median). ``quality``: flag
        integers, dropped where ``quality & bitmask != 0`` (``quality_bitmask``
        and ``mission``: see :func:`quality_bitmask`). Points that are
        flagged, non-finite, with error <= 0 or at a repeated time stamp are
        dropped and counted in ``report``. ``normalize``: divide by the median
        flux; default: for fluxes with a physical unit or a median > 10.
        ``flux_err=None``: errors estimated from the scatter."""
        t, note = _days(time, time_zero)
        f, e, normalize = _flux_values(flux, flux_err, normalize)
        q = None if quality is None else _plain(quality, "quality")[0]
        if normalize is None:
            finite = f[np.isfinite(f)]
            normalize = bool(finite.size > 0 and np.median(finite) > 10)
        return cls._from_columns(t, f, e, q, exposure, source, normalize, None,
                                 _resolve_bitmask(quality_bitmask, mission), note)

    @classmethod
    def from_lightkurve(cls, lc, flux_column: str = "flux", quality_bitmask="default", exposure: float | None = None,
                        normalize: bool | None = None, time_zero: float | None = None) -> "LightCurve":
        """A lightkurve ``LightCurve`` (e.g. ``lk.read(path)`` or
        ``search_lightcurve(...).download()``), without importing lightkurve.

        Time: its ``time`` (BKJD for Kepler, BTJD for TESS; see
        :func:`_days`); flux: ``flux_column`` and ``<flux_column>_err``
        (Quantities in e-/s are divided by their median; a normalised,
        dimensionless flux is taken as is); quality: the ``quality`` column
        with ``quality_bitmask`` of the mission in ``lc.meta`` (lightkurve
        itself drops its "default" bitmask when reading, and drops NaN times
        silently; ``report["lightkurve_quality_bitmask"]`` records what it
        used). ``exposure`` [d]: default TIMEDEL from ``lc.meta``."""
        if not (hasattr(lc, "time") and hasattr(lc, "flux") and hasattr(lc, "meta")):
            raise ValueError(f"lc must be a lightkurve LightCurve (with time, flux, meta), got {type(lc).__name__}")
        meta = {str(k).upper(): v for k, v in dict(lc.meta).items()}
        names = [c.lower() for c in getattr(lc, "colnames", [])]

        def column(name):
            if name.lower() in names:
                return lc[getattr(lc, "colnames")[names.index(name.lower())]]
            return getattr(lc, name, None)

        f = column(flux_column)
        if f is None:
            raise ValueError(f"flux_column {flux_column!r} is not a column of the light curve; columns are {names}")
        e = column(flux_column + "_err")
        q = column("quality")
        if q is None and "sap_quality" in names:
            q = column("sap_quality")
        mission = meta.get("MISSION") or meta.get("TELESCOP")
        try:
            mission = _mission(mission)
        except ValueError:
            mission = None
        if exposure is None:
            exposure = _kepler_exposure(meta)
        label = meta.get("LABEL") or meta.get("OBJECT") or meta.get("TARGETID") or ""
        extra = {"lightkurve_quality_bitmask": meta["QUALITY_BITMASK"]} if "QUALITY_BITMASK" in meta else {}
        extra = {k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in extra.items()}
        t, note = _days(lc.time, time_zero)
        fv, ev, normalize = _flux_values(f, e, normalize)
        if normalize is None:
            finite = fv[np.isfinite(fv)]
            normalize = bool(finite.size > 0 and np.median(finite) > 10)
        qv = None if q is None else _plain(q, "quality")[0]
        return cls._from_columns(t, fv, ev, qv, exposure, f"lightkurve {type(lc).__name__} {label}".strip(), normalize,
                                 None, _resolve_bitmask(quality_bitmask, mission), note, extra)

    @classmethod
    def from_csv(cls, path, exposure: float | None = None, normalize: bool | None = None,
                 columns: dict | None = None, quality_bitmask="default", mission: str | None = None) -> "LightCurve":
        """CSV (or gzip-compressed .csv.gz) with a header row.

        ``columns`` maps the roles time, flux, flux_err, quality, quarter to
        the file's column names (case-insensitive), e.g. ``{"flux_err":
        "error"}``; roles not given are looked up under the usual names
        (time, time_bkjd; flux, pdcsap_flux; flux_err, pdcsap_flux_err;
        quality, sap_quality; quarter). Flagged rows are dropped by
        ``quality_bitmask`` of ``mission`` ("kepler" or "tess"; without a
        mission every non-zero flag drops the row, see
        :func:`quality_bitmask`); an empty quality cell counts as flagged. A
        file without an error column gets errors estimated from its scatter
        (``errors_estimated``, and ``report["flux_err"]`` says so). A quarter
        column divides each quarter by its own median flux. ``normalize``:
        divide by the median; default: for raw Kepler columns (pdcsap_flux,
        sap_flux) or fluxes far from 1 (median > 10)."""
        path = Path(path)
        if not path.exists():
            raise ValueError(f"light-curve file not found: {path}")
        if path.is_dir():
            raise ValueError(f"light-curve path is a folder, not a file: {path}")
        bitmask = _resolve_bitmask(quality_bitmask, mission)
        columns = dict(columns or {})
        unknown = sorted(set(columns) - set(COLUMN_ROLES))
        if unknown:
            raise ValueError(f"columns: unknown role {unknown[0]!r}; roles are {list(COLUMN_ROLES)}")
        from astropy.io.ascii import InconsistentTableError
        from astropy.table import Table

        try:
            opener = gzip.open if path.name.lower().endswith(".gz") else open
            with opener(path, "rt", newline="") as fh:
                text = fh.read()
        except (OSError, UnicodeDecodeError, EOFError) as err:
            raise ValueError(f"cannot read {path}: {err}") from err
        if not text.strip():
            raise ValueError(f"{path}: needs a header and at least one row")
        try:
            # astropy's CSV reader ('#' comment lines; empty cells masked,
            # read as NaN below so that they are counted as dropped); given
            # the text, because its fast reader does not decompress gzip
            tab = Table.read(text, format="ascii.csv", comment="#", guess=False)
        except (InconsistentTableError, ValueError) as err:
            raise ValueError(f"cannot read {path}: {' '.join(str(err).split())[:300]}") from err
        if len(tab) < 1:
            raise ValueError(f"{path}: needs a header and at least one row")
        names = list(tab.colnames)
        header = [h.strip().lower() for h in names]

        def col(role, required=True):
            if role in columns:
                name = str(columns[role]).strip().lower()
                if name not in header:
                    raise ValueError(f"{path}: columns.{role} = {columns[role]!r} is not a column; header is {header}")
                return header.index(name)
            for n in COLUMN_ROLES[role]:
                if n in header:
                    return header.index(n)
            if required:
                raise ValueError(f"{path}: no {role} column (looked for {list(COLUMN_ROLES[role])}; set columns.{role}); "
                                 f"header is {header}")
            return None

        idx = {r: col(r, r in ("time", "flux")) for r in COLUMN_ROLES}

        def read(role):
            c = tab[names[idx[role]]]
            try:
                return np.ma.filled(np.ma.asarray(c, dtype=float), np.nan)
            except (ValueError, TypeError):
                vals = np.asarray(np.ma.filled(np.ma.asarray(c).astype(str), ""))
                bad = next(v for v in vals if v.strip() and not _is_number(v))
                row = int(np.nonzero(vals == bad)[0][0]) + 1
                raise ValueError(f"{path}: unreadable row {row} in column {header[idx[role]]!r}: {str(bad)!r} is not a number") from None

        t, f = read("time"), read("flux")
        e = None if idx["flux_err"] is None else read("flux_err")
        q = None if idx["quality"] is None else read("quality")
        seg = None if idx["quarter"] is None else read("quarter")
        if normalize is None:
            finite = f[np.isfinite(f)]
            normalize = header[idx["flux"]] in ("pdcsap_flux", "sap_flux") or (finite.size > 0 and np.median(finite) > 10)
        return cls._from_columns(t, f, e, q, exposure, path, normalize, seg, bitmask)

    @classmethod
    def concatenate(cls, parts, exposure: float | None = None) -> "LightCurve":
        """Join light curves (e.g. one file per quarter, each already divided
        by its own median). Their exposures must agree unless ``exposure``
        [d] is given; duplicated time stamps are an error."""
        parts = list(parts)
        if not parts:
            raise ValueError("concatenate needs at least one light curve")
        if exposure is None:
            exps = {p.exposure for p in parts}
            if len(exps) > 1:
                raise ValueError(f"the files have different exposures {sorted(exps, key=str)}; set exposure")
            exposure = parts[0].exposure
        t = np.concatenate([p.time for p in parts])
        if np.unique(t).size != t.size:
            raise ValueError(f"the files share {t.size - np.unique(t).size} time stamps (the same data twice?)")
        report = {"sources": [p.report for p in parts], "kept": int(t.size)}
        return cls(t, np.concatenate([p.flux for p in parts]), np.concatenate([p.flux_err for p in parts]),
                   exposure, report, errors_estimated=any(p.errors_estimated for p in parts))

    @classmethod
    def from_fits(cls, path, flux_column: str = "PDCSAP_FLUX", quality_bitmask="default",
                  mission: str | None = None) -> "LightCurve":
        """A Kepler, K2 or TESS SPOC light-curve FITS file.

        The mission comes from the primary header (TELESCOP, else MISSION)
        unless ``mission`` is given; it sets the quality column (Kepler:
        SAP_QUALITY, TESS: QUALITY), the meaning of the named bitmasks
        (:data:`QUALITY_BITMASKS`, default "default": only cadences the
        missions call unusable are dropped) and the time system: TIME [d] is
        BJD_TDB - (BJDREFI + BJDREFF), 2454833 (BKJD) for Kepler, 2457000
        (BTJD) for TESS, kept as it is (``report["time"]`` states it).
        Flagged, non-finite and repeated points are dropped and counted in
        ``report``; the flux is divided by its median; exposure from the
        header (TIMEDEL; Kepler long cadence 29.4 min, TESS 2 min; see
        :func:`_kepler_exposure`)."""
        from astropy.io import fits
        from astropy.table import Table
        from astropy.units import UnitsWarning

        _resolve_bitmask(quality_bitmask, None)  # a bad name fails before the file is read
        path = Path(path)
        if not path.exists():
            raise ValueError(f"light-curve file not found: {path}")
        if path.is_dir():
            raise ValueError(f"light-curve path is a folder, not a file: {path}")
        try:
            with fits.open(path) as hdul:
                primary = hdul[0].header.copy()
                ext = "LIGHTCURVE" if "LIGHTCURVE" in hdul else (1 if len(hdul) > 1 else None)
                if ext is None or not isinstance(hdul[ext], fits.BinTableHDU):
                    raise ValueError(f"{path}: no LIGHTCURVE table extension")
                with warnings.catch_warnings():
                    # 'e-/s' and 'BJD - 2454833' are not FITS units: astropy
                    # warns; the columns are used as numbers
                    warnings.simplefilter("ignore", UnitsWarning)
                    tab = Table.read(hdul[ext])
        except OSError as err:
            raise ValueError(f"cannot read {path} as FITS: {err}") from err
        hdr = tab.meta
        if mission is None:
            name = primary.get("TELESCOP") or primary.get("MISSION") or hdr.get("TELESCOP") or hdr.get("MISSION")
            if name is None:
                raise ValueError(f"{path}: no TELESCOP or MISSION keyword; pass mission='kepler' or 'tess'")
            try:
                mission = _mission(name)
            except ValueError:
                raise ValueError(f"{path}: TELESCOP = {name!r}; light-curve FITS files of Kepler, K2 and TESS "
                                 "are read (pass mission= for another file of the same layout)") from None
        else:
            mission = _mission(mission)
        names = {c.upper(): c for c in tab.colnames}
        qcol = next((c for c in (("SAP_QUALITY", "QUALITY") if mission == "kepler" else ("QUALITY", "SAP_QUALITY"))
                     if c in names), None)
        need = ["TIME", flux_column.upper(), flux_column.upper() + "_ERR"] + ([] if qcol else ["SAP_QUALITY or QUALITY"])
        missing = [c for c in need if c not in names]
        if missing:
            raise ValueError(f"{path}: missing columns {missing} (have {list(names)})")

        def col(c):
            v = tab[names[c]]
            return np.ma.filled(np.ma.asarray(v, dtype=float), np.nan)

        zero_default, label = _TIME_ZERO[mission]
        if "BJDREFI" in hdr:
            zero = float(hdr["BJDREFI"]) + float(hdr.get("BJDREFF", 0.0))
        else:
            zero = zero_default
        note = f"BJD_TDB - {zero:.1f} [d]" + (f" ({label})" if abs(zero - zero_default) < 1e-9 else "")
        return cls._from_columns(col("TIME"), col(flux_column.upper()), col(flux_column.upper() + "_ERR"),
                                 col(qcol), _kepler_exposure(hdr), path, True, None,
                                 _resolve_bitmask(quality_bitmask, mission), note, {"mission": mission})

    @classmethod
    def from_kepler_fits(cls, path, flux_column: str = "PDCSAP_FLUX", quality_bitmask="default") -> "LightCurve":
        """:meth:`from_fits` for a Kepler file (also without a TELESCOP key)."""
        return cls.from_fits(path, flux_column, quality_bitmask, mission="kepler")

    def to_csv(self, path) -> None:
        path = Path(path)
        tmp = path.with_suffix(path.suffix + ".tmp")
        with open(tmp, "w") as fh:
            fh.write("time,flux,flux_err\n")
            for row in zip(self.time, self.flux, self.flux_err):
                fh.write(f"{row[0]:.8f},{row[1]:.10f},{row[2]:.6e}\n")
        tmp.replace(path)

    # ---- selections -------------------------------------------------------------
    def select(self, mask) -> "LightCurve":
        mask = np.asarray(mask, bool)
        if not mask.any():
            raise ValueError("the selection keeps no points")
        return LightCurve(self.time[mask], self.flux[mask], self.flux_err[mask], self.exposure, dict(self.report),
                          self.errors_estimated)

    def windows(self, intervals) -> "LightCurve":
        """Points inside any of the (start, end) intervals."""
        keep = np.zeros(self.time.size, bool)
        for a, b in intervals:
            keep |= (self.time >= a) & (self.time <= b)
        return self.select(keep)

    def normalized(self, intervals, in_transit) -> "LightCurve":
        """Divide each window by a second-order polynomial fitted to its
        out-of-transit points (Mueller et al. 2021, Sect. 2.2).

        ``intervals``: (start, end) windows; ``in_transit``: boolean mask of
        points to exclude from the fit (same length as the light curve)."""
        in_transit = np.asarray(in_transit, bool)
        flux, err = self.flux.copy(), self.flux_err.copy()
        for a, b in intervals:
            win = (self.time >= a) & (self.time <= b)
            out = win & ~in_transit
            if out.sum() < 4:
                raise ValueError(f"window {a:.4f}..{b:.4f} has {out.sum()} out-of-transit points; need >= 4 for the polynomial")
            tm = 0.5 * (a + b)
            coef = np.polyfit(self.time[out] - tm, self.flux[out], 2, w=1 / self.flux_err[out])
            trend = np.polyval(coef, self.time[win] - tm)
            flux[win] = self.flux[win] / trend
            err[win] = self.flux_err[win] / trend
        return LightCurve(self.time, flux, err, self.exposure, dict(self.report), self.errors_estimated)

    def supersampled_times(self, n: int | None = None) -> tuple[np.ndarray, int]:
        """Times at which to evaluate a model so that averaging groups of
        ``n`` reproduces the exposure (midpoint rule; default n odd with
        sub-exposures <= SUB_EXPOSURE = 30 s, 59 for a 29.4-min Kepler long
        cadence). Why 30 s: a Kepler-20 b ingress and a planet-planet
        occultation last only 3-9 min; with 2-min sub-exposures (n = 15) the
        scan's Delta chi^2 was off by up to 0.08 (tests/test_scan.py checks
        the default against a 401-point average)."""
        if self.exposure is None:
            return self.time, 1
        if n is None:
            n = max(1, int(np.ceil(self.exposure / SUB_EXPOSURE)))
            n += 1 - n % 2
        off = (np.arange(n) + 0.5) / n - 0.5
        return (self.time[:, None] + off[None, :] * self.exposure).ravel(), n
