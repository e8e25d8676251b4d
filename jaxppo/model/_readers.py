"""Light-curve readers: the columns of CSV, Kepler / K2 / TESS FITS files and
lightkurve objects, the missions' quality flags and named bitmasks, the
column roles of a CSV file and the missions' time zero points. What
``jaxppo.model._lightcurve.LightCurve`` is built from; it cleans,
normalises and reports."""

from __future__ import annotations

import gzip
import warnings
from pathlib import Path

import numpy as np

__all__ = ["COLUMN_ROLES", "QUALITY_FLAGS", "QUALITY_BITMASKS", "TIME_ZERO", "quality_bitmask", "resolve_bitmask",
           "mission_name", "plain_values", "to_days", "is_lightkurve", "flux_values", "diff_sigma",
           "kepler_exposure", "read_csv_columns", "read_fits_columns", "lightkurve_columns", "lightkurve_exposure",
           "lightkurve_mixed_missions", "zero_text"]

# Column roles and the names looked up when the user does not name them.
COLUMN_ROLES = {
    "time": ("time", "time_bkjd", "bkjd", "t"),
    "flux": ("flux", "pdcsap_flux", "f"),
    "flux_err": ("flux_err", "pdcsap_flux_err", "err", "error", "flux_error", "sigma"),
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
TIME_ZERO = {"kepler": (2454833.0, "BKJD"), "tess": (2457000.0, "BTJD")}
_ZERO_NAMES = {zero: name for zero, name in TIME_ZERO.values()}


def zero_text(zero: float) -> str:
    """"BJD_TDB - <zero> [d]", with the name of a mission's zero point
    (BKJD, BTJD) where ``zero`` [JD] is one."""
    name = _ZERO_NAMES.get(zero)
    return f"BJD_TDB - {zero:.1f} [d]" + (f" ({name})" if name else "")


def mission_name(name) -> str | None:
    """The reader's mission key of a mission name: "kepler" for Kepler and
    K2, "tess" for TESS (any case), None for None; a ValueError otherwise."""
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
    "default", "hard", "hardest", see ``QUALITY_BITMASKS``) or an
    integer; a point is dropped when ``quality & bitmask != 0``. Without a
    mission (a CSV file) the flag bits have no known meaning: the names other
    than "none" then drop every flagged point (bitmask -1, all bits)."""
    m = mission_name(mission)
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


# the loaders' argument of the same name shadows the function
resolve_bitmask = quality_bitmask


def plain_values(x, what: str, unit=None):
    """A float array from a list, array, astropy Quantity or masked array
    (masked entries become NaN, so that they are counted as dropped). A
    Quantity is converted to ``unit``; with ``unit=None`` its unit is
    returned for the caller to judge."""
    import astropy.units as u

    if any(c.__name__ in ("Time", "TimeDelta") for c in type(x).__mro__):
        raise ValueError(f"{what} must be numbers{'' if unit is None else f' in {unit}'}, got an astropy "
                         f"{type(x).__name__} ({x!r})")
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
            except u.UnitConversionError:
                raise ValueError(f"{what} has unit {x.unit}, which does not convert to {unit}") from None
        else:
            xunit, x = x.unit, x.value
    v = np.array(x, dtype=float)
    if mask is not None and mask.shape == v.shape:
        v[mask] = np.nan
    return (v, xunit) if unit is None else v


def to_days(t, time_zero=None) -> tuple[np.ndarray, str | None, float | None]:
    """Times [d], a statement of their zero point, and the zero point [JD]
    (None where the times are plain numbers of unknown zero).

    An astropy ``Time`` becomes BJD_TDB - ``time_zero`` [d], computed from the
    two-double (jd1, jd2) representation so that no precision is lost. Its
    zero point defaults to the one of its format: 2454833 for "bkjd"
    (Kepler, lightkurve), 2457000 for "btjd" (TESS); any other format needs
    ``time_zero`` (the planets' t0 must be on the same scale, and guessing it
    would shift every transit by years). NOTE: the scale is converted to TDB;
    a barycentric correction is not applied (give barycentric times). A time
    Quantity is converted to days; plain numbers are taken as days."""
    if _isplain_values(t):
        return np.asarray(t, float), None, None
    from astropy.time import Time
    import astropy.units as u

    if isinstance(t, Time):
        fmt = t.format
        if time_zero is None:
            zeros = {"bkjd": TIME_ZERO["kepler"], "btjd": TIME_ZERO["tess"]}
            if fmt not in zeros:
                raise ValueError(
                    f"time is an astropy Time in format {fmt!r}: set time_zero [JD] (e.g. 2454833.0 for BKJD, "
                    "2457000.0 for BTJD), the zero point of the planets' t0")
            zero = zeros[fmt][0]
        else:
            zero = float(time_zero)
        tdb = t.tdb
        days = (np.asarray(tdb.jd1, float) - zero) + np.asarray(tdb.jd2, float)
        note = zero_text(zero) + f", from astropy Time ({fmt}, {t.scale})"
        return np.atleast_1d(days), note, zero
    if type(t).__name__ == "TimeDelta" or any(c.__name__ == "TimeDelta" for c in type(t).__mro__):
        return np.atleast_1d(np.asarray(t.to_value(u.day), float)), None, None
    if isinstance(t, u.Quantity) or (hasattr(t, "unmasked") and isinstance(getattr(t, "unmasked"), u.Quantity)):
        return plain_values(t, "time", u.day), None, None
    return plain_values(t, "time", None)[0], None, None


def _isplain_values(x) -> bool:
    """A list or a bare numpy array (not a Quantity, Time or masked array):
    no astropy import needed."""
    return type(x) is np.ndarray or isinstance(x, (list, tuple, float, int))


def is_lightkurve(x) -> bool:
    """True for a lightkurve ``LightCurve`` (duck-typed: it has ``flux``,
    ``time`` and ``meta``; jaxppo does not import lightkurve)."""
    return hasattr(x, "flux") and hasattr(x, "time") and hasattr(x, "meta")


def flux_values(f, e, normalize):
    """(flux, flux_err, normalize) as floats; a flux Quantity with a physical
    unit (e.g. e-/s) must be normalised, a dimensionless one is taken as is."""
    if _isplain_values(f) and (e is None or _isplain_values(e)):
        return np.asarray(f, float), None if e is None else np.asarray(e, float), normalize
    import astropy.units as u

    fv, funit = plain_values(f, "flux")
    ev = None
    if e is not None and funit is not None:
        ev = plain_values(e, "flux_err", funit)  # plain errors: in the flux's unit
    elif e is not None:
        # errors with a unit beside a plain (relative) flux: dimensionless
        # units convert (0.1 % is 1e-3, not 0.1); a physical unit cannot
        ev, eunit = plain_values(e, "flux_err")
        if eunit is not None:
            if eunit.physical_type != "dimensionless":
                raise ValueError(f"flux_err has unit {eunit} but flux has none: give relative errors (a plain number "
                                 "or a dimensionless Quantity), or flux and flux_err in the same unit")
            ev = ev * eunit.to(u.dimensionless_unscaled)
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


def diff_sigma(f: np.ndarray) -> float:
    """Robust white-noise sigma from successive differences: 1.4826 x the
    median absolute deviation of diff(f), / sqrt(2). Slow trends and a few
    jumps (transits, gaps) barely move it."""
    if f.size < 3:
        return float("nan")
    d = np.diff(f)
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def kepler_exposure(hdr) -> float | None:
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


# characters other than \n and \r at which str.splitlines breaks a line
_OTHER_BREAKS = ("\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029")


def _plain_csv(text: str):
    """(the header's names, the values [rows, columns]) of a CSV text that
    holds only numbers: '#' comment lines, then a header row of distinct
    names without quotes, then rows of numbers, no empty cells. None for
    anything else, which astropy's reader then reads (with its messages).
    numpy's parser takes 20 ms for the bundled 65,000 Kepler-20 rows,
    astropy's 54 ms plus 0.3 s to import its tables (where nothing else has:
    ``jaxppo scan`` imports them anyway to write scan.ecsv)."""
    if any(c in text for c in _OTHER_BREAKS):  # str.splitlines breaks there; astropy's reader does not
        return None
    lines = text.splitlines(keepends=True)
    k = next((i for i, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")), None)
    if k is None or '"' in text or "#" in "".join(lines[k:]):
        return None
    names = [h.strip() for h in lines[k].split(",")]
    rows = lines[k + 1:]
    if not all(names) or len({n.lower() for n in names}) != len(names) or not any(r.strip() for r in rows):
        return None
    try:
        values = np.loadtxt(rows, delimiter=",", dtype=float, ndmin=2)
    except ValueError:
        return None
    if values.shape[0] < 1 or values.shape[1] != len(names):
        return None
    return names, values


def read_csv_columns(path: Path, columns: dict):
    """The columns of a light-curve CSV file (or gzip-compressed .csv.gz)
    with a header row: (time, flux, flux_err, quality, quarter, the flux
    column's name) as float arrays, NaN where a cell is empty; flux_err,
    quality and quarter are None when the file has no such column.
    ``columns`` maps roles (``COLUMN_ROLES``) to the file's names."""
    try:
        opener = gzip.open if path.name.lower().endswith(".gz") else open
        # utf-8-sig: a byte-order mark (spreadsheet exports) is not part of the first name
        with opener(path, "rt", newline="", encoding="utf-8-sig") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError, EOFError) as err:
        raise ValueError(f"cannot read {path}: {err}") from err
    if not text.strip():
        raise ValueError(f"{path}: needs a header and at least one row")
    plain = _plain_csv(text)
    if plain is not None:
        names, values = plain
        cells = {name: values[:, j] for j, name in enumerate(names)}
    else:
        names, cells = _astropy_csv(path, text)
    header = [h.strip().lower() for h in names]
    if twice := sorted({h for h in header if h and header.count(h) > 1}):
        raise ValueError(f"{path}: the header names column(s) {twice} more than once (names are case-insensitive); "
                         f"header is {header}")

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
    _warn_foreign_errors(path, header, idx, columns)
    if idx["flux_err"] is None:
        used = {i for i in idx.values() if i is not None}
        if like := [h for i, h in enumerate(header) if i not in used and any(k in h for k in ("err", "sigma", "uncert"))]:
            import warnings

            warnings.warn(f"{path}: no error column under the usual names {list(COLUMN_ROLES['flux_err'])}, so the "
                          f"errors are estimated from the scatter; column {like[0]!r} is not used: if it holds the "
                          f"flux errors, set columns.flux_err = {like[0]!r}", UserWarning, stacklevel=2)

    def read(role):
        c = cells[names[idx[role]]]
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
    return t, f, e, q, seg, header[idx["flux"]]


def _warn_foreign_errors(path: Path, header: list, idx: dict, columns: dict) -> None:
    """Warn where the error column found under the usual names belongs to
    another flux column of the file (time, flux, pdcsap_flux,
    pdcsap_flux_err: a relative flux beside raw errors in e-/s, or the
    reverse, and chi^2 off by the ratio of their scales)."""
    if "flux_err" in columns or idx["flux_err"] is None:
        return
    err, flux = header[idx["flux_err"]], header[idx["flux"]]
    owner = next((err[:-len(x)] for x in ("_err", "_error") if err.endswith(x)), None)
    if owner and owner != flux and owner in header:
        import warnings

        warnings.warn(f"{path}: the errors are read from column {err!r}, which belongs to column {owner!r}, not to "
                      f"the flux column {flux!r}: set columns.flux_err (or columns.flux = {owner!r}) if that is not "
                      "meant", UserWarning, stacklevel=3)


def _astropy_csv(path: Path, text: str):
    """(the header's names, {name: column}) by astropy's CSV reader ('#'
    comment lines; empty cells masked, read as NaN by the caller so that
    they are counted as dropped); given the text, because its fast reader
    does not decompress gzip."""
    from astropy.io.ascii import InconsistentTableError
    from astropy.table import Table

    try:
        tab = Table.read(text, format="ascii.csv", comment="#", guess=False)
    except (InconsistentTableError, ValueError) as err:
        raise ValueError(f"cannot read {path}: {' '.join(str(err).split())[:300]}") from err
    if len(tab) < 1:
        raise ValueError(f"{path}: needs a header and at least one row")
    return list(tab.colnames), {name: tab[name] for name in tab.colnames}


def read_fits_columns(path: Path, flux_column: str, mission: str | None):
    """The columns of a Kepler, K2 or TESS SPOC light-curve FITS file:
    (time [d], flux, flux_err, quality, exposure [d], mission, a statement
    of the time system, its zero point [JD]). The mission comes from the primary header
    (TELESCOP, else MISSION) unless given; it picks the quality column and
    the time zero (``TIME_ZERO``, or BJDREFI + BJDREFF from the header)."""
    from astropy.io import fits
    from astropy.table import Table
    from astropy.units import UnitsWarning

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
            mission = mission_name(name)
        except ValueError:
            raise ValueError(f"{path}: TELESCOP = {name!r}; light-curve FITS files of Kepler, K2 and TESS "
                             "are read (pass mission= for another file of the same layout)") from None
    else:
        mission = mission_name(mission)
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

    zero_default, label = TIME_ZERO[mission]
    if "BJDREFI" in hdr:
        zero = float(hdr["BJDREFI"]) + float(hdr.get("BJDREFF", 0.0))
    else:
        zero = zero_default
    note = f"BJD_TDB - {zero:.1f} [d]" + (f" ({label})" if abs(zero - zero_default) < 1e-9 else "")
    return (col("TIME"), col(flux_column.upper()), col(flux_column.upper() + "_ERR"), col(qcol),
            kepler_exposure(hdr), mission, note, zero)


def lightkurve_columns(lc, flux_column: str):
    """The columns of a lightkurve ``LightCurve`` (without importing
    lightkurve): (flux, flux_err, quality, mission, meta with upper-case
    keys); flux_err and quality None when absent, mission None when unknown."""
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
        mission = mission_name(mission)
    except ValueError:
        mission = None
    return f, e, q, mission, meta


def lightkurve_exposure(lc, meta: dict) -> float | None:
    """The exposure [d] (or None) of a lightkurve ``LightCurve``.

    A binned light curve (``lc.bin(...)``: a ``time_bin_size`` column) keeps
    its unbinned file's TIMEDEL in ``meta``; its points average the flux over
    their bins, so the exposure is the bin size (one size, else a
    ValueError). Otherwise TIMEDEL (``kepler_exposure``)."""
    import astropy.units as u

    names = {str(c).lower(): c for c in getattr(lc, "colnames", [])}
    if "time_bin_size" in names:
        size = lc[names["time_bin_size"]]
        size = size.to_value(u.day) if hasattr(size, "to_value") else np.asarray(size, float)
        size = np.asarray(size, float)[np.isfinite(np.asarray(size, float))]
        if size.size == 0 or np.ptp(size) > 1e-6 * np.max(size):
            rng = f"{size.min():g} to {size.max():g} d" if size.size else "none finite"
            raise ValueError(f"the light curve's bins have different sizes (time_bin_size {rng}): one exposure "
                             "averages every point's model; give exposure= [d]")
        return float(size[0])
    return kepler_exposure(meta)


def lightkurve_mixed_missions(lc, meta: dict) -> str | None:
    """A warning where a lightkurve ``LightCurve``'s time format (bkjd:
    Kepler, btjd: TESS) and ``meta``'s mission disagree, as in a light curve
    stitched from both missions, whose ``meta`` (TIMEDEL, mission) is one
    part's; else None."""
    fmt = getattr(getattr(lc, "time", None), "format", None)
    fmt_mission = {"bkjd": "kepler", "btjd": "tess"}.get(fmt)
    try:
        mission = mission_name(meta.get("MISSION") or meta.get("TELESCOP"))
    except ValueError:
        mission = None
    if fmt_mission and mission and fmt_mission != mission:
        return (f"the light curve's time is in {fmt.upper()} ({fmt_mission}) but its meta names {mission}: one "
                "stitched from Kepler and TESS light curves? Its exposure (TIMEDEL) and quality bits are one part's "
                "for every point; read each mission's light curve on its own (docs/api.md, LightCurve)")
    return None
