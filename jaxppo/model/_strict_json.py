"""Strict JSON for every file jaxppo writes: numbers as plain Python
numbers, and every NaN or infinity as null (``json.dumps(...,
allow_nan=False)`` then never meets one)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["strict_jsonable"]


def strict_jsonable(obj):
    """``obj`` with dict keys as text, tuples and arrays as lists, numpy
    booleans, integers and floats as Python ones, and every non-finite
    float as None (strict JSON: a failed fit's error is NaN)."""
    if isinstance(obj, dict):
        return {str(k): strict_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return strict_jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj
