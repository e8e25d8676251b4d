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
