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
    # the model fits (the noise as given): the least chi^2 the run reached, on the fixed scan's points,
    # below the fixed scan's best (its parameters are the offset start's)
    fit = r["goodness_of_fit"]
    fixed = jp.scan(start, lc, alpha=np.arange(0.0, 360.0, 1.0), **{k: kw[k] for k in ("cases", "detrend")})
    assert fit["ok"] and fit["checked"] and not c.get("withheld") and r["case_bayes_factors"] == {}
    assert fit["points"] == fixed.summary["points"] and 0.8 < fit["reduced"] < 1.2, fit
    assert fit["chi2_best"] < fixed.summary["goodness_of_fit"]["chi2_best"] - 100.0, (fit, fixed.summary)
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


def test_a_joint_run_whose_model_does_not_fit_the_data_rates_nothing(tmp_path, monkeypatch):
    """Where the least chi^2 the sampler reached is far above the number of
    points (errors too small, a model that misses the data), joint_scan
    gives no geometry probability, rating, peak, posterior or Bayes factor
    between the cases: the reason in their place, in the result, joint.json,
    joint.csv, joint.png and the report (the sampler is a stand-in on a
    cheap target whose least chi^2 is set). Runs recorded without their
    chi^2 (an earlier jaxppo) are resumed, unchecked, with a caution."""
    from importlib.resources import files

    import jax.numpy as jnp

    import jaxppo.obliquity._joint as joint
    from jaxppo.inference._smc import tempered_smc

    reduced = {"value": 4.0}

    def stand_in(system, data, free, density, case, alpha_ref, *, n_particles, seed, cess, n_moves, progress=None,
                 found=None):
        def log_gamma(w, alpha):
            d = (alpha - 147.0 + 180.0) % 360.0 - 180.0
            return -0.5 * jnp.sum(w ** 2) + jnp.log(0.05 + jnp.exp(-0.5 * (d / 4.0) ** 2))

        out = tempered_smc(log_gamma, 2, n_particles=n_particles, seed=seed, cess=cess, n_moves=n_moves)
        out.update(modes={}, found=None, chi2_best=reduced["value"] * len(data))
        return out

    monkeypatch.setattr(joint, "joint_case_smc", stand_in)
    cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 30])
    kw = dict(particles=32, seeds=(0, 1), n_moves=2, progress=False)
    r = jp.joint_scan(cfg, out=tmp_path, **kw)
    fit = r["goodness_of_fit"]
    assert not fit["ok"] and fit["checked"] and abs(fit["reduced"] - 4.0) < 1e-12
    assert "the model does not fit the data" in fit["reason"]
    for case, c in r["cases"].items():
        assert c["withheld"] == fit["reason"] and c["favoured"] is None and c["jeffreys"] == "not rated"
        assert all(g["probability"] is None for g in c["geometries"].values())
        assert c["alpha_peak"] is None and c["alpha_68"] is None and np.all(np.isnan(c["posterior"]))
        assert np.isfinite(c["log_z"])  # the evidence of the sampler's run stays, unrated
    assert list(r["case_bayes_factors"].values()) == [None] == list(r["case_log_bayes_factors"].values())
    lines = "\n".join(joint.joint_lines(r))
    assert lines.count("no probability, peak or rating in any case: the model does not fit the data") == 1
    assert "at the best point the sampler reached" in lines and lines.count("not rated") == 2
    assert "Bayes factor same/opposite: withheld" in lines
    assert not any(w in lines for w in ("favoured", "alpha peak", "calibration", " %"))
    rec = json.loads((tmp_path / "joint.json").read_text(), parse_constant=lambda x: pytest.fail(x))
    assert rec["result"]["cases"]["same"]["geometries"] == r["cases"]["same"]["geometries"]
    rows = np.genfromtxt(tmp_path / "joint.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert rows.size == 720 and np.all(np.isnan(rows["posterior"]))
    assert (tmp_path / "joint.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # The sampler's least chi^2 against the fixed scan's best (the configuration's own parameters):
    # 50 above it (reduced chi^2 ~ 1, so the goodness of fit passes) is more than 10 free
    # parameters allow (10 + 3 sqrt(20) = 23.4): the sampled model cannot reach the configuration's
    # fit (data made from a/R* of two stellar densities, tied to one), withheld; 5 above: rated
    fixed = joint._fixed_scan(cfg)
    best, n = fixed.summary["goodness_of_fit"]["chi2_best"], fixed.summary["points"]
    reduced["value"] = (best + 50.0) / n
    far = jp.joint_scan(cfg, out=tmp_path / "far", fixed=fixed, **kw)
    assert not far["goodness_of_fit"]["ok"] and far["goodness_of_fit"]["reach"]["excess"] == pytest.approx(50.0)
    assert "cannot fit these data as well as the fixed parameters do" in far["goodness_of_fit"]["reason"]
    assert all(c["jeffreys"] == "not rated" and c["favoured"] is None for c in far["cases"].values())
    reduced["value"] = (best + 5.0) / n
    near = jp.joint_scan(cfg, out=tmp_path / "near", fixed=fixed, **kw)
    assert near["goodness_of_fit"]["ok"] and near["goodness_of_fit"]["reach"]["checked"]
    assert all(c["jeffreys"] != "not rated" for c in near["cases"].values())
    # chi^2 / N = 1.1 (p = 1e-4 for 2,924 points, within the limit), the fixed scan's alike (a
    # stand-in, as the sampler is): rated as before, with a caution
    reduced["value"] = 1.1
    fixed.summary["goodness_of_fit"]["chi2_best"] = 1.1 * n
    ok = jp.joint_scan(cfg, out=tmp_path / "fits", fixed=fixed, **kw)
    assert ok["goodness_of_fit"]["ok"] and "raise every ln K by about 10 %" in ok["goodness_of_fit"]["caution"]
    assert all(c["jeffreys"] != "not rated" and not c.get("withheld") for c in ok["cases"].values())
    assert "caution: chi^2 = 3216.4 for 2924 points" in "\n".join(joint.joint_lines(ok))
    assert all(v is not None for v in ok["case_log_bayes_factors"].values())
    # a chi^2 that is not finite (a model that gives NaN): nothing rated, and strict JSON throughout
    reduced["value"] = float("nan")
    nan = jp.joint_scan(cfg, out=tmp_path / "nan", **kw)
    assert not nan["goodness_of_fit"]["ok"] and nan["goodness_of_fit"]["chi2_best"] is None
    assert "is nan" in nan["goodness_of_fit"]["reason"]
    assert all(c["jeffreys"] == "not rated" for c in nan["cases"].values())
    json.dumps(nan["goodness_of_fit"], allow_nan=False)
    again = jp.joint_scan(cfg, out=tmp_path / "nan", **kw)  # resumed: its null chi^2 is not an earlier jaxppo's
    assert not again["goodness_of_fit"]["ok"] and again["goodness_of_fit"]["checked"]
    # runs of an earlier jaxppo (no chi^2 recorded): resumed, unchecked, said so
    for run in rec["runs"].values():
        del run["chi2_best"]
    (tmp_path / "joint.json").write_text(json.dumps({"settings": rec["settings"], "runs": rec["runs"]}))
    old = jp.joint_scan(cfg, out=tmp_path, **kw)
    assert old["goodness_of_fit"]["ok"] and not old["goodness_of_fit"]["checked"]
    assert [c["seconds"] for c in old["cases"].values()] == [c["seconds"] for c in r["cases"].values()]
    assert "caution: goodness of fit not checked" in "\n".join(joint.joint_lines(old))
