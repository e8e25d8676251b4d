"""Transit times in a scan config: ``transit_times`` / ``transit_epochs``
of a [[planet]] table (docs/config.md), inline lists or a CSV/ECSV file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["transit_times_from", "planet_ttv_dict", "ttv_digest"]


def transit_times_from(p: dict, base) -> dict:
    """``transit_times`` / ``transit_epochs`` of a [[planet]] table as
    Planet keywords ({} without them): inline lists, or
    ``transit_times = "file"`` (CSV, or ECSV by its suffix; relative to the
    config's folder ``base``) with columns epoch and tc [d] (tc_err may be
    there; the model does not use it). Raises ValueError naming the key."""
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
        if "epoch" not in cols or "tc" not in cols:
            raise ValueError(f"transit_times file {str(path)!r} needs columns epoch and tc (and optionally "
                             f"tc_err), got {table.colnames}")
        return {"transit_times": np.asarray(table[cols["tc"]], float),
                "transit_epochs": np.asarray(table[cols["epoch"]]).tolist()}
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
