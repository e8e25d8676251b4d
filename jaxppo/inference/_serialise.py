"""Results on disk: strict-JSON floats and a System as plain values."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..model._star import Star
from ..model._planet import Planet
from ..model._system import System

__all__ = ["to_jsonable", "from_jsonable", "system_to_dict", "system_from_dict"]


def to_jsonable(v):
    """Floats (nested lists) for strict JSON: NaN -> None, +-inf -> "inf"/"-inf"."""
    v = np.asarray(v, float) if not isinstance(v, list) else v
    if isinstance(v, list):
        return [to_jsonable(x) for x in v]
    if v.ndim:
        return [to_jsonable(x) for x in v]
    x = float(v)
    return None if np.isnan(x) else ("inf" if x == np.inf else "-inf" if x == -np.inf else x)


def from_jsonable(v):
    """Inverse of ``to_jsonable`` (None -> NaN, "inf" -> inf)."""
    if isinstance(v, list):
        return [from_jsonable(x) for x in v]
    return np.nan if v is None else float(v)


def system_to_dict(system: System) -> dict:
    """A System as plain JSON-ready values (every field of Star and Planet;
    ``system_from_dict`` inverts it exactly)."""
    star = {}
    for f in dataclasses.fields(system.star):
        v = getattr(system.star, f.name)
        if f.name == "surface" and v is not None:
            raise ValueError("a Star built from a tabulated surface object cannot be saved as JSON")
        star[f.name] = v if v is None or isinstance(v, str) else to_jsonable(v)
    planets = []
    for pl in system.planets:
        entry = {}
        for f in dataclasses.fields(pl):
            v = getattr(pl, f.name)
            if f.name == "name":
                entry[f.name] = v
            elif f.name == "transit_epochs":
                entry[f.name] = None if v is None else [int(e) for e in v]
            elif f.name == "moons":
                entry[f.name] = [_moon_to_dict(m) for m in v]
            elif f.name == "a" and system.orbits == "nbody":
                entry[f.name] = None  # derived again on loading
            else:
                entry[f.name] = None if v is None else to_jsonable(v)
        planets.append(entry)
    out = {"star": star, "planets": planets, "tilted": int(system.tilted)}
    if system.orbits == "nbody":
        opts = system.nbody_options()
        out["nbody"] = {k: (None if v is None else list(v) if k == "span" else to_jsonable(v) if k in
                            ("star_mass", "star_radius") else v) for k, v in opts.items() if k != "orbits"}
    return out


def _moon_to_dict(moon) -> dict:
    return {f.name: (getattr(moon, f.name) if f.name == "name" else to_jsonable(getattr(moon, f.name)))
            for f in dataclasses.fields(moon)}


def system_from_dict(d: dict) -> System:
    """The System ``system_to_dict`` wrote."""
    kw = {}
    for f in dataclasses.fields(Star):
        if f.name not in d["star"]:
            continue
        v = d["star"][f.name]
        if f.name in ("law", "interpolation") or v is None:
            kw[f.name] = v
        elif f.name == "degree":
            kw[f.name] = int(v)
        elif f.name == "table_residual":
            kw[f.name] = float(from_jsonable(v))
        else:
            kw[f.name] = jnp.asarray(from_jsonable(v), float)
    star = Star(**kw)
    # name and the epochs as written; transit_times None: a linear ephemeris
    from ..model._moon import Moon

    planets = []
    for p in d["planets"]:
        kw = {k: (v if k in ("name", "transit_epochs", "moons") or v is None else from_jsonable(v))
              for k, v in p.items()}
        kw["moons"] = [Moon(**{k: (v if k == "name" else from_jsonable(v)) for k, v in m.items()})
                       for m in kw.get("moons") or ()]
        planets.append(Planet(**kw))
    nbody = d.get("nbody")
    if nbody:
        nbody = {k: (tuple(v) if k == "span" and v is not None else from_jsonable(v) if k in
                     ("star_mass", "star_radius") else v) for k, v in nbody.items()}
        return System(star, planets, d["tilted"], orbits="nbody", **nbody)
    return System(star, planets, d["tilted"])
