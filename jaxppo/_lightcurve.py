"""LightCurve: photometry with errors, from CSV or Kepler FITS files."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np

__all__ = ["LightCurve"]

_TIME = ("time", "time_bkjd", "bkjd", "t")
_FLUX = ("flux", "pdcsap_flux", "f")
_ERR = ("flux_err", "pdcsap_flux_err", "err", "sigma")
_QUALITY = ("quality", "sap_quality")


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
    dropped."""

    time: np.ndarray
    flux: np.ndarray
    flux_err: np.ndarray
    exposure: float | None = None
    report: dict = dataclasses.field(default_factory=dict)

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
    def _from_columns(cls, t, f, e, q, exposure, source, normalize=True) -> "LightCurve":
        t, f, e = (np.asarray(v, float) for v in (t, f, e))
        q = np.zeros(t.size, int) if q is None else np.asarray(q).astype(float)
        flagged = q != 0
        bad = ~(np.isfinite(t) & np.isfinite(f) & np.isfinite(e)) | (e <= 0)
        keep = ~flagged & ~bad
        report = {"source": str(source), "points": int(t.size), "flagged": int(flagged.sum()),
                  "non_finite": int((bad & ~flagged).sum()), "kept": int(keep.sum())}
        if not keep.any():
            raise ValueError(f"{source}: no usable points ({report['flagged']} flagged, {report['non_finite']} non-finite of {t.size})")
        med = np.median(f[keep]) if normalize else 1.0
        if not np.isfinite(med) or med == 0:
            raise ValueError(f"{source}: cannot normalise flux with median {med}")
        report["divided_by"] = float(med)
        return cls(t[keep], f[keep] / med, e[keep] / abs(med), exposure=exposure, report=report)

    @classmethod
    def from_csv(cls, path, exposure: float | None = None, normalize: bool | None = None) -> "LightCurve":
        """CSV with a header naming time, flux and flux_err columns (also
        time_bkjd, pdcsap_flux, pdcsap_flux_err; optional quality or
        sap_quality: non-zero rows are dropped). ``normalize``: divide flux
        and error by the median flux; default: only for raw Kepler columns
        (pdcsap_flux) or fluxes far from 1 (median > 10)."""
        path = Path(path)
        if not path.exists():
            raise ValueError(f"light-curve file not found: {path}")
        try:
            with open(path, newline="") as fh:
                rows = list(csv.reader(row for row in fh if not row.lstrip().startswith("#")))
        except (OSError, UnicodeDecodeError) as err:
            raise ValueError(f"cannot read {path}: {err}") from err
        if len(rows) < 2:
            raise ValueError(f"{path}: needs a header and at least one row")
        header = [h.strip().lower() for h in rows[0]]

        def col(names, required=True):
            for n in names:
                if n in header:
                    return header.index(n)
            if required:
                raise ValueError(f"{path}: no column named any of {names}; header is {header}")
            return None

        it, i_f, ie, iq = col(_TIME), col(_FLUX), col(_ERR), col(_QUALITY, required=False)
        try:
            data = np.array([[float(r[i]) if r[i].strip() else np.nan for i in (it, i_f, ie)] for r in rows[1:] if r])
        except (ValueError, IndexError) as err:
            raise ValueError(f"{path}: unreadable row ({err})") from err
        q = None if iq is None else np.array([float(r[iq]) if r[iq].strip() else 1 for r in rows[1:] if r])
        if normalize is None:
            finite = data[np.isfinite(data[:, 1]), 1]
            normalize = header[i_f] != "flux" or (finite.size > 0 and np.median(finite) > 10)
        return cls._from_columns(data[:, 0], data[:, 1], data[:, 2], q, exposure, path, normalize)

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
        return LightCurve(self.time[mask], self.flux[mask], self.flux_err[mask], self.exposure, dict(self.report))

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
        return LightCurve(self.time, flux, err, self.exposure, dict(self.report))

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
