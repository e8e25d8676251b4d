"""``jaxppo.inference._mapped.mapped``: the joint sampler's batches, one
point after another, give what ``jax.vmap`` gives."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo.inference._mapped import mapped


@pytest.mark.parametrize("batch_size", [None, 3])
def test_mapped_equals_vmap_on_the_model(batch_size):
    """The flux of a two-planet system at a batch of tilts and
    radii: mapped (any batch size, a batch not a multiple of it) equals
    vmapped to rounding."""
    system = jp.kepler20_system(radius_scale=2.0)
    t = jnp.linspace(-0.2, 0.2, 301) + float(system.planets[0].t0)

    def flux(alpha, scale):
        b, c = system.planets
        s = system.replace(planets=[b.replace(radius=b.radius * scale), c])
        return s.flux(t, alpha, case="same")

    alphas = jnp.asarray(np.linspace(0.0, 350.0, 10))
    scales = jnp.asarray(np.linspace(0.9, 1.1, 10))
    got = np.asarray(mapped(flux, batch_size)(alphas, scales))
    want = np.asarray(jax.jit(jax.vmap(flux))(alphas, scales))
    assert got.shape == want.shape == (10, 301)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)
    assert np.ptp(want) > 1e-3  # the transits are in the frames
