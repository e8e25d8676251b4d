"""Jitted occultation terms over batches of frames: the union integral of
whole frames, one-disk terms (general and midpoint rules) and lenses of
crossing pairs. ``jaxppo.model._plan`` decides which frames take which."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array

from ._programs import stored
from ._star import Star
from ..core.centre import centre_split
from ..core.occult import disk_deficit, inner_disk_deficit, lens_deficit, lens_rho, union_deficit

@stored(static_argnames=("order",))
def exact_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """Flux of each frame by the exact union integral ([frame, disk] centres
    and radii [R*]; ``order`` Gauss-Legendre nodes per arc piece)."""
    g, phi1 = star.radial_kernel()
    inten = star.radial_intensity()
    deficit = jax.vmap(lambda a, b, c: union_deficit(a, b, c, g, phi1, order, inten))(x, y, r)
    return 1.0 - deficit / (2.0 * jnp.pi * phi1)


@stored(static_argnames=("order",))
def separate_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """Frames whose disks do not overlap each other: a sum of one-disk terms."""
    g, phi1 = star.radial_kernel()
    inten = star.radial_intensity()
    d, centre = centre_split(x, y, r, inten)  # right second derivatives at d = 0
    one = jax.vmap(lambda dd, rr: disk_deficit(dd, rr, g, phi1, order, inten))
    deficit = (one(d.reshape(-1), r.reshape(-1)).reshape(d.shape) + centre).sum(-1)
    return 1.0 - deficit / (2.0 * jnp.pi * phi1)


@stored(static_argnames=("order",))
def disk_terms(star: Star, d: Array, p: Array, order: int) -> Array:
    """Relative deficits of single disks (general rule, any position)."""
    g, phi1 = star.radial_kernel()
    inten = star.radial_intensity()
    return jax.vmap(lambda dd, rr: disk_deficit(dd, rr, g, phi1, order, inten))(d, p) / (2.0 * jnp.pi * phi1)


@stored
def inner_disk_terms(star: Star, d: Array, p: Array) -> Array:
    """Relative deficits of single disks well inside the star (midpoint rule)."""
    g, phi1 = star.radial_kernel()
    return inner_disk_deficit(d, p, g) / (2.0 * jnp.pi * phi1)


@stored(static_argnames=("order", "inner"))
def column_terms(star: Star, d: Array, unused: Array, p: Array, order: int, inner: bool) -> Array:
    """One-disk relative deficits of [disk, 1] columns d and p (the frame
    kernels' layout; ``unused`` fills their y slot): the midpoint rule where
    ``inner`` (disks well inside the star), else the general rule."""
    if inner:
        return inner_disk_terms(star, d[:, 0], p[:, 0])
    return disk_terms(star, d[:, 0], p[:, 0], order)


@stored(static_argnames=("order",))
def lens_terms(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """Relative flux of the lens of each crossing pair ([pair, 2] arrays),
    ``order`` Gauss-Legendre nodes per arc."""
    g, phi1 = star.radial_kernel()
    return lens_deficit(x, y, r, g, order) / (2.0 * jnp.pi * phi1)


lens_rho_jit = jax.jit(lens_rho)
