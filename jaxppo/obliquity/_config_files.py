"""The files a scan config reads: the star's profile (a table or a PHOENIX
file; its content is part of a scan's digest) and the list of every input
file, which no output may overwrite."""

from __future__ import annotations

import hashlib
import tomllib
from pathlib import Path

import numpy as np

from ..model._phoenix import data_path, phoenix_star
from ..model._processes import is_writer, read_once
from ..model._star import Star

__all__ = ["default_config_path", "config_inputs", "refuse_overwriting_inputs", "star_file_digest", "star_from_table", "star_table",
           "out_folder", "out_file", "finished_scan"]


def default_config_path() -> Path:
    """The bundled default scan: real Kepler-20 long-cadence data."""
    return data_path("kepler20_real_llc.toml")


def star_from_table(section: dict, law: str, base: Path) -> Star:
    """The star of a ``[star]`` section with ``law`` "phoenix" (``path``: a
    PHOENIX SPECINT FITS file) or "tabulated" (``mu`` and ``intensity``, or
    ``path``: a table file; ``interpolation``, ``pad_ends``); relative
    paths start at ``base``. ValueError naming the key and the file."""
    if law == "phoenix":
        if "path" not in section:
            raise ValueError("[star] law = 'phoenix' needs path = a PHOENIX SPECINT FITS file")
        p = base / section["path"]
        try:
            return phoenix_star(p, limb=section.get("limb", "rescale"))
        except (OSError, ValueError, KeyError, IndexError) as e:
            raise ValueError(f"[star] path = {str(section['path'])!r} ({p}): {e}") from e
    has_arrays, has_path = "mu" in section or "intensity" in section, "path" in section
    if has_arrays and has_path:
        raise ValueError("[star] law = 'tabulated' takes mu = [...] and intensity = [...] or path = 'table.csv', not both")
    try:
        if has_path:
            mu, intensity = star_table(base / section["path"])
        elif "mu" in section and "intensity" in section:
            mu, intensity = section["mu"], section["intensity"]
        else:
            raise ValueError("needs mu = [...] and intensity = [...], or path = 'table.csv'")
        pad = section.get("pad_ends", False)
        if not isinstance(pad, bool):
            raise ValueError(f"pad_ends must be true or false, got {pad!r}")
        return Star.tabulated(mu, intensity, interpolation=section.get("interpolation", "sqrt-poly"), pad_ends=pad)
    except ValueError as e:
        where = f"path = {str(section['path'])!r}" if has_path else "mu, intensity"
        raise ValueError(f"[star] law = 'tabulated' ({where}): {e}") from e


def star_table(p: Path):
    """(mu, intensity) from a CSV table file: the first two columns
    (further ones are not used), separated by commas (or white space), '#' comments, an optional header row (e.g.
    ``mu,intensity``). ValueError naming the file and the row otherwise."""
    if not p.is_file():
        raise ValueError(f"table file not found: {p}")
    rows, header = [], False
    for n, line in enumerate(p.read_text(errors="replace").splitlines(), start=1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        cells = [c.strip() for c in text.split(",")] if "," in text else text.split()
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows and not header:
                header = True  # the one header row, before the numbers
                continue
            raise ValueError(f"{p}, line {n}: {line.strip()!r} is not two numbers (mu, intensity)") from None
        if len(values) < 2:
            raise ValueError(f"{p}, line {n}: {line.strip()!r} has {len(values)} column, not 2 (mu, intensity)")
        rows.append(values[:2])  # further columns (an error, a flag) are not used
    if not rows:
        raise ValueError(f"{p} holds no rows of mu, intensity")
    tab = np.asarray(rows, float)
    return tab[:, 0], tab[:, 1]


def config_inputs(path, raw: dict | None = None) -> set:
    """The files a config reads (resolved): the TOML file itself (None: the
    bundled default), its ``[data] path``, ``[star] path``, the planets'
    ``transit_times`` files and ``[ttv] reference`` tables. ``raw``: the
    parsed TOML (read from ``path`` when None; an unreadable file adds
    nothing, its loading reports it)."""
    path = Path(path) if path is not None else default_config_path()
    base = path.resolve().parent
    if raw is None:
        try:
            raw = tomllib.loads(path.read_text())
        except (OSError, ValueError, UnicodeDecodeError):
            raw = {}
    found = [path]
    for section in ("data", "star"):
        sec = raw.get(section)
        paths = sec.get("path") if isinstance(sec, dict) else None
        found += [v for v in (paths if isinstance(paths, list) else [paths]) if isinstance(v, str)]
    planets = raw.get("planet")
    for pl in planets if isinstance(planets, list) else ():
        if isinstance(pl, dict) and isinstance(pl.get("transit_times"), str):
            found.append(pl["transit_times"])
    ttv = raw.get("ttv")
    refs = ttv.get("reference", []) if isinstance(ttv, dict) else []
    found += [r for r in ([refs] if isinstance(refs, str) else refs if isinstance(refs, list) else []) if isinstance(r, str)]
    return {(base / Path(p).expanduser()).resolve() for p in found}


def refuse_overwriting_inputs(targets, inputs, option: str = "--out") -> None:
    """ValueError when a file about to be written (``targets``) is one the
    run reads (``inputs``, from ``config_inputs``): jaxppo never writes over
    its own inputs (a light curve replaced by a result is lost)."""
    for t in targets:
        if Path(t).resolve() in inputs:
            raise ValueError(f"{option} {t}: that file is an input of this run (the config or a file it reads); "
                             "jaxppo does not write over its inputs: choose another name")


def star_file_digest(section, star) -> dict:
    """What a star read from a file (``[star] path``: a tabulated profile or
    a PHOENIX file) adds to a scan's digest: the hash of the profile it
    holds, so that editing the file is a changed config; {} otherwise (the
    digests of other scans do not change)."""
    if not (isinstance(section, dict) and "path" in section):
        return {}
    import equinox as eqx
    import jax

    leaves = [np.asarray(v) for v in jax.tree_util.tree_leaves(eqx.filter(star, eqx.is_array))]
    return {"star_profile": hashlib.sha256(b"".join(v.tobytes() for v in leaves)).hexdigest()}


def out_folder(path, option="--out") -> Path:
    """An output folder that may be created (its parents too), or a clear
    error when a file stands in the way."""
    out = Path(path)
    for p in (out, *out.parents):
        if p.exists():
            if not p.is_dir():
                raise ValueError(f"{option} {out}: {p} is a file, not a folder")
            break
    return out


def out_file(path, option="--out") -> Path:
    """An output file whose folder exists."""
    out = Path(path)
    if out.is_dir():
        raise ValueError(f"{option} {out} is a folder; give a file name")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ValueError(f"{option} {out}: {parent} is a file, not a folder" if parent.exists() else
                         f"{option} {out}: the folder {parent} does not exist")
    return out


def finished_scan(out) -> tuple:
    """(config, summary, scan table) of the finished scan in ``out``, read
    by process 0 (of several JAX processes; the others may run where that
    folder does not exist): they rebuild them from its files, shared."""
    import tempfile

    from ._config import finished_scan_config
    from ._figures import read_scan_csv

    out = Path(out)
    names = ("config.json", "summary.json", "scan.csv")
    here = []

    def read():  # process 0: its errors (no scan there, a changed config) stop every process
        here.append((*finished_scan_config(out), read_scan_csv(out / "scan.csv")))
        return {n: (out / n).read_text() if (out / n).exists() else None for n in names}

    texts = read_once(read, out)
    if is_writer():
        return here[0]
    with tempfile.TemporaryDirectory(prefix="jaxppo_plot_") as tmp:
        for n, text in texts.items():
            if text is not None:
                (Path(tmp) / n).write_text(text)
        return (*finished_scan_config(tmp), read_scan_csv(Path(tmp) / "scan.csv"))
