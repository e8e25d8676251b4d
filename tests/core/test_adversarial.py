"""Adversarial and property checks of the exact engine (issue 16).

Seeded generators (tests/helpers.py ``adversarial_classes``) of scenes of up
to three disks in the classes where methods fail: tangencies (exact and
1e-15 off), three circles through a point, crossings on the limb,
concentric, identical, disks matching or covering the star, tiny and huge
radii, far disks, and random scenes. Every law (quadratic, non-linear,
power-2, tabulated) in float64 and float32:

* values of "exact" and "auto" against the independent radial reference
  (tests/helpers.py ``reference_deficit``, with a numpy profile written from
  the coefficients): <= 1e-10 in float64, <= 3e-6 in
  float32 except where float32 cannot represent the scene (measured
  9e-12 and 5.5e-7, benchmarks/adversarial_table.py);
* gradients finite (both dtypes) and, in float64, equal to the mean of the
  one-sided finite differences within their spread (so equal to them where
  the flux is smooth).

The table of the closing note (more scenes per class) is
``python benchmarks/adversarial_table.py``.
"""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from helpers import KEPLER20_P100, adversarial_classes, numpy_intensity, pad_scenes, reference_deficit, reference_total


def _stars():
    mu = np.sort(np.concatenate([[0.0], np.cos(np.linspace(0, np.pi / 2, 78))[:-1]]))
    mu[-1] = 1.0
    return {
        "quadratic": jp.Star.quadratic(0.4, 0.25),
        "nonlinear": jp.Star.nonlinear(*KEPLER20_P100),
        "power2": jp.Star.power2(0.7178, 0.7764),
        "tabulated": jp.Star.tabulated(mu, np.asarray(jp.Star.power2(0.7178, 0.7764).intensity(mu))),
    }


STARS = _stars()
SEEDS = {law: 10 * i for i, law in enumerate(STARS)}  # fixed (hash() of a str is salted per process)
SCENES_PER_CLASS = 4
TOL64 = 1e-10


def _as32(star):
    return jax.tree_util.tree_map(lambda v: v.astype(jnp.float32) if hasattr(v, "astype") else v, star)


def _reference(star, cfgs):
    inten = numpy_intensity(star)
    ir = lambda r: inten(np.sqrt(max(1.0 - r * r, 0.0)))  # noqa: E731
    f0 = reference_total(ir)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.array([1.0 - reference_deficit(ir, *c) / f0 for c in cfgs])


def _scenes(seed):
    classes = adversarial_classes(np.random.default_rng(seed), SCENES_PER_CLASS)
    names = [name for name, cfgs in classes.items() for _ in cfgs]
    cfgs = [c for cl in classes.values() for c in cl]
    return np.array(names), cfgs


def float32_representable(cfgs):
    """Scenes float32 can carry: radii <= 100 (a disk's distance is rounded
    to ~6e-8 d, which moves a huge disk's edge) and no tiny disks (a 1e-6
    disk's flux is below float32's resolution of 1)."""
    keep = []
    for x, y, r in cfgs:
        r = np.asarray(r)
        keep.append(bool(np.all(r <= 100.0) and np.all((r == 0) | (r >= 1e-3))))
    return np.array(keep)


@pytest.mark.parametrize("law", list(STARS))
def test_values_against_reference(law):
    star = STARS[law]
    names, cfgs = _scenes(SEEDS[law])
    x, y, r = pad_scenes(cfgs)
    ref = _reference(star, cfgs)
    for method in ("exact", "auto"):
        got = np.asarray(jp.occultation_flux(star, x, y, r, method=method))
        err = np.abs(got - ref)
        worst = int(np.argmax(err))
        assert err[worst] <= TOL64, (method, names[worst], cfgs[worst], err[worst])
    # float32: inputs rounded to float32 are the scene; the reference is
    # computed for those rounded numbers
    keep = float32_representable(cfgs)
    x32, y32, r32 = (v[keep].astype(np.float32) for v in (x, y, r))
    cfgs32 = [tuple(list(np.asarray(v, np.float32).astype(float)) for v in c) for c, k in zip(cfgs, keep) if k]
    ref32 = _reference(star, cfgs32)
    for method in ("exact", "auto"):
        got = np.asarray(jp.occultation_flux(_as32(star), x32, y32, r32, method=method))
        assert got.dtype == np.float32 and np.all(np.isfinite(got))
        err = np.abs(got.astype(float) - ref32)
        worst = int(np.argmax(err))
        assert err[worst] <= 3e-6, (method, names[keep][worst], cfgs32[worst], err[worst])


def _fd_step(r):
    """A finite-difference step well below the smallest disk."""
    pos = np.where(r > 0, r, np.inf).min(axis=1)
    return np.clip(0.01 * pos, 1e-9, 1e-6)


@pytest.mark.parametrize("method", ["exact", "auto"])
@pytest.mark.parametrize("law", list(STARS))
def test_gradients_finite_and_between_one_sided_differences(law, method):
    """Under jit, "auto" plans on the device (lens, midpoint, general and
    union rules): its gradients are checked as "exact"'s."""
    star = STARS[law]
    names, cfgs = _scenes(SEEDS[law] + 1)
    x, y, r = (jnp.asarray(v) for v in pad_scenes(cfgs))
    flux = jax.jit(lambda x, y, r: jp.occultation_flux(star, x, y, r, method=method))
    grads = jax.jit(jax.grad(lambda x, y, r: jnp.sum(flux(x, y, r)), argnums=(0, 1, 2)))(x, y, r)
    h = _fd_step(np.asarray(r))
    scale = np.max(np.abs(np.concatenate([np.asarray(x), np.asarray(y), np.asarray(r)], 1)), axis=1).clip(1.0)
    f0 = np.asarray(flux(x, y, r))
    for arg, g in enumerate(grads):
        g = np.asarray(g)
        assert np.all(np.isfinite(g)), (arg, names[~np.all(np.isfinite(g), axis=1)])
        for k in range(x.shape[1]):
            present = np.asarray(r)[:, k] > 0
            args = [x, y, r]
            step = jnp.zeros_like(x).at[:, k].set(jnp.asarray(h))
            base = args[arg]
            args[arg] = base + step
            fp = np.asarray(flux(*args))
            hp = np.asarray(args[arg] - base)[:, k]  # the step as rounded
            args[arg] = base - step
            fm = np.asarray(flux(*args))
            hm = np.asarray(base - args[arg])[:, k]
            plus, minus = (fp - f0) / hp, (f0 - fm) / hm
            # Where the flux is smooth the one-sided differences agree to
            # f'' h and the gradient is their mean; at a tangency or a kink of
            # f'' they differ, and the gradient must lie within their spread.
            # Slack: rounding of the values (~1e-15, and ~1e-16 R for a disk of
            # radius or distance R, whose position is rounded), second order (h), and
            # the gradient's own quadrature (1e-6 relative).
            tol = np.abs(plus - minus) + 4e-15 * scale / h + h + 1e-6 * np.abs(g[:, k])
            bad = present & (np.abs(g[:, k] - 0.5 * (plus + minus)) > tol)
            assert not np.any(bad), [
                (names[i], cfgs[i], ("x", "y", "r")[arg], k, g[i, k], minus[i], plus[i]) for i in np.nonzero(bad)[0][:3]
            ]


@pytest.mark.parametrize("law", ["quadratic", "tabulated"])
def test_float32_gradients_finite(law):
    star = _as32(STARS[law])
    names, cfgs = _scenes(7)
    keep = float32_representable(cfgs)
    x, y, r = (jnp.asarray(v[keep], jnp.float32) for v in pad_scenes(cfgs))
    grads = jax.jit(jax.grad(lambda x, y, r: jnp.sum(jp.occultation_flux(star, x, y, r, method="exact")), argnums=(0, 1, 2)))(x, y, r)
    for g in grads:
        assert g.dtype == jnp.float32
        assert np.all(np.isfinite(np.asarray(g))), names[keep][~np.all(np.isfinite(np.asarray(g)), axis=1)]
