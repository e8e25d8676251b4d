"""One function over a batch, one item after another, in one compiled call.

The joint sampler and its mode search evaluate the transit posterior (or
run a Levenberg-Marquardt solve) for many points at once. ``jax.vmap`` of
those functions was measured slower than a loop (``jax.lax.map``) on CPU:
on the bundled real Kepler-20 windows (6,656 model frames, 2 planets) one
log density took 2.45 ms per point vmapped over 128 points and 1.47-1.65
ms mapped (both cores); 16 Levenberg-Marquardt solves of 40 steps 6.1 s
vmapped and 2.7 s mapped, since a vmapped solve runs every point for as
many steps as the slowest one needs and the batch's arrays leave the
caches. One point at a time also lets a ``jax.lax.cond`` inside branch
(the model's union integral runs only in blocks of frames where disks
meet, ``jaxppo.inference._model.union_frames``): under vmap a cond computes
both branches. ``batch_size`` points go through vmap together
(``jax.lax.map``'s own option)."""

import jax


def mapped(fn, batch_size: int | None = None):
    """``jax.jit`` of ``fn`` mapped over the leading axis of each of its
    positional arguments (``jax.lax.map``, ``batch_size`` at a time)."""

    def run(*xs):
        return jax.lax.map(lambda x: fn(*x), xs, batch_size=batch_size)

    return jax.jit(run)


def mapped_over_devices(fn):
    """``mapped(fn)`` with the batch split over every device of every JAX
    process (one global mesh; ``jax.distributed``): each device maps its
    share of the points, and every process gets the whole result as numpy
    arrays (``jaxppo.model._plan.to_host``), so each holds the same numbers.
    The batch is padded to a multiple of the device count (the last point
    repeated, its results dropped). With one device this is ``mapped(fn)``
    with the result brought to the host."""
    import numpy as np
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    from ..model._plan import to_host

    devices = jax.devices()
    run = mapped(fn)
    if len(devices) == 1:
        return lambda *xs: jax.tree_util.tree_map(np.asarray, run(*xs))
    mesh = Mesh(np.array(devices), ("points",))
    spec = PartitionSpec("points")
    # check_vma=False: the kernels close over constants (quadrature nodes,
    # limb-darkening tables) that JAX's varying-axes check rejects beside
    # the per-point values ("Primitive sub requires varying manual axes to
    # match"); each device maps its own points, nothing crosses devices
    each = jax.jit(jax.shard_map(lambda *xs: jax.lax.map(lambda x: fn(*x), xs), mesh=mesh, in_specs=spec,
                                 out_specs=spec, check_vma=False))
    place = NamedSharding(mesh, spec)

    def call(*xs):
        xs = [np.asarray(x) for x in xs]
        n = xs[0].shape[0]
        pad = -n % len(devices)
        if pad:
            xs = [np.concatenate([x, np.repeat(x[-1:], pad, axis=0)]) for x in xs]
        out = each(*(jax.device_put(x, place) for x in xs))
        return jax.tree_util.tree_map(lambda v: to_host(v)[:n], out)

    return call
