"""Tempered SMC over (w, alpha) (jaxppo.inference._smc) against targets
whose evidence and mode masses are known in closed form."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxppo.inference._smc import tempered_smc

MU = jnp.array([0.5, -0.3])
SD = jnp.array([0.3, 0.8])


def _log_gamma(w, a):
    """A Gaussian in w times two narrow modes in alpha (147 deg, width 2;
    300 deg, width 3, half the height), times exp(50): the integral over w
    and alpha / 360 is exp(50) (2 + 0.5 x 3) sqrt(2 pi) / 360."""
    lw = jnp.sum(-0.5 * ((w - MU) / SD) ** 2 - jnp.log(SD * jnp.sqrt(2 * jnp.pi)))
    d1 = (a - 147.0 + 180.0) % 360.0 - 180.0
    d2 = (a - 300.0 + 180.0) % 360.0 - 180.0
    return lw + jnp.logaddexp(-0.5 * (d1 / 2.0) ** 2, jnp.log(0.5) - 0.5 * (d2 / 3.0) ** 2) + 50.0


@pytest.mark.parametrize("seed", [0, 1])
def test_evidence_and_mode_masses_of_a_bimodal_target(seed):
    log_z = 50.0 + np.log(3.5 * np.sqrt(2.0 * np.pi) / 360.0)
    r = tempered_smc(_log_gamma, 2, n_particles=512, seed=seed)
    assert abs(r["log_z"] - log_z) < 0.3, (r["log_z"], log_z)
    near = np.abs((r["alpha"] - 147.0 + 180.0) % 360.0 - 180.0) < 20.0
    mass = float(np.sum(r["weights"][near]))
    assert abs(mass - 2.0 / 3.5) < 0.08, mass
    # the rest sits in the other mode, and w follows the Gaussian
    far = np.abs((r["alpha"] - 300.0 + 180.0) % 360.0 - 180.0) < 20.0
    assert abs(float(np.sum(r["weights"][far])) + mass - 1.0) < 1e-9
    mean = r["weights"] @ r["w"]
    assert np.allclose(mean, np.asarray(MU), atol=0.15), mean
    assert r["ess"] > 100 and r["steps"] >= 2


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="n_particles must be an integer >= 16"):
        tempered_smc(_log_gamma, 2, n_particles=4)
    with pytest.raises(ValueError, match="cess must be in"):
        tempered_smc(_log_gamma, 2, cess=1.5)
