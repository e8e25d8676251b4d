"""The joint (alpha, transit parameters) sampler (jaxppo.joint_scan)
against injected PPOs: the truth recovered from a user's offset start where
the importance average over no-PPO draws fails, resume, outputs and the
command line."""

import json

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.inference._coords import a_from_density, density_from_a

ALPHA, CASE = 147.0, "opposite"


@pytest.fixture(scope="module")
def injected():
    """Kepler-20 b and c with twice their radii (c's a/R* from b's stellar
    density), 1-minute data with noise 2e-4, a PPO at alpha = 147 deg, case
    "opposite"; all seven double transits (with fewer, the PPO's timing
    lets alpha slide along the alpha-t0 ridge: with the three around the
    PPO the posterior runs from 147 to 166 deg, peak 160, as an
    independent profile-Laplace computation confirms). The start is a
    user's: c.t0 4 min late, b's a/R* 3 % large (all ten transit
    parameters free and b's radius 4 % small too: benchmarks/joint.py)."""
    truth = jp.kepler20_system(None, 2.0)
    b, c = truth.planets
    rho = density_from_a(float(b.a), float(b.period))
    truth = truth.replace(planets=[b, c.replace(a=float(a_from_density(rho, float(c.period))))])
    t = jp.simulate_kepler20(seed=5, noise=2e-4, radius_scale=2.0).time
    lc = jp.simulate(truth, t, 2e-4, ALPHA, CASE, 5)
    # the event whose model changes most between the PPO and a quiet tilt
    quiet = np.asarray(truth.flux(t, 0.0, CASE))
    loud = np.asarray(truth.flux(t, ALPHA, CASE))
    t_ppo = float(np.asarray(t)[np.argmax(np.abs(loud - quiet))])
    b, c = truth.planets
    start = truth.replace(planets=[b.replace(a=float(b.a) * 1.03), c.replace(t0=float(c.t0) + 4 / 1440)])
    return start, lc, t_ppo


def test_the_injected_tilt_and_geometry_from_an_offset_start(injected, tmp_path):
    start, lc, t_ppo = injected
    # the t0s (the ridge) and the a/R* (one stellar density) free: a test-sized problem
    kw = dict(cases=(CASE,), detrend="none", free=("b.t0", "c.t0", "b.a", "c.a"))
    r = jp.joint_scan(start, lc, particles=128, seeds=(0,), out=tmp_path, progress=False, **kw)
    c = r["cases"][CASE]
    assert abs(c["alpha_peak"] - ALPHA) < 3.0, c["alpha_peak"]
    lo, hi = c["alpha_68"]
    assert lo - 1.0 < ALPHA < hi + 1.0, c["alpha_68"]
    assert c["geometries"]["retrograde, same hemisphere"]["probability"] > 0.95
    assert c["modes"]["modes"] and abs(c["modes"]["modes"][0]["alpha"] - ALPHA) < 3.0
    # outputs: joint.json (strict JSON, the result), joint.csv (a density per degree)
    rec = json.loads((tmp_path / "joint.json").read_text(), parse_constant=lambda x: pytest.fail(x))
    assert rec["result"]["cases"][CASE]["alpha_peak"] == c["alpha_peak"]
    rows = np.genfromtxt(tmp_path / "joint.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert rows.size == 360 and abs(float(np.sum(rows["posterior"])) - 1.0) < 1e-9
    # joint.png: the joint posterior against the fixed scan of the same config
    assert r["figures"] == [str((tmp_path / "joint.png").resolve())]
    assert (tmp_path / "joint.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # a rerun resumes: nothing sampled again, the same numbers
    again = jp.joint_scan(start, lc, particles=128, seeds=(0,), out=tmp_path, progress=False, **kw)
    assert again["cases"][CASE]["alpha_peak"] == c["alpha_peak"]
    assert again["cases"][CASE]["seconds"] == c["seconds"] and again["seconds"] < 30.0
    # the alpha grid (the fixed scan's) is not the joint sampler's: another grid resumes too
    other = jp.joint_scan(start, lc, particles=128, seeds=(0,), out=tmp_path, progress=False,
                          alpha=np.arange(0.0, 360.0, 2.0), **kw)
    assert other["cases"][CASE]["seconds"] == c["seconds"]
    with pytest.raises(ValueError, match="holds a joint run of other settings"):
        jp.joint_scan(start, lc, particles=64, seeds=(0,), out=tmp_path, progress=False, **kw)


def test_bad_settings_are_named(injected):
    start, lc, t_ppo = injected
    for kw, msg in [(dict(particles=8), "particles must be an integer >= 16"),
                    (dict(particles=True), "particles must be an integer >= 16"),
                    (dict(seeds=(1, 1)), "seeds must be a sequence of distinct integers"),
                    (dict(seeds="12"), "seeds must be a sequence of distinct integers"),
                    (dict(seeds=(0.7, 1.2)), "seeds must be a sequence of distinct integers"),
                    (dict(seeds=(-1, 0)), "seeds must be a sequence of distinct integers >= 0"),
                    (dict(particles=None), "particles must be an integer >= 16"),
                    (dict(particles=float("nan")), "particles must be an integer >= 16"),
                    (dict(cess=1.0), "cess must be a number in"), (dict(cess="0.5"), "cess must be a number in"),
                    (dict(fixed=jp.scan(start, lc, cases=(CASE,), detrend="none", alpha=np.arange(0.0, 360.0, 30.0))),
                     "fixed: a scan of another configuration"),
                    (dict(n_moves=0), "n_moves must be an integer >= 1")]:
        with pytest.raises(ValueError, match=msg):
            jp.joint_scan(start, lc, progress=False, **kw)
    cfg = jp.load_config()
    with pytest.raises(ValueError, match="lightcurve must not be given with a ScanConfig"):
        jp.joint_scan(cfg, lc)
    with pytest.raises(ValueError, match="jaxppo.joint_scan"):
        jp.joint_scan(cfg, margin=0.1)


def test_case_summary_at_the_wrap_and_with_one_geometry_empty():
    """The 68 % arc of a mode at 0.2 deg is given on [0, 360); when every
    particle is in one geometry there is no finite Bayes factor, the other
    geometry's mass gets a 95 % upper bound, and the error is at least that."""
    from jaxppo.obliquity._joint import _case_summary

    rng = np.random.default_rng(0)
    runs = [{"alpha": np.mod(0.2 + rng.normal(0, 1.5, 400), 360.0), "weights": np.full(400, 1 / 400), "ess": 400.0,
             "log_z": -10.0 + 0.01 * s, "steps": 3, "calls": 1, "seconds": 1.0} for s in range(2)]
    c = _case_summary("same", runs)
    lo, hi = c["alpha_68"]
    assert 355.0 < lo < 360.0 and 0.0 < hi < 5.0, c["alpha_68"]
    assert c["alpha_peak"] in (0.5, 359.5)
    assert c["bayes_factor"] is None and 0 < c["upper_bound_other"] < 0.01
    assert c["geometries"]["prograde, same hemisphere"]["probability"] == 1.0
    assert c["geometries"]["prograde, same hemisphere"]["error"] >= c["upper_bound_other"]
    assert "at least" in c["jeffreys"]
