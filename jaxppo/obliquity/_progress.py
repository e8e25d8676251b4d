"""Results written as they go: atomic file writes and the checksummed JSON
lines of progress files, shared by the scan and the marginal scan. A run that
is interrupted resumes from the complete, valid records; a record of another
configuration is refused, an edited one recomputed."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from ..model._processes import is_writer

__all__ = ["progress_header", "atomic_write", "record_line", "read_progress"]


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a fsynced temporary file and a rename:
    the file is either the old one or the whole new one. Under several JAX
    processes only process 0 writes (``jaxppo.model._processes``)."""
    if not is_writer():
        return
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def record_line(rec: dict) -> str:
    """One progress record as a JSON line with its checksum: sha256 of the
    canonical JSON of the other fields (floats written exactly by repr)."""
    return json.dumps(dict(rec, sha256=_checksum(rec)), allow_nan=False) + "\n"


def _checksum(rec: dict) -> str:
    body = json.dumps({k: v for k, v in rec.items() if k != "sha256"}, sort_keys=True, allow_nan=False)
    return hashlib.sha256(body.encode()).hexdigest()[:20]


def read_progress(path: Path, digest: str, out: Path, source: str, settings: dict | None = None, explain=None):
    """Finished (case, alpha) -> chi^2 from the progress file, and notes on
    what was not usable. Only complete lines count (a line cut by an
    interruption is dropped); each record must carry this config's digest and
    a valid checksum (an edited record is recomputed, with a note). The file
    is then rewritten atomically with the good records only, so the next
    append never lands on a torn line. ``settings`` (the marginal scan's):
    kept in the header, and a header of other settings is refused naming
    the ones that differ. ``explain``: a callable giving what differs from
    the configuration ``out`` holds (added to the refusal)."""
    done, notes, keep = {}, [], []
    if not path.exists():
        return done, notes
    raw = path.read_bytes()
    text = raw.decode("utf-8", errors="replace")
    lines = text.split("\n")
    if lines and lines[-1] != "":
        notes.append(f"{path.name}: the last line was cut by an interruption; dropped (recomputed)")
    lines = [ln for ln in lines[:-1]]
    head, first_is_record = None, False
    if lines:
        try:
            first = json.loads(lines[0])
        except json.JSONDecodeError:
            first = None
        first_is_record = isinstance(first, dict) and "case" in first
        if isinstance(first, dict) and "config_digest" in first and not first_is_record:
            head = first
    body = lines if first_is_record else lines[1:]
    if head is None and lines:
        notes.append(f"{path.name}: the header line is damaged; rewritten (records are checked one by one)")
    elif head is not None and head.get("config_digest") != digest:
        _refuse_other_settings(out, head.get("settings"), settings)
        raise ValueError(
            f"{out} holds results of a different configuration (digest {head.get('config_digest')}, now {digest}"
            f"{'; ' + explain() if explain else ''}); use another --out folder or --restart to discard them"
        )
    foreign = set()
    for n, line in enumerate(body, start=1 if first_is_record else 2):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            ok = isinstance(rec, dict) and {"case", "alpha", "chi2"} <= set(rec)
        except json.JSONDecodeError:
            ok = False
        if not ok:
            notes.append(f"{path.name} line {n}: not a progress record; recomputed")
            continue
        if rec.get("config_digest") not in (None, digest):
            foreign.add(rec.get("config_digest"))
            continue
        if rec.get("sha256") != _checksum(rec) or rec.get("config_digest") != digest:
            notes.append(f"{path.name} line {n}: checksum mismatch (record edited or from an older version); "
                         f"its {len(rec.get('alpha', []))} alphas are recomputed")
            continue
        for a, c2 in zip(rec["alpha"], rec["chi2"]):
            done[(rec["case"], round(float(a), 9))] = float(c2)
        keep.append(line + "\n")
    if foreign:
        raise ValueError(
            f"{out} holds results of a different configuration (digest {sorted(foreign)[0]}, now {digest}"
            f"{'; ' + explain() if explain else ''}); use another --out folder or --restart to discard them"
        )
    atomic_write(path, progress_header(digest, source, settings) + "".join(keep))
    return done, notes


def progress_header(digest: str, source: str, settings: dict | None = None) -> str:
    """The first line of a progress file: the digest of what its records
    belong to, the config's source and (marginal scan) its settings."""
    head = {"config_digest": digest, "source": source, "format": 2}
    if settings is not None:
        head["settings"] = settings
    return json.dumps(head, default=str) + "\n"


def _refuse_other_settings(out: Path, before, now) -> None:
    """ValueError naming the marginal scan's settings that differ from the
    run whose progress ``out`` holds (nothing when either is unknown or the
    settings agree: then the scan's config differs)."""
    if not isinstance(before, dict) or now is None:
        return
    now = json.loads(json.dumps(now, default=str))
    if before.get("scan_config_digest") != now.get("scan_config_digest"):
        return  # another config: the plain refusal
    differ = [f"{k} {before.get(k)!r} -> {now.get(k)!r}" for k in sorted(set(before) | set(now))
              if before.get(k) != now.get(k)]
    if differ:
        raise ValueError(
            f"{out} holds a marginal scan of the same config with other marginal settings ({'; '.join(differ)}): "
            "draws are not added to an earlier run's (they are a thinned chain of its own length and seed). "
            "Use another --out folder for the new settings, or --restart to discard the earlier draws "
            "(the fixed scan in the folder is computed again too)")
