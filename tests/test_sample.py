"""NUTS (numpyro) through jp.sample: the change of coordinates keeps the
physical priors, arviz export under the public names, diagnostics against
arviz, and the CLI's netCDF output."""

import warnings

import numpy as np
import pytest
from scipy import stats

import jaxppo as jp
from jaxppo._sample import rank_diagnostics

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)  # arviz announces its 1.0 refactor on import
    import arviz as az


def test_without_information_the_draws_follow_the_physical_priors():
    """With flux_err = 1e3 the likelihood is flat, so the draws must follow
    the documented priors: a uniform in [1, 4 a] (truncated at 1 + p, where
    a transit duration stops existing), b / (1 + p) uniform in (-1, 1),
    p log-uniform in [1e-4, 0.5]. NUTS moves in (log T14, atanh b, ...), so
    a missing or wrong Jacobian term would distort all three."""
    truth = jp.kepler20_system()
    b = truth.planets[0]
    lc = jp.simulate_kepler20(seed=3)
    keep = np.abs(((lc.time - float(b.t0)) / float(b.period) + 0.5) % 1 - 0.5) * float(b.period) < 0.3
    keep &= np.cumsum(keep) <= 200
    lc = jp.LightCurve(lc.time[keep], lc.flux[keep], np.full(keep.sum(), 1e3))
    res = jp.sample(jp.System(truth.star, [b]), lc, free=("b.a", "b.inc", "b.radius"), num_warmup=200,
                    num_samples=500, num_chains=4, seed=1, progress_bar=False)
    a = res.samples["b.a"]
    p = res.samples["b.radius"]
    bn = a * np.cos(np.deg2rad(res.samples["b.inc"])) / (1 + p)
    ess = min(d["ess_bulk"] for d in res.diagnostics.values())
    assert ess > 500, res.diagnostics
    assert not np.any(res.stats["diverging"])
    # thin to about one draw per effective sample for the KS tests
    step = max(1, int(a.size / ess))
    hi = 4 * float(b.a)
    assert stats.kstest(a[::step], stats.uniform(1.0, hi - 1.0).cdf).pvalue > 1e-3
    assert stats.kstest(bn[::step], stats.uniform(-1.0, 2.0).cdf).pvalue > 1e-3
    assert stats.kstest(np.log(p[::step]), stats.uniform(np.log(1e-4), np.log(0.5 / 1e-4)).cdf).pvalue > 1e-3


@pytest.fixture(scope="module")
def small_run():
    truth = jp.kepler20_system()
    b = truth.planets[0]
    one = jp.System(truth.star, [b])
    lc = jp.simulate_kepler20(seed=21, noise=4e-4)
    near = np.abs(((lc.time - float(b.t0)) / float(b.period) + 0.5) % 1 - 0.5) * float(b.period) < 0.3
    lc = lc.select(near & (np.cumsum(near) <= 400))
    free = ("b.t0", "b.a", "b.inc", "b.radius")
    return one, lc, free, jp.sample(one, lc, free=free, num_warmup=40, num_samples=30, num_chains=2, seed=0,
                                    progress_bar=False)


def test_to_arviz_gives_physical_quantities_under_public_names(small_run, tmp_path):
    """Issue 15 item 3: the posterior holds "b.inc" in degrees (the old
    export called b / (1 + p) "b_inc"), the log-likelihood sits in its own
    group (per data point), sample stats and observed data are there, with a
    chain axis; a netCDF file round-trips through arviz."""
    truth, lc, free, res = small_run
    idata = res.to_arviz()
    path = tmp_path / "posterior.nc"
    res.to_netcdf(path)
    back = az.from_netcdf(str(path))
    for data in (idata, back):
        post = data.posterior
        assert sorted(post.data_vars) == sorted(free)
        assert post["b.inc"].shape == (2, 30)
        assert np.all((post["b.inc"].values > 45) & (post["b.inc"].values < 135))  # degrees, not b / (1 + p)
        assert np.allclose(post["b.a"].values.reshape(-1), res.samples["b.a"])
        assert "loglike" not in post.data_vars
        assert data.log_likelihood["obs"].shape == (2, 30, len(lc))
        for name in ("diverging", "step_size", "tree_depth", "n_steps", "energy", "lp", "acceptance_rate"):
            assert data.sample_stats[name].shape == (2, 30), name
        assert np.array_equal(data.observed_data["obs"].values, lc.flux)
        assert np.array_equal(data.observed_data["time"].values, lc.time)
    # the pointwise log-likelihood is the Gaussian density of the data around
    # the model of each draw: check one draw against the light curve directly
    i, j = 1, 7
    draw = {n: float(back.posterior[n].values[i, j]) for n in free}
    bb = truth.planets[0].replace(t0=draw["b.t0"], a=draw["b.a"], inc=draw["b.inc"], radius=draw["b.radius"])
    model = np.asarray(truth.replace(planets=(bb,)).flux(*lc.supersampled_times()[:1], 0.0))
    model = model.reshape(-1, lc.supersampled_times()[1]).mean(-1)
    ref = stats.norm(model, lc.flux_err).logpdf(lc.flux)
    assert np.allclose(back.log_likelihood["obs"].values[i, j], ref, rtol=0, atol=1e-6)
    # waic runs on it (needs the pointwise log-likelihood and the chain axis)
    assert np.isfinite(az.waic(back).elpd_waic)


def test_diagnostics_agree_with_arviz(small_run):
    _, _, free, res = small_run
    for n in free:
        x = res.chains[n]
        d = res.diagnostics[n]
        assert np.isclose(d["r_hat"], float(az.rhat(x)), rtol=1e-6)
        # numpyro's autocorrelation estimator and arviz's differ a little
        # on 30-draw chains; on long chains they agree within 2 % (below)
        assert np.isclose(d["ess_bulk"], float(az.ess(x, method="bulk")), rtol=0.15)
        assert np.isclose(d["ess_tail"], float(az.ess(x, method="tail")), rtol=0.15)
    rng = np.random.default_rng(0)
    x = rng.standard_normal((4, 200)) + np.array([[0.0], [0.0], [0.0], [1.0]])  # one chain off: R-hat large
    x[:, 50:60] = x[:, 49:50]  # ties, as when NUTS stays put
    d = rank_diagnostics(x)
    assert np.isclose(d["r_hat"], float(az.rhat(x)), rtol=1e-9) and d["r_hat"] > 1.1
    ar = np.zeros((4, 1000))  # AR(1), rho = 0.8: ESS about 1/9 of the draws
    e = rng.standard_normal((4, 1000))
    for i in range(1, 1000):
        ar[:, i] = 0.8 * ar[:, i - 1] + e[:, i]
    d = rank_diagnostics(ar)
    for key, method in (("ess_bulk", "bulk"), ("ess_tail", "tail")):
        assert np.isclose(d[key], float(az.ess(ar, method=method)), rtol=0.02), (key, d[key], az.ess(ar, method=method))
    assert np.isclose(d["r_hat"], float(az.rhat(ar)), rtol=1e-9)


def test_cli_sample_writes_netcdf(tmp_path, capsys):
    from jaxppo.cli import main

    out = tmp_path / "post.nc"
    rc = main(["sample", "--windows", "--free", "b.t0", "--warmup", "15", "--samples", "10", "--chains", "2",
               "--quiet", "--netcdf", str(out)])
    assert rc == 0
    back = az.from_netcdf(str(out))
    assert list(back.posterior.data_vars) == ["b.t0"] and back.posterior["b.t0"].shape == (2, 10)
    assert "ess bulk" in capsys.readouterr().out
    rc = main(["sample", "--free", "b.t0", "--netcdf", str(tmp_path / "missing" / "x.nc")])
    assert rc == 2
