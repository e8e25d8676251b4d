"""What ``jaxppo ttv`` writes: the measured transit times (ECSV), the O-C
diagram of each planet, and the comparison with reference times."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..model._strict_json import strict_jsonable
from ._times import TIMES_COLUMNS, linear_ephemeris

if TYPE_CHECKING:  # astropy is imported where a table is read
    from astropy.table import Table

__all__ = ["read_times", "days_column", "epoch_column", "read_references", "compare_times", "plot_oc", "write_times_products",
           "summary_lines", "time_system_offset", "TIME_SYSTEM_OFFSETS"]

MINUTES = 1440.0


def read_times(path) -> "Table":
    """A table of transit times (columns planet, epoch, tc [d], tc_err [d];
    CSV or, by its suffix, ECSV), as ``measure_transit_times`` writes
    it. Raises ValueError naming the file and what is missing."""
    from astropy.table import Table

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"transit-times file {str(path)!r} not found")
    fmt = "ascii.ecsv" if path.suffix.lower() == ".ecsv" else "ascii.csv"
    try:
        table = Table.read(path, format=fmt)
    except Exception as e:  # astropy raises many kinds on a malformed table
        raise ValueError(f"cannot read transit-times file {str(path)!r} as {fmt}: {e}") from None
    missing = [c for c in ("planet", "epoch", "tc", "tc_err") if c not in table.colnames]
    if missing:
        raise ValueError(f"transit-times file {str(path)!r} needs columns planet, epoch, tc, tc_err; missing "
                         f"{missing} (has {table.colnames})")
    out = Table()
    out["planet"] = [str(v) for v in table["planet"]]
    out["epoch"] = epoch_column(table, "epoch", path)
    out["tc"] = days_column(table, "tc", path)
    out["tc_err"] = days_column(table, "tc_err", path)
    # a reference is compared epoch by epoch: each time finite, each error
    # finite and > 0 (one NaN made a planet's whole comparison NaN), one row
    # per (planet, epoch)
    bad = np.flatnonzero(~np.isfinite(out["tc"]) | ~(np.asarray(out["tc_err"]) > 0) | ~np.isfinite(out["tc_err"]))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"transit-times file {str(path)!r} row {i + 1} (planet {out['planet'][i]}, epoch "
                         f"{out['epoch'][i]}): tc must be finite and tc_err finite and > 0 [d], got tc = "
                         f"{out['tc'][i]!r}, tc_err = {out['tc_err'][i]!r} ({bad.size} such rows)")
    seen = {}
    for i, key in enumerate(zip(out["planet"], out["epoch"])):
        if key in seen:
            raise ValueError(f"transit-times file {str(path)!r} lists planet {key[0]} epoch {key[1]} twice (rows "
                             f"{seen[key] + 1} and {i + 1})")
        seen[key] = i
    return out


def days_column(table, name: str, path) -> np.ndarray:
    """Column ``name`` of a times table in days: a column with a time unit
    (an ECSV file's, e.g. errors in minutes) is converted, one without a
    unit taken as days, one with another unit refused naming the file."""
    column = table[name]
    if getattr(column, "unit", None) is None:
        return np.asarray(column, float)
    import astropy.units as u

    try:
        return np.asarray(column.quantity.to_value(u.d), float)
    except u.UnitConversionError:
        raise ValueError(f"transit-times file {str(path)!r}: column {name} is in {column.unit}, not a unit of time "
                         "(days, or minutes etc.: converted)") from None


def epoch_column(table, name: str, path) -> np.ndarray:
    """Column ``name`` of a times table as integer epochs; a value that is
    not a whole number (it was truncated) is refused naming the file."""
    values = np.asarray(table[name], float)
    bad = ~np.isfinite(values) | (values != np.round(values))
    if bad.any():
        raise ValueError(f"transit-times file {str(path)!r}: column {name} must hold whole epoch numbers, got "
                         f"{float(values[bad][0])!r} ({int(bad.sum())} such rows)")
    return values.astype(int)


def read_references(paths) -> dict:
    """{label: ``read_times`` table} of the reference files ``paths``
    (``[ttv] reference``): each labelled by its file name, or by its path
    where two files share a name (one must not replace the other)."""
    names = [Path(p).name for p in paths]
    return {(n if names.count(n) == 1 else str(p)): read_times(p) for n, p in zip(names, paths)}


def compare_times(measured, reference) -> dict:
    """Per planet, the measured times against reference times of the same
    epochs: z = (tc - tc_ref) / sqrt(tc_err^2 + tc_err_ref^2); returns
    {planet: {n, median_abs_z, within_1sigma, within_2sigma, max_abs_z,
    chi2, median_diff_min, err_ratio}} (the median of tc - tc_ref [min]: a
    shift common to every epoch shows there; err_ratio the median of
    tc_err_ref / tc_err: errors in minutes in a CSV, read as days, give
    about 1440 and every z near 0). A planet without common epochs gets
    {n: 0, reference_planets} (the reference's planet names)."""
    out = {}
    for planet in sorted(set(measured["planet"])):
        m = measured[measured["planet"] == planet]
        r = reference[reference["planet"] == planet]
        ref = {int(e): (float(t), float(s)) for e, t, s in zip(r["epoch"], r["tc"], r["tc_err"])}
        z, diff, ratio = [], [], []
        for e, t, s in zip(m["epoch"], m["tc"], m["tc_err"]):
            if int(e) in ref:
                tr, sr = ref[int(e)]
                diff.append(float(t) - tr)
                z.append(diff[-1] / np.hypot(float(s), sr))
                ratio.append(sr / float(s))
        z = np.asarray(z)
        if not z.size:  # e.g. planets named 1, 2, 3 there: said, not left out
            out[planet] = {"n": 0, "reference_planets": sorted({str(v) for v in reference["planet"]})}
            continue
        out[planet] = {"n": int(z.size), "median_abs_z": float(np.median(np.abs(z))),
                       "within_1sigma": float(np.mean(np.abs(z) < 1)), "within_2sigma": float(np.mean(np.abs(z) < 2)),
                       "max_abs_z": float(np.max(np.abs(z))), "chi2": float(np.sum(z**2)),
                       "median_diff_min": float(np.median(diff) * MINUTES), "err_ratio": float(np.median(ratio))}
    return out


#: The median ratio of a reference's errors to the measured ones above which
#: ``summary_lines`` says that the reference's errors may be minutes read
#: as days (a CSV carries no unit): 1440 then, and every z near 0.
ERR_RATIO_SUSPECT = 100.0


#: Offsets between the time systems a reference may be given in [d]: BJD_TDB
#: less BKJD and BTJD, BTJD less BKJD, JD less MJD and reduced JD.
TIME_SYSTEM_OFFSETS = {"BJD - BKJD (2454833)": 2454833.0, "BJD - BTJD (2457000)": 2457000.0,
                       "BTJD - BKJD (2167)": 2167.0, "JD - MJD (2400000.5)": 2400000.5,
                       "JD - RJD (2400000)": 2400000.0}


def time_system_offset(median_diff_min: float) -> "str | None":
    """The time-system offset (``TIME_SYSTEM_OFFSETS``) nearest the median
    difference measured - reference [min], either sign, where it lies
    within 1 d of it; None where none does."""
    days = abs(median_diff_min) / MINUTES
    name = min(TIME_SYSTEM_OFFSETS, key=lambda n: abs(days - TIME_SYSTEM_OFFSETS[n]))  # the nearest (RJD vs MJD)
    return name if abs(days - TIME_SYSTEM_OFFSETS[name]) < 1.0 else None


def plot_oc(measured, planet: str, path, references=None) -> dict:
    """The O-C diagram of one planet: measured minus the linear ephemeris
    fitted to the measured times [min] against epoch, with 1-sigma errors
    (and the times of each of ``references``, {label: table}, against the
    same ephemeris).
    Returns the ephemeris {t0, period, t0_err, period_err} [d]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = measured[measured["planet"] == planet]
    t0, period, cov = linear_ephemeris(m["epoch"], m["tc"], m["tc_err"])
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for k, (label, ref) in enumerate((references or {}).items()):
        r = ref[ref["planet"] == planet]
        if len(r):
            ax.errorbar(np.asarray(r["epoch"]) + 0.15 * (k + 1), (np.asarray(r["tc"]) - t0 - period
                        * np.asarray(r["epoch"])) * MINUTES, np.asarray(r["tc_err"]) * MINUTES, fmt="sD^v"[k % 4],
                        ms=3, color=f"C{k + 1}", mfc="none", label=label)
    ax.errorbar(m["epoch"], (np.asarray(m["tc"]) - t0 - period * np.asarray(m["epoch"])) * MINUTES,
                np.asarray(m["tc_err"]) * MINUTES, fmt="o", ms=3, color="C0", label="jaxppo")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("epoch")
    ax.set_ylabel("O - C [min]")
    ax.set_title(f"planet {planet}: tc = {t0:.5f} + {period:.6f} n [d]")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return {"t0": t0, "period": period, "t0_err": float(np.sqrt(cov[0, 0])), "period_err": float(np.sqrt(cov[1, 1]))}


def write_times_products(table, out, references=None) -> dict:
    """Write ``transit_times.ecsv`` (columns ``TIMES_COLUMNS``), an O-C
    figure ``oc_<planet>.png`` per planet with two or more epochs and
    ``ttv_summary.json`` (the fit, each planet's linear ephemeris and O-C
    scatter, and the comparison with each of ``references``, {label:
    table}) in the folder ``out``; returns the summary."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / "transit_times.ecsv.tmp"
    table[list(TIMES_COLUMNS)].write(tmp, format="ascii.ecsv", overwrite=True)
    os.replace(tmp, out / "transit_times.ecsv")
    summary = {"fit": dict(table.meta), "planets": {}, "figures": []}
    err = np.asarray(table["tc_err"], float)
    measured = table[np.isfinite(err) & (err > 0)]  # a time without an error has no place in an ephemeris fit
    for planet in sorted(set(table["planet"])):
        entry = {"transits": int(np.sum(table["planet"] == planet))}
        lost = table[(table["planet"] == planet) & ~(np.isfinite(err) & (err > 0))]
        if len(lost):
            entry["epochs_without_error"] = [int(e) for e in lost["epoch"]]
        m = measured[measured["planet"] == planet]
        if len(set(m["epoch"])) >= 2:
            name = f"oc_{planet}.png"
            eph = plot_oc(measured, planet, out / name, references)
            oc = np.asarray(m["tc"]) - eph["t0"] - eph["period"] * np.asarray(m["epoch"])
            entry.update(eph, oc_rms_min=float(np.sqrt(np.mean(oc**2)) * MINUTES),
                         oc_max_abs_min=float(np.max(np.abs(oc)) * MINUTES),
                         median_tc_err_min=float(np.median(m["tc_err"]) * MINUTES),
                         chi2_linear=float(np.sum((oc / np.asarray(m["tc_err"])) ** 2)))
            summary["figures"].append(name)
        summary["planets"][planet] = entry
    if references:
        # the times with an error (a NaN one made the planet's whole comparison NaN)
        summary["reference"] = {label: compare_times(measured, ref) for label, ref in references.items()}
    # the O-C figures of an earlier run in this folder (planets not measured
    # now) went with its table and summary, which this run replaces: those
    # its summary lists (no other file of the folder)
    try:
        before = json.loads((out / "ttv_summary.json").read_text()).get("figures", [])
    except (OSError, ValueError, AttributeError):
        before = []
    for name in before if isinstance(before, list) else []:
        if isinstance(name, str) and name.startswith("oc_") and name not in summary["figures"]:
            (out / Path(name).name).unlink(missing_ok=True)
    tmp = out / "ttv_summary.json.tmp"
    tmp.write_text(json.dumps(strict_jsonable(summary), indent=2, allow_nan=False) + "\n")
    os.replace(tmp, out / "ttv_summary.json")
    return summary


def summary_lines(summary: dict, n_times: int, seconds: float) -> list[str]:
    """What ``jaxppo ttv`` prints of ``write_times_products``' summary."""
    fit = summary["fit"]
    jitter = "lc.jitter" in fit.get("parameters", {})  # chi2 is then the objective -2 ln L + const
    lines = [f"{n_times} transit times, " + (
        f"-2 ln L - sum ln(2 pi sigma^2) = {fit['chi2']:.1f} (a free jitter) for {fit['n_points']} points (chi^2 "
        f"with the jitter's errors / (N - k) = {fit['reduced_chi2']:.3f})" if jitter else
        f"chi^2 = {fit['chi2']:.1f} for {fit['n_points']} points (chi^2/(N - k) = {fit['reduced_chi2']:.3f})")
        + f", {seconds:.1f} s"]
    for name, (value, error) in fit.get("parameters", {}).items():
        lines.append(f"  {name} = {value:.6g} +- {error:.2g}")
    for planet, e in summary["planets"].items():
        line = f"  {planet}: {e['transits']} transits"
        if "oc_rms_min" in e:
            line += (f", O-C rms {e['oc_rms_min']:.1f} min (max {e['oc_max_abs_min']:.1f}), median error "
                     f"{e['median_tc_err_min']:.1f} min, chi^2 of a linear ephemeris {e['chi2_linear']:.1f}")
        if e.get("epochs_without_error"):
            line += f"; epochs {e['epochs_without_error']} without an error (left out of the ephemeris)"
        lines.append(line)
    for label, per_planet in summary.get("reference", {}).items():
        lines.append(f"  against {label}:")
        for planet, c in per_planet.items():
            if c["n"]:
                lines.append(f"    {planet}: {c['n']} epochs, median |z| {c['median_abs_z']:.2f}, "
                             f"{100 * c['within_1sigma']:.0f} % within 1 sigma, {100 * c['within_2sigma']:.0f} % "
                             f"within 2, max |z| {c['max_abs_z']:.2f} (median difference "
                             f"{c['median_diff_min']:+.2f} min, error ratio reference / measured "
                             f"{c['err_ratio']:.2g})")
                offset = time_system_offset(c["median_diff_min"])
                if offset is not None:
                    lines.append(f"      warning: the measured and reference times differ by {c['median_diff_min']:+.6g} "
                                 f"min, the offset {offset} d between time systems: the reference is in another "
                                 "time system than the data (convert one of them)")
                if c["err_ratio"] > ERR_RATIO_SUSPECT:
                    lines.append(f"      warning: the reference's errors are {c['err_ratio']:.0f} times the measured "
                                 "ones, so every z is near 0: errors in minutes read as days? (a CSV has no units: "
                                 "give tc_err in days, or an ECSV with its unit)")
            else:
                lines.append(f"    {planet}: no epoch in common, nothing compared (the reference's planets: "
                             f"{c.get('reference_planets', [])}; epochs count from each planet's t0)")
    return lines
