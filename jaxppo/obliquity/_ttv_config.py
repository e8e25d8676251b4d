"""Transit times in a scan config: ``transit_times`` / ``transit_epochs``
of a [[planet]] table (docs/config.md), inline lists or a CSV/ECSV file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["TTV_KEYS", "transit_times_from", "planet_ttv_dict", "ttv_digest", "ttv_settings"]

TTV_KEYS = ("planets", "free", "search", "grid", "min_points", "reference")
"""The keys of a config's [ttv] section (``jaxppo ttv``; docs/config.md)."""


def transit_times_from(p: dict, base) -> dict:
    """``transit_times`` / ``transit_epochs`` of a [[planet]] table as
    Planet keywords ({} without them): inline lists, or
    ``transit_times = "file"`` (CSV, or ECSV by its suffix; relative to the
    config's folder ``base``) with columns epoch and tc [d] (tc_err may be
    there; the model does not use it; with a planet column, the rows of
    this planet's name). Raises ValueError naming the key."""
    if "transit_times" not in p:
        if "transit_epochs" in p:
            raise ValueError("transit_epochs needs transit_times (the mid-times [d] of those epochs)")
        return {}
    tt = p["transit_times"]
    if isinstance(tt, str):
        if "transit_epochs" in p:
            raise ValueError(f"transit_epochs comes from the file {tt!r} (its epoch column); remove the key")
        path = Path(tt) if Path(tt).is_absolute() else Path(base) / tt
        if not path.is_file():
            raise ValueError(f"transit_times file {str(path)!r} not found (relative paths are relative to the "
                             "config's folder)")
        from astropy.table import Table

        fmt = "ascii.ecsv" if path.suffix.lower() == ".ecsv" else "ascii.csv"
        try:
            table = Table.read(path, format=fmt)
        except Exception as e:  # astropy raises many kinds on a malformed table
            raise ValueError(f"cannot read transit_times file {str(path)!r} as {fmt}: {e}") from None
        cols = {c.lower(): c for c in table.colnames}
        if "planet" in cols:  # a table of several planets (jaxppo ttv's transit_times.ecsv): this one's rows
            name = str(p.get("name", ""))
            table = table[[str(v) == name for v in table[cols["planet"]]]]
            if not len(table):
                raise ValueError(f"transit_times file {str(path)!r} has no rows of planet {name!r} (its planet "
                                 "column names the planet of each time)")
        if "epoch" not in cols or "tc" not in cols:
            raise ValueError(f"transit_times file {str(path)!r} needs columns epoch and tc (and optionally "
                             f"tc_err), got {table.colnames}")
        from ..inference._times_report import days_column, epoch_column

        return {"transit_times": days_column(table, cols["tc"], path),
                "transit_epochs": epoch_column(table, cols["epoch"], path).tolist()}
    if not (isinstance(tt, list) and tt and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in tt)):
        raise ValueError(f"transit_times must be a non-empty list of mid-times [d] or a file path, got {tt!r}")
    ep = p.get("transit_epochs")
    if ep is not None and not (isinstance(ep, list) and all(isinstance(v, int) and not isinstance(v, bool)
                                                             for v in ep)):
        raise ValueError(f"transit_epochs must be a list of integers (0: the transit at t0), got {ep!r}")
    return {"transit_times": [float(v) for v in tt], "transit_epochs": ep}


def planet_ttv_dict(pl) -> dict:
    """The transit times of a Planet as config values ({} without them)."""
    if pl.transit_times is None:
        return {}
    return {"transit_times": np.asarray(pl.transit_times).tolist(), "transit_epochs": list(pl.transit_epochs)}


def ttv_digest(system) -> dict:
    """What the transit times add to a scan's digest: their values (a file's
    content, not its path); {} for linear ephemerides, so that the digests
    of those scans do not change."""
    ttv = {pl.name: np.asarray(pl.transit_times).tolist() for pl in system.planets if pl.transit_times is not None}
    return {"transit_times": ttv} if ttv else {}


def ttv_settings(section, system, base) -> dict:
    """The checked [ttv] section (``jaxppo ttv``), as keywords of
    ``jaxppo.measure_transit_times`` plus ``reference``: ``planets`` (names; default all), ``free`` (parameters
    fitted with the times), ``search`` [d], ``grid``, ``min_points``,
    ``reference`` (tables of times to compare with: columns planet, epoch,
    tc, tc_err; a file or a list, relative to the config's folder; a list
    of absolute paths here). Raises ValueError naming the key."""
    if not isinstance(section, dict):
        raise ValueError("must be a table (a [ttv] section)")
    bad = sorted(set(section) - set(TTV_KEYS))
    if bad:
        raise ValueError(f"unknown key(s) {bad}; valid: {list(TTV_KEYS)}")
    out = {}
    names = [pl.name for pl in system.planets]
    if "planets" in section:
        pl = section["planets"]
        if not (isinstance(pl, list) and pl and all(isinstance(v, str) for v in pl)):
            raise ValueError(f"planets must be a list of planet names, got {pl!r}")
        unknown = [v for v in pl if v not in names]
        if unknown:
            raise ValueError(f"planets: no planet {unknown[0]!r}; the planets are {names}")
        if len(set(pl)) != len(pl):
            raise ValueError(f"planets: {pl!r} names a planet twice")
        out["planets"] = list(pl)
    if "free" in section:
        free = section["free"]
        if not (isinstance(free, list) and all(isinstance(v, str) for v in free)):
            raise ValueError(f"free must be a list of parameter names such as \"b.radius\", got {free!r}")
        from ..inference._params import parameter_names

        valid = parameter_names(system)
        unknown = [v for v in free if v not in valid]
        if unknown:
            raise ValueError(f"free: unknown parameter(s) {unknown}; valid: {valid}")
        measured = out.get("planets", names)
        clash = [v for v in free if ".tc[" in v or (v.endswith(".t0") and v.split(".")[0] in measured)]
        if clash:
            raise ValueError(f"free: {clash} are measured by jaxppo ttv (every transit time of the measured planets "
                             "is free; their t0 is then degenerate with them); name the other parameters only")
        out["free"] = tuple(free)
    if "search" in section:
        v = section["search"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
            raise ValueError(f"search must be a positive half-width [d], got {v!r}")
        out["search"] = float(v)
    for key, low in (("grid", 3), ("min_points", 1)):
        if key in section:
            v = section[key]
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ValueError(f"{key} must be an integer >= {low}, got {v!r}")
            out[key] = v
    refs = section.get("reference", [])
    refs = [refs] if isinstance(refs, str) else refs
    if not (isinstance(refs, list) and all(isinstance(v, str) for v in refs)):
        raise ValueError(f"reference must be a file name or a list of them, got {section['reference']!r}")
    out["reference"] = []
    for ref in refs:
        path = Path(ref) if Path(ref).is_absolute() else Path(base) / ref
        if not path.is_file():
            raise ValueError(f"reference file {str(path)!r} not found (relative paths are relative to the "
                             "config's folder)")
        out["reference"].append(str(path))
    return out
