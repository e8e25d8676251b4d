"""Disks centred on (or within CENTRED_D of) the star's centre, where the
polar coordinates (d, e) of a centre are singular: the second derivatives
of one-disk terms there (``centre_split``)."""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array

from .geometry import safe_hypot

__all__ = ["CENTRED_D", "centre_split"]


# Distance [R*] of a disk's centre from the star's below which its terms are
# taken from the centre (``centre_split``, ``_union_parts``): there the
# polar coordinates (d, e) lose ~eps / d of the curvature across e, and a
# one-disk deficit's Taylor polynomial f(0) + f''(0) d^2 / 2 errs by
# ~(d / p)^2 of it (~1e-9 and ~1e-10 at 1e-6, estimated; the curvature is
# checked at d = 0, 1e-8, 1e-4 in tests/model/test_centre_hessian.py).
CENTRED_D = 1e-6


def centre_split(x: Array, y: Array, p: Array, intensity: Callable[[Array], Array]) -> tuple[Array, Array]:
    """For a one-disk deficit f(d) (``disk_deficit``, ``inner_disk_deficit``)
    of a disk centred at (x, y): ``(d_in, extra)`` with f(d_in) + extra
    equal to f(d) and right in its first and second derivatives in the
    centre, also at d = 0. Elementwise.

    Through d = hypot(x, y) every second derivative at d = 0 is 0 (the
    guards give d a zero derivative there) and just off it the curvature
    across the centre's direction, f'(d) / d, loses ~eps / d of its digits.
    Within CENTRED_D of the star's centre (a disk of radius p < 1 off the
    limb) f is even and smooth: f(0) + f''(0) (x^2 + y^2) / 2 (error
    ~f''''(0) d^4, below rounding), where the Hessian's trace, the integral
    of I's Laplacian over the disk (divergence theorem), gives
    f''(0) = 2 pi p^2 I'(p^2), I' = dI/d(r^2). So d_in = 0 and
    extra = pi p^2 I'(p^2) (x^2 + y^2) there; d_in = d, extra = 0 elsewhere.
    """
    d = safe_hypot(x, y)
    at = (d < CENTRED_D) & (p > 0) & (p < 1.0 - CENTRED_D)
    s = jnp.where(at, p * p, 0.25)  # a harmless point elsewhere (I' is infinite at the limb)
    _, di = jax.jvp(intensity, (s,), (jnp.ones_like(s),))
    return jnp.where(at, 0.0, d), jnp.where(at, jnp.pi * s * di * (x * x + y * y), 0.0)
