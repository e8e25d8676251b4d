"""Units at the API's edge: astropy Quantities, TimeDeltas and refused
types turned into the plain numbers (days, degrees, stellar radii, solar
masses and radii) the model computes in, with errors that name the
parameter."""

from __future__ import annotations

import numpy as np

__all__ = ["from_quantity"]


def _is_quantity(value) -> bool:
    # astropy Quantities (and Time) carry a unit; plain numbers and jax arrays do not
    return hasattr(value, "unit") and hasattr(value, "to")


_WANT = {"deg": "an angle", "d": "a time", "": "dimensionless (a plain number; lengths in stellar radii)", "M_sun": "a mass [M_sun]",
         "R_sun": "a length [R_sun]"}


# parameters that are lengths in stellar radii (the others given as "" are pure numbers)
_LENGTHS = {"a", "radius", "x", "y", "r"}


def _is_time_class(value, name: str) -> bool:
    # astropy.time classes by name, so that plain inputs need no astropy import
    return any(c.__name__ == name for c in type(value).__mro__)


def from_quantity(name: str, value, unit: str):
    """Convert an astropy Quantity to the plain number the API expects:
    ``unit`` "deg" (angles), "d" (times) or "" (dimensionless ratios).
    Plain numbers pass unchanged (their units are the documented ones). For
    times, an astropy ``TimeDelta`` is converted to days; an absolute
    astropy ``Time`` is refused: it has no day count of its own, and
    the zero point of the planets' t0 is the caller's to choose."""
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise ValueError(f"{name} must be {_WANT[unit]}, got {type(value).__name__} {value!r}")
    if np.ma.isMaskedArray(value) or (hasattr(value, "unmasked") and hasattr(value, "mask")):
        # a masked entry has no value to compute with: refused, never used
        if np.any(np.asarray(value.mask)):
            raise ValueError(f"{name} holds {int(np.sum(np.asarray(value.mask)))} masked (missing) values; drop or "
                             "fill them (LightCurve.from_arrays drops masked points and reports them)")
        value = value.unmasked if hasattr(value, "unmasked") else np.ma.getdata(value)
    if isinstance(value, (list, tuple)) and any(_is_quantity(v) or _is_time_class(v, "TimeDelta")
                                                or _is_time_class(v, "Time") for v in value):
        # a list of Quantities: each converted (a bare TypeError from astropy otherwise)
        return np.asarray([from_quantity(name, v, unit) for v in value], float)
    if isinstance(value, (list, tuple, np.ndarray)) and np.asarray(value).dtype.kind in "bUS":
        raise ValueError(f"{name} must be {_WANT[unit]}, got an array of {np.asarray(value).dtype} "
                         f"({np.asarray(value).ravel()[:3].tolist()}...)")
    if _is_time_class(value, "Time"):
        raise ValueError(
            f"{name} must be a number of days, a time Quantity or a TimeDelta, got an absolute astropy Time "
            f"({value!r}); pass the days since the zero point of the planets' t0, e.g. t.jd - 2454833.0 "
            "(BKJD), or the TimeDelta t - Time(2454833.0, format='jd')"
        )
    if _is_time_class(value, "TimeDelta"):
        if unit != "d":
            raise ValueError(f"{name} must be {_WANT[unit]}, got the TimeDelta {value!r}")
        import astropy.units as u

        return np.asarray(value.to_value(u.day), float)
    if not _is_quantity(value):
        return value
    import astropy.units as u

    target = {"deg": u.deg, "d": u.day, "": u.dimensionless_unscaled, "M_sun": u.M_sun, "R_sun": u.R_sun}[unit]
    try:
        return np.asarray(value.to_value(target), float)
    except u.UnitConversionError:
        pass
    if unit == "" and value.unit.physical_type == "length":
        want = ("in stellar radii (a plain number or a dimensionless Quantity)" if name in _LENGTHS else
                "dimensionless (a plain number or a dimensionless Quantity; lengths in stellar radii)")
        raise ValueError(
            f"{name} must be {want}, got {value!r}: "
            f"a length is ambiguous without the star's radius; pass ({name} / R_star).decompose()"
        )
    raise ValueError(f"{name} must be {_WANT[unit]}, got the Quantity {value!r}")
