"""occultation_flux: relative flux of a star behind any number of disks."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._star import Star
from ._plan import is_concrete, run_padded, auto_frames, traced_auto_frames
from ._terms import exact_frames
from ._units import from_quantity
from ..core.geometry import float_dtype
from ..core.occult import MAX_RADIUS

__all__ = ["occultation_flux", "METHODS"]

METHODS = ("auto", "exact", "raster")


_WARNED = {"float32": False}  # (a dict: module-level values stay put for the program store)
FLOAT32_MESSAGE = (
    "jaxppo: float32: JAX's float64 is off (jax_enable_x64 is False), so every flux is computed in float32. "
    "The flux kernel alone then errs by ~1e-7, but float32 times and positions put a light curve off by up to "
    "~20 ppm (Kepler-20 near a planet-planet occultation; docs/methods.md). For science, call "
    "jax.config.update('jax_enable_x64', True) at startup; to keep float32 deliberately, silence this with "
    "warnings.filterwarnings('ignore', message='jaxppo: float32')."
)


def _warn_float32_once() -> None:
    """The float32 policy (docs/methods.md): the library never flips JAX's
    global x64 switch, but a user cannot miss that it is off."""
    if not _WARNED["float32"] and not jax.config.jax_enable_x64:
        _WARNED["float32"] = True
        import warnings

        warnings.warn(FLOAT32_MESSAGE, UserWarning, stacklevel=3)


@functools.lru_cache(maxsize=None)
def device_auto(order: int):
    """The "auto" rule for traced inputs at ``order`` Gauss-Legendre nodes:
    ``f(star, x, y, r)`` on [frame, disk] arrays -> [frame] relative flux.

    Unbatched (inside ``jit``/``grad``) it runs the device plan,
    ``traced_auto_frames``. Batched by ``vmap`` (the choice is made by
    JAX's public ``jax.custom_batching.custom_vmap``, whatever the nesting
    of ``jit`` and ``vmap``) it takes the union integral instead: a batched
    plan turns its per-block switches into selects that run every rule on
    every frame (2.3x the union integral, measured). Derivatives are those
    of the device plan (``custom_vmap`` alone has no reverse mode, hence the
    ``custom_jvp`` around it); a derivative under ``vmap`` runs the batched
    plan (correct, not faster)."""

    def plan(star, x, y, r):
        return traced_auto_frames(star, x, y, r, order)

    @jax.custom_batching.custom_vmap
    def unbatched(star, x, y, r):
        return plan(star, x, y, r)

    @unbatched.def_vmap
    def batched(axis_size, in_batched, star, x, y, r):
        del axis_size
        axes = jax.tree_util.tree_map(lambda b: 0 if b else None, in_batched)
        union = jax.vmap(lambda s, a, b, c: exact_frames(s, a, b, c, order), in_axes=axes)
        return union(star, x, y, r), True

    @jax.custom_jvp
    def auto(star, x, y, r):
        return unbatched(star, x, y, r)

    @auto.defjvp
    def auto_jvp(primals, tangents):
        return jax.jvp(plan, primals, tangents)

    return auto


def _prepare(x, y, r):
    # stellar radii: a dimensionless Quantity converts, a length (ambiguous
    # without the star's radius), a string or a bool is refused by name
    x, y, r = (from_quantity(name, v, "") for name, v in (("x", x), ("y", y), ("r", r)))
    try:
        x, y, r = jnp.broadcast_arrays(jnp.asarray(x), jnp.asarray(y), jnp.asarray(r))
    except ValueError as err:
        raise ValueError(
            f"x, y and r must broadcast together, got shapes {jnp.shape(x)}, {jnp.shape(y)}, {jnp.shape(r)}"
        ) from err
    if x.ndim == 0:
        x, y, r = x[None], y[None], r[None]
    dtype = float_dtype(x, y, r)
    return x.astype(dtype), y.astype(dtype), r.astype(dtype)


def _validate_concrete(x, y, r) -> None:
    for name, v in (("x", x), ("y", y), ("r", r)):
        arr = np.asarray(v)
        if not np.all(np.isfinite(arr)):
            bad = arr[~np.isfinite(arr)].ravel()[0]
            raise ValueError(f"{name} must be finite, found {bad}")
    rr = np.asarray(r)
    if np.any(rr < 0):
        raise ValueError(f"r (disk radius) must be >= 0, found {rr[rr < 0].ravel()[0]}")
    if np.any(rr > MAX_RADIUS):
        raise ValueError(
            f"r (disk radius) must be <= {MAX_RADIUS:g} stellar radii (beyond it the rounding of the disk's "
            f"distance alone exceeds 1e-10 of the flux), found {rr[rr > MAX_RADIUS].ravel()[0]}"
        )


def occultation_flux(
    star: Star,
    x: ArrayLike,
    y: ArrayLike,
    r: ArrayLike,
    method: str = "auto",
    order: int = 24,
    chunk: int = 65536,
    raster=None,
    times=None,
) -> Array:
    """Compute the relative flux of a star behind opaque disks.

    The disks (planets) are all in front of the star; any number of them,
    overlapping or not, so planet-planet occultations are modelled exactly.
    The flux is relative to the star's unocculted flux (1: nothing hidden).

    Parameters
    ----------
    star : Star
        The star (any limb-darkening law or table; a star with a surface map
        or spots is modelled by the raster).
    x, y : array_like
        Disk centres [R*], [..., n_disks]: the last axis indexes the disks,
        leading axes (frames) broadcast. A scalar is one frame of one disk.
    r : array_like
        Disk radii [R*], >= 0 and <= ``MAX_RADIUS`` (1e6), broadcast against
        ``x`` and ``y``; a disk of radius 0 is absent.
    method : {"auto", "exact", "raster"}, optional
        ``"exact"`` integrates the union of the disks exactly (Green's
        theorem, ``jaxppo.core.occult``); ``"auto"`` (default) models no
        more than each frame needs: frames with no disk on the star cost
        nothing; disks off the star or inside another disk are dropped;
        where each disk crosses at most one other, the flux is the sum of
        one-disk terms minus the lens of each crossing pair (a midpoint
        rule for disks well inside the star, Gauss-Legendre on lenses
        where ``lens_rho`` says it converges); only the remaining frames
        (three disks meeting, lenses at the limb) run the union integral.
        Its error is the same as ``"exact"``'s (both ~4e-12 at worst,
        measured). Piecewise-table stars take the union integral for every
        overlap. Under ``jit``/``grad``/``vmap`` (traced inputs) the same
        plan runs on the device (``jaxppo.model._plan.traced_auto_frames``):
        each rule on the frames that need it, at the host plan's numbers,
        gradients by shape derivatives. Under ``vmap`` (with or without
        ``jit``, either nesting) it takes the union integral (a batched
        plan would run every rule on every frame; ``device_auto``);
        better, broadcast leading axes instead of vmapping.
        ``"raster"`` is the pixel-grid method (``RasterSettings``).
    order : int, optional
        Gauss-Legendre nodes per arc piece (default 24: worst measured error
        ~1e-11 in float64 over adversarial scenes; 20 is ~5e-11).
    chunk : int, optional
        Frames per compiled batch (bounds memory; default 65536).
    raster : RasterSettings, optional
        Settings for ``method="raster"`` (default: windowed, exact pixel
        coverage, each disk's own pixels: its visible part / 32, i.e.
        r / 16; accuracy in ``RasterSettings``).
    times : array_like, optional
        Time [d] of each frame (broadcast against the leading axes), needed
        only by a star with rotating spots (``Star.with_spots``);
        ``System.flux`` passes its t.

    Returns
    -------
    flux : jax.Array
        Relative flux, shape = the broadcast leading axes (1 per frame when
        the disk axis is empty; an empty array when there are no frames).

    Raises
    ------
    ValueError
        When ``method`` is unknown, ``star`` is not a ``Star``,
        ``order`` or ``chunk`` is not a positive integer, ``x``, ``y``, ``r``
        do not broadcast, a concrete value is not finite or a concrete
        radius is negative or above ``MAX_RADIUS`` (the message names x, y
        or r), ``method="exact"`` is asked of a star with a surface map, or
        (raster) a spotted star has no ``times`` or the settings exceed the
        memory cap.

    Warns
    -----
    UserWarning
        Once per process, when JAX's float64 is off (float32 policy below).

    Notes
    -----
    float32: when JAX's x64 is off every input is float32; the first call
    in a process then warns once (docs/methods.md, float32 policy). With x64
    on, float32 inputs (explicitly float32 arrays and star) run in float32.

    Bad input under ``jit``/``grad``/``vmap`` (traced input): a frame with a
    non-finite value, a negative radius or one above ``MAX_RADIUS`` has a
    NaN flux (and gradient), never a finite plausible value, so that an
    optimiser or sampler sees it; the exact and union methods do this per
    frame, so one bad frame does not poison a batch.

    Examples
    --------
    Three frames of one disk on a limb-darkened star (centre, halfway, off
    the star), then one frame of two overlapping disks: the overlap is
    hidden once.

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> star = jp.Star.quadratic(0.4, 0.25)
    >>> x = np.array([[0.0], [0.5], [2.0]])  # [frame, disk]
    >>> f = jp.occultation_flux(star, x, 0.0, 0.1)
    >>> f.shape
    (3,)
    >>> print(np.round(np.asarray(f), 6))
    [0.987891 0.988604 1.      ]
    >>> print(f"{float(jp.occultation_flux(star, [0.0, 0.15], 0.0, [0.1, 0.1])):.6f}")
    0.977584
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    _warn_float32_once()
    if not isinstance(star, Star):
        raise ValueError(f"star must be a jaxppo.Star, got {type(star).__name__}")
    for name, value in (("order", order), ("chunk", chunk)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return _dispatch(star, *_prepare(x, y, r), method, order, chunk, raster, times)


def _dispatch(star: Star, x: Array, y: Array, r: Array, method: str, order: int, chunk: int, raster, times) -> Array:
    """``occultation_flux`` on checked arguments and broadcast [..., disk]
    arrays: the method for these inputs (concrete or traced, batched or not)."""
    lead = x.shape[:-1]
    k = x.shape[-1]
    if k == 0 or x.size == 0:
        # no disks: the star unocculted; no frames: nothing to compute
        if is_concrete(x, y, r):
            _validate_concrete(x, y, r)
        return jnp.ones(lead, x.dtype)
    if not star.symmetric:
        if method == "exact":
            raise ValueError(
                "method='exact' needs a radially symmetric star; this star has a surface map: use method='raster'"
            )
        method = "raster"
    if is_concrete(x, y, r):
        # every method checks concrete input the same way (the raster too:
        # a NaN position or a negative radius gave it a plausible flux)
        _validate_concrete(x, y, r)
    if method == "raster":
        from ._raster import raster_flux

        return raster_flux(star, x, y, r, raster, times=times)
    concrete = is_concrete(x, y, r, *jax.tree_util.tree_leaves(star))
    xf, yf, rf = (v.reshape(-1, k) for v in (x, y, r))
    if method == "exact":
        if concrete:
            return jnp.asarray(run_padded(exact_frames, star, xf, yf, rf, order, chunk).reshape(lead))
        return exact_frames(star, xf, yf, rf, order).reshape(lead)
    if not concrete:
        return device_auto(order)(star, xf, yf, rf).reshape(lead)
    xf, yf, rf = (np.asarray(v) for v in (xf, yf, rf))
    return jnp.asarray(auto_frames(star, xf, yf, rf, order, chunk).reshape(lead))
