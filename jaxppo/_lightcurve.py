"""LightCurve: photometry with errors, from CSV or Kepler FITS files."""

from __future__ import annotations

import csv
import dataclasses
import gzip
from pathlib import Path

import numpy as np

__all__ = ["LightCurve"]

# Column roles and the names looked up when the user does not name them.
_ROLES = {
    "time": ("time", "time_bkjd", "bkjd", "t"),
    "flux": ("flux", "pdcsap_flux", "f"),
    "flux_err": ("flux_err", "pdcsap_flux_err", "err", "sigma"),
    "quality": ("quality", "sap_quality"),
    "quarter": ("quarter",),
}


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
    dropped. ``errors_estimated``: the file had no errors and ``flux_err``
    is an estimate from the scatter (the scan re-estimates it per window)."""

    time: np.ndarray
    flux: np.ndarray
    flux_err: np.ndarray
    exposure: float | None = None
    report: dict = dataclasses.field(default_factory=dict)
    errors_estimated: bool = False

    def __post_init__(self):
        t = np.asarray(self.time, float)
        f = np.asarray(self.flux, float)
        e = np.asarray(self.flux_err, float)
        if t.ndim != 1 or f.shape != t.shape or e.shape != t.shape:
            raise ValueError(f"time, flux and flux_err must be 1D of equal length, got {t.shape}, {f.shape}, {e.shape}")
        if t.size == 0:
            raise ValueError("the light curve has no points")
        for name, v in (("time", t), ("flux", f), ("flux_err", e)):
            if not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be finite (use the loaders to drop bad points)")
        if np.any(e <= 0):
            raise ValueError(f"flux_err must be > 0, found {e[e <= 0][0]}")
        if self.exposure is not None and not (np.isfinite(self.exposure) and self.exposure > 0):
            raise ValueError(f"exposure must be > 0 days, got {self.exposure}")
        order = np.argsort(t, kind="stable")
        object.__setattr__(self, "time", t[order])
        object.__setattr__(self, "flux", f[order])
        object.__setattr__(self, "flux_err", e[order])

    def __len__(self) -> int:
        return self.time.size

    # ---- loading ----------------------------------------------------------------
    @classmethod
    def _from_columns(cls, t, f, e, q, exposure, source, normalize=True, segment=None) -> "LightCurve":
        """Drop flagged (q != 0) and non-finite points, divide each segment
        (e.g. a Kepler quarter, each with its own flux level) by its median
        flux when ``normalize``; ``e=None`` (no errors in the file): estimate
        one error per segment from the point-to-point scatter."""
        t, f = np.asarray(t, float), np.asarray(f, float)
        has_err = e is not None
        e = np.asarray(e, float) if has_err else np.ones_like(f)
        q = np.zeros(t.size, int) if q is None else np.asarray(q).astype(float)
        flagged = q != 0
        bad = ~(np.isfinite(t) & np.isfinite(f) & np.isfinite(e)) | (e <= 0)
        keep = ~flagged & ~bad
        report = {"source": str(source), "points": int(t.size), "flagged": int(flagged.sum()),
                  "non_finite": int((bad & ~flagged).sum()), "kept": int(keep.sum())}
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
    def from_csv(cls, path, exposure: float | None = None, normalize: bool | None = None,
                 columns: dict | None = None) -> "LightCurve":
        """CSV (or gzip-compressed .csv.gz) with a header row.

        ``columns`` maps the roles time, flux, flux_err, quality, quarter to
        the file's column names (case-insensitive), e.g. ``{"flux_err":
        "error"}``; roles not given are looked up under the usual names
        (time, time_bkjd; flux, pdcsap_flux; flux_err, pdcsap_flux_err;
        quality, sap_quality; quarter). Non-zero quality rows are dropped. A
        file without an error column gets errors estimated from its scatter
        (``errors_estimated``, and ``report["flux_err"]`` says so). A quarter
        column divides each quarter by its own median flux. ``normalize``:
        divide by the median; default: for raw Kepler columns (pdcsap_flux,
        sap_flux) or fluxes far from 1 (median > 10)."""
        path = Path(path)
        if not path.exists():
            raise ValueError(f"light-curve file not found: {path}")
        columns = dict(columns or {})
        unknown = sorted(set(columns) - set(_ROLES))
        if unknown:
            raise ValueError(f"columns: unknown role {unknown[0]!r}; roles are {list(_ROLES)}")
        try:
            opener = gzip.open if path.name.lower().endswith(".gz") else open
            with opener(path, "rt", newline="") as fh:
                rows = list(csv.reader(row for row in fh if not row.lstrip().startswith("#")))
        except (OSError, UnicodeDecodeError, EOFError) as err:
            raise ValueError(f"cannot read {path}: {err}") from err
        if len(rows) < 2:
            raise ValueError(f"{path}: needs a header and at least one row")
        header = [h.strip().lower() for h in rows[0]]

        def col(role, required=True):
            if role in columns:
                name = str(columns[role]).strip().lower()
                if name not in header:
                    raise ValueError(f"{path}: columns.{role} = {columns[role]!r} is not a column; header is {header}")
                return header.index(name)
            for n in _ROLES[role]:
                if n in header:
                    return header.index(n)
            if required:
                raise ValueError(f"{path}: no {role} column (looked for {list(_ROLES[role])}; set columns.{role}); "
                                 f"header is {header}")
            return None

        idx = {r: col(r, r in ("time", "flux")) for r in _ROLES}
        body = [r for r in rows[1:] if r]

        def read(role, empty=np.nan):
            i = idx[role]
            try:
                return np.array([float(r[i]) if r[i].strip() else empty for r in body])
            except (ValueError, IndexError) as err:
                raise ValueError(f"{path}: unreadable row in column {header[i]!r} ({err})") from err

        t, f = read("time"), read("flux")
        e = None if idx["flux_err"] is None else read("flux_err")
        q = None if idx["quality"] is None else read("quality", empty=1)
        seg = None if idx["quarter"] is None else read("quarter")
        if normalize is None:
            finite = f[np.isfinite(f)]
            normalize = header[idx["flux"]] in ("pdcsap_flux", "sap_flux") or (finite.size > 0 and np.median(finite) > 10)
        return cls._from_columns(t, f, e, q, exposure, path, normalize, seg)

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
    def from_kepler_fits(cls, path, flux_column: str = "PDCSAP_FLUX") -> "LightCurve":
        """Kepler light-curve FITS (LIGHTCURVE extension: TIME, PDCSAP_FLUX,
        PDCSAP_FLUX_ERR, SAP_QUALITY). Flagged and non-finite points are
        dropped and counted in ``report``; exposure from the header (long
        cadence: 29.4 min, see :func:`_kepler_exposure`)."""
        from astropy.io import fits

        path = Path(path)
        if not path.exists():
            raise ValueError(f"light-curve file not found: {path}")
        try:
            hdul = fits.open(path)
        except OSError as err:
            raise ValueError(f"cannot read {path} as FITS: {err}") from err
        with hdul:
            hdu = hdul["LIGHTCURVE"] if "LIGHTCURVE" in hdul else (hdul[1] if len(hdul) > 1 else None)
            if hdu is None or not hasattr(hdu, "columns"):
                raise ValueError(f"{path}: no LIGHTCURVE table extension")
            names = [c.upper() for c in hdu.columns.names]
            need = ("TIME", flux_column, flux_column + "_ERR", "SAP_QUALITY")
            missing = [c for c in need if c not in names]
            if missing:
                raise ValueError(f"{path}: missing columns {missing} (have {names})")
            d = hdu.data
            hdr = hdu.header
            exposure = _kepler_exposure(hdr)
            return cls._from_columns(d["TIME"], d[flux_column], d[flux_column + "_ERR"], d["SAP_QUALITY"], exposure, path)

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
        ``n`` reproduces the exposure (n odd, sub-exposure <= 2 min)."""
        if self.exposure is None:
            return self.time, 1
        if n is None:
            n = max(1, int(np.ceil(self.exposure / (2.0 / 1440.0))))
            n += 1 - n % 2
        off = (np.arange(n) + 0.5) / n - 0.5
        return (self.time[:, None] + off[None, :] * self.exposure).ravel(), n
