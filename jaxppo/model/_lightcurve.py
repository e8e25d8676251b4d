"""LightCurve: photometry with errors, from CSV, Kepler / TESS FITS files,
lightkurve objects or astropy Time / Quantity arrays."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ._exposure import supersampled_times
from ._units import from_quantity
from ._readers import (COLUMN_ROLES, diff_sigma, flux_values, is_lightkurve, lightkurve_columns, lightkurve_exposure,
                       lightkurve_mixed_missions, plain_values, read_csv_columns, read_fits_columns, resolve_bitmask,
                       to_days, TIME_ZERO, zero_text)
# importable from here as before the readers moved (jaxppo.obliquity, the CLI)
from ._readers import QUALITY_BITMASKS as QUALITY_BITMASKS
from ._readers import QUALITY_FLAGS as QUALITY_FLAGS
from ._readers import quality_bitmask as quality_bitmask

__all__ = ["LightCurve", "QUALITY_FLAGS", "QUALITY_BITMASKS", "quality_bitmask", "COLUMN_ROLES", "is_lightkurve",
           "LONG_CADENCE", "cadence_warning"]

LONG_CADENCE = 5.0 / 1440.0
"""Median spacing [d] above which points without an exposure get a warning
(``cadence_warning``): the model of such points must be averaged over their
integration."""


@dataclasses.dataclass(frozen=True)
class LightCurve:
    """Photometry: time [d], relative flux and its 1-sigma error.

    A frozen dataclass; the points are stored sorted by time, as float
    numpy arrays. The constructor is strict: every value finite, errors > 0,
    no repeated time stamp (it would count twice in chi^2). The loaders
    (``from_arrays``, ``from_csv``, ``from_fits``,
    ``from_lightkurve``) drop such points instead and say so in
    ``report``.

    Parameters
    ----------
    time : array_like or astropy.time.Time or Quantity
        Times [d], shape [n_times]. An astropy ``Time`` is converted to
        BJD_TDB - ``time_zero`` [d] (formats "bkjd" and "btjd" carry their
        own zero point, 2454833 and 2457000); a time Quantity to days.
    flux : array_like or Quantity
        Relative flux [n_times] (numbers or a dimensionless Quantity; raw
        fluxes in e-/s: ``from_arrays`` with ``normalize=True``).
    flux_err : array_like or Quantity
        1-sigma errors of ``flux`` [n_times], > 0.
    exposure : float or Quantity or TimeDelta or None, optional
        Integration time of each point [d] (e.g. 0.0204 for Kepler long
        cadence), used to average the model over the exposure; a time
        Quantity or TimeDelta is converted to days and stored as a float.
        0: the points are instants, said so (stored as None with
        ``instantaneous`` True). None (default): not given, modelled as
        instants; ``fit``, ``sample`` and ``measure_transit_times`` warn
        where such points lie more than ``LONG_CADENCE`` (5 min) apart (a
        29.4-min Kepler point modelled at one instant gives transit times
        with errors 1.2-1.4 times too small).
    report : dict, optional
        What loading kept and dropped (``report_line`` says it in words).
    errors_estimated : bool, optional
        True when the file had no errors and ``flux_err`` is an estimate from
        the scatter (the scan re-estimates it per window). Default False.
    time_zero : float or None, optional
        Zero point [JD] of an astropy ``Time`` given as ``time``, and the
        light curve's zero point for ``to_time_zero``.
    instantaneous : bool, optional
        True: the points are instants, said so (``exposure=0`` sets it); no
        warning about a long cadence. Ignored where an exposure is given.

    Raises
    ------
    ValueError
        When time, flux and flux_err are not 1D of equal length, empty, or
        hold a non-finite value; an error is <= 0; a time stamp is repeated;
        ``exposure`` is not one positive number of days; ``time`` is a
        lightkurve object (use ``from_lightkurve``) or an astropy
        ``Time`` without a known zero point.

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> lc = jp.LightCurve(np.array([0.04, 0.0, 0.02]), np.array([1.0, 0.999, 1.001]), np.full(3, 1e-3),
    ...                    exposure=0.0204)
    >>> len(lc), lc.time
    (3, array([0.  , 0.02, 0.04]))

    The loaders clean the points and report what they dropped:

    >>> lc = jp.LightCurve.from_arrays([1.0, 2.0, 3.0, np.nan], [1.0, 0.999, np.nan, 1.0], [1e-3] * 4)
    >>> lc.report_line()
    '2 of 4 points kept from arrays; dropped: 0 flagged (quality bitmask none: no quality column),
    2 non-finite or with error <= 0, 0 repeated time stamps'

    A bundled piece of Kepler-20's quarter 1 (PDCSAP flux, divided by its median):

    >>> from importlib.resources import files
    >>> path = files("jaxppo") / "data" / "kepler20_kic6850504_q1_llc_BKJD159.0-161.5.csv"
    >>> lc = jp.LightCurve.from_csv(path, exposure=0.0204, mission="kepler")
    >>> print(len(lc), f"{np.median(lc.flux):.6f}", f"{lc.flux_err[0]:.1e}", lc.report["flags_kept"])
    122 1.000000 7.0e-05 7
    """

    time: np.ndarray
    flux: np.ndarray
    flux_err: np.ndarray
    exposure: float | None = None
    report: dict = dataclasses.field(default_factory=dict)
    errors_estimated: bool = False
    time_zero: float | None = None
    instantaneous: bool = False

    def __post_init__(self):
        if is_lightkurve(self.time):
            raise ValueError("a lightkurve LightCurve goes through LightCurve.from_lightkurve(lc)")
        if self.flux_err is None:
            raise ValueError("flux_err must be given (one error per point); LightCurve.from_arrays(time, flux) "
                             "estimates it from the point-to-point scatter")
        t, note, zero = to_days(self.time, self.time_zero)
        if self.time_zero is None and zero is not None:
            object.__setattr__(self, "time_zero", zero)  # an astropy Time's BKJD / BTJD
        f, e, _ = flux_values(self.flux, self.flux_err, False)
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
        if self.exposure is not None:
            # a time Quantity or TimeDelta becomes days here, where it is
            # stored: the model code downstream does arithmetic in days
            exposure = np.asarray(from_quantity("exposure", self.exposure, "d"), float)
            if exposure.shape != ():
                raise ValueError(f"exposure must be one number of days, got shape {exposure.shape}: {self.exposure!r}")
            if not (np.isfinite(exposure) and exposure >= 0):
                raise ValueError(f"exposure must be >= 0 days (0: the points are instants), got {self.exposure}")
            object.__setattr__(self, "exposure", float(exposure) if exposure > 0 else None)
            object.__setattr__(self, "instantaneous", bool(exposure == 0))
        if not isinstance(self.instantaneous, (bool, np.bool_)):
            raise ValueError(f"instantaneous must be True or False, got {self.instantaneous!r}")
        order = np.argsort(t, kind="stable")
        t = t[order]
        dup = np.diff(t) == 0
        if dup.any():
            raise ValueError(f"time has {int(dup.sum())} repeated time stamps (first at {t[1:][dup][0]!r}); each would "
                             "count twice in chi^2 (LightCurve.from_arrays keeps the first and reports it)")
        if self.exposure is not None and t.size >= 3:
            # an exposure in minutes or seconds read as days (29.4 for 29.4 min) averaged the model over weeks
            # and asked for tens of GiB; exposures longer than the points' spacing overlap each other
            spacing = float(np.median(np.diff(t)))
            if self.exposure > 2.0 * spacing:
                raise ValueError(
                    f"exposure must be a number of days no longer than the points' spacing, got {self.exposure:g} "
                    f"d, {self.exposure / spacing:.3g} times their median spacing of {spacing:.6g} d (a 29.4-min "
                    "Kepler long cadence is 0.0204 d)")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "flux", f[order])
        object.__setattr__(self, "flux_err", e[order])
        if note is not None and "time" not in self.report:
            object.__setattr__(self, "report", dict(self.report, time=note))

    def __len__(self) -> int:
        return self.time.size

    def report_line(self) -> str:
        """What loading kept and dropped, in one line (also in the scan summary).

        Returns
        -------
        str
            Points kept of those read, from which source, and how many were
            dropped as flagged, non-finite (or with error <= 0) and repeated;
            flags outside the bitmask that were kept; the time system.
        """
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
        selected_out = tot["points"] - tot["flagged"] - tot["non_finite"] - tot["duplicated"] - len(self)
        if selected_out > 0:  # select / windows after loading (each part counts its whole file)
            s += f"; {selected_out} more left out by a selection"
        if tot["flags_kept"]:
            s += f"; {tot['flags_kept']} points with flags outside the bitmask kept"
        div = r.get("divided_by")
        if isinstance(div, dict) and any(v != 1.0 for v in div.values()):
            s += f"; flux and errors divided by the median of each of {len(div)} segments"
        elif isinstance(div, (int, float)) and div != 1.0:
            s += f"; flux and errors divided by their median {div:.6g}"
        if r.get("time"):
            s += f"; time: {r['time']}"
        return s

    # ---- loading ----------------------------------------------------------------
    @classmethod
    def _from_columns(cls, t, f, e, q, exposure, source, normalize=True, segment=None, bitmask=(-1, "any flag"),
                      time_note=None, extra=None, time_zero=None) -> "LightCurve":
        """Drop flagged (``q & bitmask != 0``; a missing flag counts as
        flagged), non-finite and repeated-time points (the first of each
        repeated stamp is kept), counting each in ``report``; divide each
        segment (e.g. a Kepler quarter, each with its own flux level) by its
        median flux when ``normalize``; ``e=None`` (no errors in the file):
        estimate one error per segment from the point-to-point scatter."""
        t, f = np.asarray(t, float), np.asarray(f, float)
        shapes = {k: np.shape(v) for k, v in (("time", t), ("flux", f), ("flux_err", e), ("quality", q),
                                              ("segment", segment)) if v is not None}
        if t.ndim != 1 or any(v != t.shape for v in shapes.values()):
            raise ValueError(f"{source}: {', '.join(shapes)} must be 1D of equal length (one value per point), got "
                             + ", ".join(f"{k} {v}" for k, v in shapes.items()))
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
            raise ValueError(f"{source}: no usable points ({report['flagged']} flagged, {report['non_finite']} non-finite or with error <= 0, of {t.size})")
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
                sig = diff_sigma(flux[m][np.argsort(t[m])])
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
        return cls(t, flux, err, exposure=exposure, report=report, errors_estimated=not has_err, time_zero=time_zero)

    @classmethod
    def from_arrays(cls, time, flux, flux_err=None, quality=None, *, exposure: float | None = None,
                    normalize: bool | None = None, quality_bitmask="default", mission: str | None = None,
                    time_zero: float | None = None, source: str = "arrays") -> "LightCurve":
        """A light curve from arrays as they come, cleaned and reported.

        Points that are flagged, non-finite, with error <= 0 or at a repeated
        time stamp (all but the first) are dropped and counted in ``report``.

        Parameters
        ----------
        time : array_like or astropy.time.Time or Quantity
            Times [n_times]: days, a time Quantity, or an astropy ``Time``
            (BJD_TDB - ``time_zero`` [d]; "bkjd" / "btjd" formats need no
            ``time_zero``).
        flux : array_like or Quantity
            Flux [n_times]; a physical unit such as e-/s means raw flux,
            divided by its median.
        flux_err : array_like or Quantity or None, optional
            1-sigma errors [n_times]; None (default): one error per light
            curve estimated from the point-to-point scatter
            (``errors_estimated``).
        quality : array_like of int or None, optional
            Quality flags [n_times]; a point is dropped where
            ``quality & bitmask != 0``.
        exposure : float or None, optional
            Integration time of each point [d]; None: instantaneous.
        normalize : bool or None, optional
            Divide flux and errors by the median flux; default (None): for
            fluxes with a physical unit or a median > 10.
        quality_bitmask : str or int, optional
            "none", "default" (default), "hard", "hardest" or an integer
            (see ``jaxppo.model._lightcurve.quality_bitmask``).
        mission : str or None, optional
            "kepler", "k2" or "tess": the meaning of the named bitmasks;
            without one every non-zero flag drops the point.
        time_zero : float or None, optional
            Zero point [JD] of an astropy ``Time`` in another format.
        source : str, optional
            Name of the source in ``report`` (default "arrays").

        Returns
        -------
        LightCurve
            The kept points, sorted by time.

        Raises
        ------
        ValueError
            When time, flux, flux_err and quality are not 1D of equal length,
            no point is usable, the median flux is 0 or not finite, the
            errors cannot be estimated, the bitmask or mission is unknown,
            or the time has no known zero point.
        """
        t, note, zero = to_days(time, time_zero)
        f, e, normalize = flux_values(flux, flux_err, normalize)
        q = None if quality is None else plain_values(quality, "quality")[0]
        if normalize is None:
            finite = f[np.isfinite(f)]
            normalize = bool(finite.size > 0 and np.median(finite) > 10)
        return cls._from_columns(t, f, e, q, exposure, source, normalize, None,
                                 resolve_bitmask(quality_bitmask, mission), note, time_zero=zero)

    @classmethod
    def from_lightkurve(cls, lc, flux_column: str = "flux", quality_bitmask="default", exposure: float | None = None,
                        normalize: bool | None = None, time_zero: float | None = None) -> "LightCurve":
        """A light curve from a lightkurve ``LightCurve``, without importing lightkurve.

        E.g. ``lk.read(path)`` or ``search_lightcurve(...).download()``. Time:
        its ``time`` (an astropy ``Time``, BKJD for Kepler, BTJD for TESS,
        converted to days since its zero point); flux: ``flux_column`` and
        ``<flux_column>_err`` (Quantities in e-/s are divided by their
        median; a normalised, dimensionless flux is taken as is); quality:
        the ``quality`` column with ``quality_bitmask`` of the mission in
        ``lc.meta`` (lightkurve itself drops its "default" bitmask when
        reading, and drops NaN times silently;
        ``report["lightkurve_quality_bitmask"]`` records what it used).

        Parameters
        ----------
        lc : lightkurve.LightCurve
            The light curve (anything with ``time``, ``flux`` and ``meta``).
        flux_column : str, optional
            Column of the flux (default "flux"); errors from
            ``<flux_column>_err``.
        quality_bitmask : str or int, optional
            "none", "default" (default), "hard", "hardest" or an integer.
        exposure : float or None, optional
            Integration time [d]; default: the bin size of a binned light
            curve (its ``time_bin_size``; ``lc.meta`` keeps the unbinned
            TIMEDEL), else TIMEDEL from ``lc.meta``.
        normalize : bool or None, optional
            Divide by the median flux; default (None): for fluxes with a
            physical unit or a median > 10.
        time_zero : float or None, optional
            Zero point [JD] for a time in a format without one.

        Returns
        -------
        LightCurve
            The kept points, sorted by time.

        Raises
        ------
        ValueError
            When ``lc`` lacks time, flux or meta, its bins differ in size
            and ``exposure`` is not given, or no point is usable.

        Warns
        -----
        UserWarning
            When the time's format (bkjd, btjd) names another mission than
            ``lc.meta`` (a light curve stitched from Kepler and TESS data:
            its TIMEDEL and quality bits are one part's).
        """
        if not (hasattr(lc, "time") and hasattr(lc, "flux") and hasattr(lc, "meta")):
            raise ValueError(f"lc must be a lightkurve LightCurve (with time, flux, meta), got {type(lc).__name__}")
        f, e, q, mission, meta = lightkurve_columns(lc, flux_column)
        if exposure is None:
            exposure = lightkurve_exposure(lc, meta)
        if mixed := lightkurve_mixed_missions(lc, meta):
            import warnings

            warnings.warn(f"from_lightkurve: {mixed}", UserWarning, stacklevel=2)
        label = meta.get("LABEL") or meta.get("OBJECT") or meta.get("TARGETID") or ""
        extra = {"lightkurve_quality_bitmask": meta["QUALITY_BITMASK"]} if "QUALITY_BITMASK" in meta else {}
        extra = {k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in extra.items()}
        t, note, zero = to_days(lc.time, time_zero)
        fv, ev, normalize = flux_values(f, e, normalize)
        if normalize is None:
            finite = fv[np.isfinite(fv)]
            normalize = bool(finite.size > 0 and np.median(finite) > 10)
        qv = None if q is None else plain_values(q, "quality")[0]
        return cls._from_columns(t, fv, ev, qv, exposure, f"lightkurve {type(lc).__name__} {label}".strip(), normalize,
                                 None, resolve_bitmask(quality_bitmask, mission), note, extra, zero)

    @classmethod
    def from_csv(cls, path, exposure: float | None = None, normalize: bool | None = None,
                 columns: dict | None = None, quality_bitmask="default", mission: str | None = None) -> "LightCurve":
        """A light curve from a CSV file (or a gzip-compressed .csv.gz) with a header row.

        Flagged rows (an empty quality cell counts as flagged), non-finite
        values and repeated time stamps are dropped and counted in
        ``report``. A file without an error column gets errors estimated from
        its scatter (``errors_estimated``, and ``report["flux_err"]`` says
        so). A quarter column divides each quarter by its own median flux.

        Parameters
        ----------
        path : str or path-like
            The file.
        exposure : float or None, optional
            Integration time of each point [d]; None: instantaneous.
        normalize : bool or None, optional
            Divide by the median flux; default (None): for raw Kepler columns
            (pdcsap_flux, sap_flux) or fluxes far from 1 (median > 10).
        columns : dict or None, optional
            Maps the roles time, flux, flux_err, quality, quarter to the
            file's column names (case-insensitive), e.g. ``{"flux_err":
            "error"}``; roles not given are looked up under the usual names
            (time, time_bkjd; flux, pdcsap_flux; flux_err, pdcsap_flux_err;
            quality, sap_quality; quarter).
        quality_bitmask : str or int, optional
            "none", "default" (default), "hard", "hardest" or an integer; a
            row is dropped where ``quality & bitmask != 0``.
        mission : str or None, optional
            "kepler" or "tess": the meaning of the named bitmasks; without a
            mission every non-zero flag drops the row.

        Returns
        -------
        LightCurve
            The kept points, sorted by time.

        Raises
        ------
        ValueError
            When ``path`` is not one file, the file does not exist, is a
            folder or cannot be read (no header row, a cell that is not a
            number), ``columns`` names an unknown role or column, a needed column is missing, the bitmask
            or mission is unknown, or no point is usable.
        """
        path = _one_file(path)
        if not path.exists():
            raise ValueError(f"light-curve file not found: {path}")
        if path.is_dir():
            raise ValueError(f"light-curve path is a folder, not a file: {path}")
        bitmask = resolve_bitmask(quality_bitmask, mission)
        columns = dict(columns or {})
        unknown = sorted(set(columns) - set(COLUMN_ROLES))
        if unknown:
            raise ValueError(f"columns: unknown role {unknown[0]!r}; roles are {list(COLUMN_ROLES)}")
        t, f, e, q, seg, flux_name = read_csv_columns(path, columns)
        if normalize is None:
            finite = f[np.isfinite(f)]
            normalize = flux_name in ("pdcsap_flux", "sap_flux") or (finite.size > 0 and np.median(finite) > 10)
        return cls._from_columns(t, f, e, q, exposure, path, normalize, seg, bitmask)

    @classmethod
    def concatenate(cls, parts, exposure: float | None = None) -> "LightCurve":
        """Join light curves, e.g. one file per quarter, each already divided by its own median.

        Parameters
        ----------
        parts : iterable of LightCurve
            The light curves; their exposures must agree unless ``exposure``
            is given, and their times must count from one zero point (a
            TESS light curve joins Kepler data after
            ``to_time_zero("bkjd")``).
        exposure : float or None, optional
            Integration time of the joined light curve [d]; a part that
            has another one gets a UserWarning (its points would be
            averaged over the wrong length).

        Returns
        -------
        LightCurve
            All points, sorted by time; ``report["sources"]`` holds the
            parts' reports; ``time_zero`` is the parts' common zero point
            (None where a part's is unknown).

        Warns
        -----
        UserWarning
            When a part of unknown zero point (a CSV file's) joins parts of
            a known one (a TESS file's BTJD): nothing tells whether its times
            are on the same scale.

        Raises
        ------
        ValueError
            When ``parts`` is one light curve, empty or holds anything but
            jaxppo LightCurves, two parts' known zero points differ
            (BTJD beside BKJD: ``time_zero``, or a Kepler or TESS file's),
            the exposures differ and ``exposure`` is not given, or two parts
            share a time stamp.
        """
        if isinstance(parts, LightCurve) or is_lightkurve(parts):
            raise ValueError("concatenate takes a list of light curves, got one light curve")
        parts = list(parts)
        if not parts:
            raise ValueError("concatenate needs at least one light curve")
        for k, p in enumerate(parts):
            if not isinstance(p, LightCurve):
                hint = " (LightCurve.from_lightkurve(lc) first)" if is_lightkurve(p) else ""
                raise ValueError(f"concatenate: part {k} must be a jaxppo LightCurve, got {type(p).__name__}{hint}")
        zeros = [_known_zero(p) for p in parts]
        known = sorted({z for z in zeros if z is not None})
        if len(known) > 1:
            # BTJD points beside BKJD ones sit 2167 d (6 years) off: every transit in the wrong place, no error
            names = ", ".join(_zero_name(z) for z in known)
            raise ValueError(f"the light curves count time from different zero points, BJD_TDB - {names} [JD]: move "
                             "them onto one first, e.g. tess.to_time_zero('bkjd') beside Kepler data")
        time_zero = known[0] if known and None not in zeros else None
        if known and None in zeros:
            import warnings

            label = _zero_name(known[0])
            unknown = [k for k, z in enumerate(zeros) if z is None]
            warnings.warn(f"concatenate: part(s) {unknown} have no known time zero point (e.g. read from CSV) beside "
                          f"parts in BJD_TDB - {label}: they are joined as they are, so their times must be on that "
                          "scale too (Kepler BKJD and TESS BTJD are 2167 d apart); declare it, e.g. "
                          "part.to_time_zero('bkjd', current='bkjd'), to silence this", UserWarning, stacklevel=2)
        exps = {p.exposure for p in parts}
        if exposure is None:
            if len(exps) > 1:
                raise ValueError(
                    f"the light curves have different exposures {sorted(exps, key=str)} [d]: a light curve has one "
                    "exposure, over which every point's model is averaged; set exposure only if one length is right "
                    "for every part (e.g. parts of one instrument read without it), else model each instrument's "
                    "light curve on its own (docs/api.md, LightCurve)")
            exposure = parts[0].exposure
        elif other := sorted(e for e in exps - {None} if abs(e - exposure) > 1e-3 * exposure):
            import warnings

            warnings.warn(f"concatenate: parts with exposures {other} [d] are modelled "
                          f"with exposure = {exposure} d: a point integrated over another length gets the wrong "
                          "average (a 2-min TESS cadence smeared over 29.4 min rounds its ingress and egress)",
                          UserWarning, stacklevel=2)
        t = np.concatenate([p.time for p in parts])
        if np.unique(t).size != t.size:
            raise ValueError(f"the files share {t.size - np.unique(t).size} time stamps (the same data twice?)")
        report = {"sources": [p.report for p in parts], "kept": int(t.size)}
        if time_zero is not None:
            report["time"] = zero_text(time_zero)
        return cls(t, np.concatenate([p.flux for p in parts]), np.concatenate([p.flux_err for p in parts]),
                   exposure, report, errors_estimated=any(p.errors_estimated for p in parts), time_zero=time_zero,
                   instantaneous=all(p.instantaneous for p in parts))

    @classmethod
    def from_fits(cls, path, flux_column: str = "PDCSAP_FLUX", quality_bitmask="default",
                  mission: str | None = None) -> "LightCurve":
        """A light curve from a Kepler, K2 or TESS SPOC light-curve FITS file.

        The mission comes from the primary header (TELESCOP, else MISSION)
        unless ``mission`` is given; it sets the quality column (Kepler:
        SAP_QUALITY, TESS: QUALITY), the meaning of the named bitmasks
        (``jaxppo.model._lightcurve.QUALITY_BITMASKS``; "default": only
        cadences the missions call unusable are dropped) and the time
        system: TIME [d] is BJD_TDB - (BJDREFI + BJDREFF), 2454833 (BKJD) for
        Kepler, 2457000 (BTJD) for TESS, kept as it is (``report["time"]``
        states it). Flagged, non-finite and repeated points are dropped and
        counted in ``report``; the flux is divided by its median; the
        exposure comes from the header (TIMEDEL; Kepler long cadence
        29.4 min, TESS 2 min).

        Parameters
        ----------
        path : str or path-like
            The FITS file.
        flux_column : str, optional
            Flux column (default "PDCSAP_FLUX"; errors from
            ``<flux_column>_ERR``).
        quality_bitmask : str or int, optional
            "none", "default" (default), "hard", "hardest" or an integer.
        mission : str or None, optional
            "kepler", "k2" or "tess"; default: from the header.

        Returns
        -------
        LightCurve
            The kept points, sorted by time.

        Raises
        ------
        ValueError
            When the bitmask name is unknown, ``flux_column`` is not a
            string, ``path`` is not one file, the file does not exist, is a
            folder or cannot be read as a light-curve FITS file, a column is
            missing, the mission is missing or not Kepler, K2 or TESS, or no
            point is usable.
        """
        resolve_bitmask(quality_bitmask, None)  # a bad name fails before the file is read
        if not isinstance(flux_column, str):
            raise ValueError(f"flux_column must be a column name such as 'PDCSAP_FLUX', got {flux_column!r}")
        path = _one_file(path)
        if not path.exists():
            raise ValueError(f"light-curve file not found: {path}")
        if path.is_dir():
            raise ValueError(f"light-curve path is a folder, not a file: {path}")
        t, f, e, q, exposure, mission, note, zero = read_fits_columns(path, flux_column, mission)
        return cls._from_columns(t, f, e, q, exposure, path, True, None, resolve_bitmask(quality_bitmask, mission),
                                 note, {"mission": mission}, zero)

    @classmethod
    def from_kepler_fits(cls, path, flux_column: str = "PDCSAP_FLUX", quality_bitmask="default") -> "LightCurve":
        """``from_fits`` for a Kepler file (also without a TELESCOP key).

        Parameters
        ----------
        path : str or path-like
            The FITS file.
        flux_column : str, optional
            Flux column (default "PDCSAP_FLUX").
        quality_bitmask : str or int, optional
            "none", "default" (default), "hard", "hardest" or an integer
            (Kepler's flag bits).

        Returns
        -------
        LightCurve
            The kept points, sorted by time.
        """
        return cls.from_fits(path, flux_column, quality_bitmask, mission="kepler")

    def to_csv(self, path) -> None:
        """Write time, flux and flux_err to a CSV file that ``from_csv`` reads back.

        The file is written next to ``path`` and then renamed, so a reader
        never sees half of it. The exposure and report are not written.

        Parameters
        ----------
        path : str or path-like
            The file to write (replaced if it exists).
        """
        path = Path(path)
        tmp = path.with_suffix(path.suffix + ".tmp")
        with open(tmp, "w") as fh:
            fh.write("time,flux,flux_err\n")
            for row in zip(self.time, self.flux, self.flux_err):
                fh.write(f"{row[0]:.8f},{row[1]:.10f},{row[2]:.6e}\n")
        tmp.replace(path)

    def to_time_zero(self, time_zero, current=None) -> "LightCurve":
        """The light curve with its times counted from another zero point.

        A TESS light curve joins Kepler data with ``lc.to_time_zero("bkjd")``
        (times + 2167 d). The shift is exact: both are BJD_TDB.

        Parameters
        ----------
        time_zero : str or float
            The new zero point: "bkjd" (BJD_TDB - 2454833, Kepler), "btjd"
            (BJD_TDB - 2457000, TESS) or a number [JD].
        current : str or float or None, optional
            The current zero point (same forms); default the light curve's
            ``time_zero``, else its mission's (a Kepler or TESS FITS file).

        Returns
        -------
        LightCurve
            The shifted light curve (``time_zero`` set, ``report["time"]``
            saying so).

        Raises
        ------
        ValueError
            When a zero point is not "bkjd", "btjd" or a finite number, the
            current zero point is unknown, or ``current`` contradicts the
            light curve's known ``time_zero``.
        """
        new, now = _zero_point(time_zero, "time_zero"), None
        if current is not None:
            now = _zero_point(current, "current")
            if self.time_zero is not None and now != float(self.time_zero):
                # a TESS file's BTJD declared BKJD: no shift, BTJD times labelled BKJD, every transit 2167 d off
                raise ValueError(f"current = {current!r} (BJD_TDB - {_zero_name(now)}) contradicts the light "
                                 f"curve's own zero point, BJD_TDB - {_zero_name(float(self.time_zero))} (read from "
                                 "its file or set by an earlier shift); leave current out")
        elif self.time_zero is not None:
            now = float(self.time_zero)
        elif self.report.get("mission") in TIME_ZERO:
            now = TIME_ZERO[self.report["mission"]][0]
        if now is None:
            raise ValueError("the light curve's time zero point is unknown (not read from a Kepler or TESS file); "
                             "give current= ('bkjd', 'btjd' or a JD)")
        report = dict(self.report, time=zero_text(new) + f", shifted by {now - new:+.1f} d")
        return dataclasses.replace(self, time=self.time + (now - new), report=report, time_zero=new)

    # ---- selections -------------------------------------------------------------
    def select(self, mask) -> "LightCurve":
        """The points where ``mask`` is True.

        Parameters
        ----------
        mask : array_like of bool
            One entry per point [n_times].

        Returns
        -------
        LightCurve
            The selected points (same exposure, report and zero point).

        Raises
        ------
        ValueError
            When the mask is not one bool per point or keeps no point.
        """
        mask = np.asarray(mask, bool)
        if mask.shape != self.time.shape:
            raise ValueError(f"mask must hold one bool per point, shape {self.time.shape}, got shape {mask.shape}")
        if not mask.any():
            raise ValueError("the selection keeps no points")
        return LightCurve(self.time[mask], self.flux[mask], self.flux_err[mask], self.exposure, dict(self.report),
                          self.errors_estimated, self.time_zero, self.instantaneous)

    def windows(self, intervals) -> "LightCurve":
        """The points inside any of the (start, end) intervals.

        Parameters
        ----------
        intervals : iterable of (float, float)
            Time windows [d], ends included.

        Returns
        -------
        LightCurve
            The points in the windows.

        Raises
        ------
        ValueError
            When an interval is not a (start, end) pair or no point lies in
            any window.
        """
        keep = np.zeros(self.time.size, bool)
        for a, b in _pairs(intervals):
            keep |= (self.time >= a) & (self.time <= b)
        return self.select(keep)

    def normalized(self, intervals, in_transit) -> "LightCurve":
        """Divide each window by a second-order polynomial fitted to its out-of-transit points.

        As in Mueller et al. (2021), Sect. 2.2; the fit weights points by
        1 / flux_err. Points outside every window are left as they are.

        Parameters
        ----------
        intervals : iterable of (float, float)
            The (start, end) windows [d].
        in_transit : array_like of bool
            Points to exclude from the fit [n_times] (same length as the
            light curve).

        Returns
        -------
        LightCurve
            The light curve with flux and flux_err divided by the trend.

        Raises
        ------
        ValueError
            When an interval is not a (start, end) pair, ``in_transit`` is
            not one bool per point, or a window has fewer than 4
            out-of-transit points.
        """
        in_transit = np.asarray(in_transit, bool)
        if in_transit.shape != self.time.shape:
            raise ValueError(f"in_transit must hold one bool per point, shape {self.time.shape}, got shape "
                             f"{in_transit.shape}")
        flux, err = self.flux.copy(), self.flux_err.copy()
        for a, b in _pairs(intervals):
            win = (self.time >= a) & (self.time <= b)
            out = win & ~in_transit
            if out.sum() < 4:
                raise ValueError(f"window {a:.4f}..{b:.4f} has {out.sum()} out-of-transit points; need >= 4 for the polynomial")
            tm = 0.5 * (a + b)
            coef = np.polyfit(self.time[out] - tm, self.flux[out], 2, w=1 / self.flux_err[out])
            trend = np.polyval(coef, self.time[win] - tm)
            flux[win] = self.flux[win] / trend
            err[win] = self.flux_err[win] / trend
        return LightCurve(self.time, flux, err, self.exposure, dict(self.report), self.errors_estimated,
                          self.time_zero, self.instantaneous)

    def supersampled_times(self, n: int | None = None) -> tuple[np.ndarray, int]:
        """Times [d] at which to evaluate a model so that averaging groups of ``n`` reproduces the exposure.

        Midpoint rule, cadence by cadence; averaging consecutive groups of
        ``n`` (``jaxppo.model._exposure.exposure_mean``) gives the model of
        each exposure (the rule and why 30 s: ``jaxppo.model._exposure``).

        Parameters
        ----------
        n : int or None, optional
            Sub-exposures per cadence; default: odd, with sub-exposures <=
            SUB_EXPOSURE = 30 s (59 for a 29.4-min Kepler long cadence).

        Returns
        -------
        times : numpy.ndarray
            Sub-exposure midpoints [d], shape [n_times * n]; the times themselves
            when ``exposure`` is None.
        n : int
            Sub-exposures per cadence (1 without an exposure).

        Raises
        ------
        ValueError
            When ``n`` is not a positive integer.
        """
        return supersampled_times(self.time, self.exposure, n)


def _zero_name(zero: float) -> str:
    """A zero point [JD] for a message: "2457000.0 (BTJD)", the mission's
    name where it is one of theirs."""
    name = dict(TIME_ZERO.values()).get(zero)
    return f"{zero:.1f}" + (f" ({name})" if name else "")


def _one_file(path) -> Path:
    """``path`` as a Path; a ValueError for a list of files or anything not path-like."""
    if isinstance(path, (list, tuple)):
        raise ValueError(f"path must be one file, got a {type(path).__name__} of {len(path)}: read each and join them "
                         "with LightCurve.concatenate")
    try:
        return Path(path)
    except TypeError:
        raise ValueError(f"path must be a file name or path-like, got {type(path).__name__}") from None


def _pairs(intervals) -> list:
    """The (start, end) windows [d] of ``intervals``; a ValueError for anything else (a bare pair)."""
    out = []
    for window in intervals:
        if np.shape(window) != (2,):
            raise ValueError(f"intervals must be (start, end) pairs [d], e.g. [(3856.5, 3857.5)], got {window!r} "
                             "among them")
        out.append((float(window[0]), float(window[1])))
    return out


def _known_zero(lc: LightCurve) -> float | None:
    """The zero point [JD] of a light curve's times: its ``time_zero``, else
    its mission's (a Kepler or TESS file), else None (unknown)."""
    if lc.time_zero is not None:
        return float(lc.time_zero)
    mission = lc.report.get("mission")
    return TIME_ZERO[mission][0] if mission in TIME_ZERO else None


def _zero_point(value, name: str) -> float:
    """A zero point [JD] from "bkjd", "btjd" or a number."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be 'bkjd', 'btjd' or a Julian date, got {value!r}")
    if isinstance(value, str):
        zeros = {"bkjd": TIME_ZERO["kepler"][0], "btjd": TIME_ZERO["tess"][0]}
        if value.lower() not in zeros:
            raise ValueError(f"{name} must be 'bkjd', 'btjd' or a Julian date, got {value!r}")
        return zeros[value.lower()]
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 'bkjd', 'btjd' or a Julian date, got {value!r}") from None
    if not np.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def cadence_warning(lc: LightCurve) -> str | None:
    """The warning about ``lc``'s points being modelled as instants where
    they are more than ``LONG_CADENCE`` apart (median) and neither an
    exposure nor ``instantaneous`` says what they are; None otherwise, and
    where it was given for this light curve already (``report
    ["exposure_note"]``, which holds it)."""
    if lc.exposure is not None or lc.instantaneous or lc.time.size < 2 or "exposure_note" in lc.report:
        return None
    spacing = float(np.median(np.diff(lc.time)))
    if spacing <= LONG_CADENCE:
        return None
    note = (f"no exposure is given, so every point is modelled at one instant, but the points are {spacing * 1440:.1f} "
            "min apart (median): if each integrates over that time (Kepler long cadence: 0.0204 d, 29.4 min), give "
            "its length in days (LightCurve(..., exposure=...), [data] exposure in a config; transit times and errors "
            "from an instantaneous model of such points are wrong), or exposure=0 if the points are instants")
    lc.report["exposure_note"] = note
    return note
