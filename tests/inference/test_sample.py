"""NUTS (numpyro) through jp.sample: the change of coordinates keeps the
physical priors, arviz export under the public names, diagnostics against
arviz, and the CLI's netCDF output."""

import warnings

import numpy as np
import pytest
from scipy import stats

import jaxppo as jp
from jaxppo.inference._diagnostics import rank_diagnostics

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)  # arviz 0.x announces its 1.0 refactor on import
    import arviz as az

AZ1 = int(az.__version__.split(".")[0]) >= 1  # arviz 1.x (DataTree); CI runs these tests with both


def test_the_arviz_ci_asks_for():
    """.ci/run runs the arviz tests a second time against arviz 1.x with
    JAXPPO_ARVIZ_MAJOR=1: they must see that version, not fall back to 0.x."""
    import os

    want = os.environ.get("JAXPPO_ARVIZ_MAJOR")
    assert want is None or int(az.__version__.split(".")[0]) == int(want), az.__version__


def _az_ess(x, method):
    """arviz's bulk / tail ESS (1.x needs the tail quantiles spelled out:
    0.05 and 0.95, 0.x's fixed choice)."""
    if AZ1 and method == "tail":
        return float(az.ess(x, method="tail", prob=(0.05, 0.95)))
    return float(az.ess(x, method=method))


def test_without_information_the_draws_follow_the_physical_priors():
    """With flux_err = 1e3 the likelihood is flat, so the draws must follow
    the documented priors: a uniform in [1, 4 a] (truncated at 1 + p, where
    a transit duration stops existing), |b| / (1 + p) uniform in [0, 1)
    (the inclination folded into [0, 90] deg),
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
    # thin to about one draw per effective sample for the KS tests, which
    # assume independent draws: by the smaller of bulk and tail ESS, and at
    # least every second draw (NUTS's bulk ESS of these chains, 1,100-1,650
    # of 2,000, holds for the mean, not for the empirical CDF at every
    # quantile: over seeds 1-6, every draw gave p down to 1.4e-4 for b at
    # seed 1, every second draw p >= 0.003 at every seed)
    step = max(2, int(a.size / min(min(d["ess_bulk"], d["ess_tail"]) for d in res.diagnostics.values())))
    hi = 4 * float(b.a)
    assert stats.kstest(a[::step], stats.uniform(1.0, hi - 1.0).cdf).pvalue > 1e-3
    assert np.all(bn >= 0)
    assert stats.kstest(bn[::step], stats.uniform(0.0, 1.0).cdf).pvalue > 1e-3
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


class TestSmallRun:
    """The tests of one short run (small_run: 40 s to compile and run). A
    class is their xdist scope: .ci/run's arviz 1.x rerun (--dist
    loadscope) gives it one worker, which runs the fixture once (split over
    both workers, each ran it)."""

    def test_to_arviz_gives_physical_quantities_under_public_names(self, small_run, tmp_path):
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
        if AZ1:
            # arviz 1.x's PSIS k-hat refuses a tail of equal values ("All tail
            # values are the same"), as this 60-draw run has (NUTS repeats a
            # draw it rejects): its own ESS of the posterior read back instead
            ess = az.ess(back)
            assert all(np.isfinite(float(ess[n])) for n in free)
        else:
            # PSIS-LOO runs on it (needs the pointwise log-likelihood and the chain axis)
            assert np.isfinite(az.loo(back).elpd_loo)

    def test_diagnostics_agree_with_arviz(self, small_run):
        _, _, free, res = small_run
        for n in free:
            x = res.chains[n]
            d = res.diagnostics[n]
            assert np.isclose(d["r_hat"], float(az.rhat(x)), rtol=1e-6)
            # numpyro's autocorrelation estimator and arviz's differ a little
            # on 30-draw chains; on long chains they agree within 2 % (below)
            assert np.isclose(d["ess_bulk"], _az_ess(x, "bulk"), rtol=0.15)
            assert np.isclose(d["ess_tail"], _az_ess(x, "tail"), rtol=0.15)
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
            assert np.isclose(d[key], _az_ess(ar, method), rtol=0.02), (key, d[key], _az_ess(ar, method))
        assert np.isclose(d["r_hat"], float(az.rhat(ar)), rtol=1e-9)

    def test_sample_result_save_load_round_trip(self, small_run, tmp_path):
        res = small_run[3]
        path = res.save(tmp_path / "post.npz")
        back = jp.SampleResult.load(path)
        assert back.names == res.names and list(back.chains) == list(res.chains)
        for n in res.chains:
            assert np.array_equal(back.chains[n], res.chains[n]) and np.array_equal(back.samples[n], res.samples[n])
        for n in res.stats:
            assert np.array_equal(back.stats[n], res.stats[n])
        assert np.array_equal(back.log_likelihood, res.log_likelihood) and np.array_equal(back.time, res.time)
        assert back.intervals == res.intervals and back.deviance_min == res.deviance_min
        assert all(np.isclose(back.diagnostics[n][k], res.diagnostics[n][k], rtol=0, atol=0, equal_nan=True)
                   for n in res.diagnostics for k in res.diagnostics[n])
        assert float(back.best.planets[0].a) == float(res.best.planets[0].a)
        # without the model the pointwise log-likelihood cannot be made: asked
        # for it (the default), a loaded result refuses instead of handing the
        # total per draw to az.loo as if it were one observation
        with pytest.raises(ValueError, match="pointwise=False"):
            back.to_arviz()
        ar = back.to_arviz(pointwise=False)
        assert list(ar.posterior.data_vars) == list(res.names)
        assert ar.log_likelihood["obs"].shape == res.log_likelihood.shape
        live = res.to_arviz(pointwise=False)  # a live run's total, the same numbers
        assert np.array_equal(live.log_likelihood["obs"].values, ar.log_likelihood["obs"].values)
        with pytest.raises(ValueError, match="not a file written by SampleResult.save"):
            (tmp_path / "x.npz").write_text("nonsense")
            jp.SampleResult.load(tmp_path / "x.npz")


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


# ---- user priors, Kipping q1/q2, jitter, results on disk ----

def _one_planet(jitter=0.0, noise=2e-4, seed=0):
    """One planet on a quadratic star (u = 0.4, 0.25), 2-min cadence over
    +-0.25 d of one transit."""
    truth = jp.System(jp.Star.quadratic(0.4, 0.25), [jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.0, radius=0.1,
                                                               name="b")])
    t = np.arange(-0.25, 0.25, 2.0 / 1440.0)
    f = np.asarray(truth.flux(t)) + np.random.default_rng(seed).normal(0.0, np.hypot(noise, jitter), t.size)
    return truth, jp.LightCurve(t, f, np.full(t.size, noise))


def test_sample_q1_q2_jitter_from_a_lightkurve_lightcurve():
    """q1, q2 are drawn in [0, 1] and reported with the implied u1, u2 (the
    analytic map, draw by draw); a free jitter has the posterior width the
    Gaussian likelihood with its log-variance term implies:
    sd(s) = V / (s sqrt(2 N)), V = sigma^2 + s^2."""
    import lightkurve as lk
    from astropy.time import Time

    from jaxppo.inference._params import kipping_u

    s = 4e-4
    truth, lc = _one_planet(jitter=s)
    klc = lk.LightCurve(time=Time(lc.time, format="bkjd", scale="tdb"), flux=lc.flux, flux_err=lc.flux_err)
    res = jp.sample(truth, klc, free=("b.t0", "star.q1", "star.q2", "lc.jitter"), num_warmup=150, num_samples=150,
                    num_chains=4, seed=2, progress_bar=False)
    q1, q2 = res.samples["star.q1"], res.samples["star.q2"]
    assert np.all((q1 > 0) & (q1 < 1) & (q2 > 0) & (q2 < 1))
    u1, u2 = kipping_u(q1, q2)
    assert np.allclose(res.samples["star.u1"], u1, rtol=0, atol=1e-12)
    assert np.allclose(res.samples["star.u2"], u2, rtol=0, atol=1e-12)
    assert res.names == ("b.t0", "star.q1", "star.q2", "lc.jitter") and "star.u1" in res.intervals
    jit = res.samples["lc.jitter"]
    expect = (2e-4**2 + s**2) / (s * np.sqrt(2.0 * len(lc)))
    assert abs(np.median(jit) - s) < 3 * expect
    assert abs(np.std(jit) / expect - 1) < 0.2, (np.std(jit), expect)
    for n in ("star.u1", "star.u2"):  # the truth within the 99.7 % interval
        lo, hi = np.percentile(res.samples[n], [0.15, 99.85])
        assert lo < {"star.u1": 0.4, "star.u2": 0.25}[n] < hi


def test_an_informative_prior_sets_the_posterior_width():
    """A Normal prior on t0 ten times narrower than the likelihood: the
    posterior is the product of two Gaussians, sd = (1/sp^2 + 1/sl^2)^-1/2
    and mean = (mp/sp^2 + ml/sl^2) sd^2, with the likelihood's mean and sd
    (ml, sl) from the least-squares fit."""
    import numpyro.distributions as dist

    truth, lc = _one_planet()
    fit = jp.fit(truth, lc, free=("b.t0", "b.radius"))
    ml, sl = fit.values[0], fit.errors[0]
    sp = 0.1 * sl
    mp = ml + 2.0 * sp
    res = jp.sample(truth, lc, free=("b.t0", "b.radius"), num_warmup=150, num_samples=250, num_chains=4, seed=0,
                    progress_bar=False, priors={"b.t0": dist.Normal(mp, sp)})
    want_sd = (1 / sp**2 + 1 / sl**2) ** -0.5
    want_mean = (mp / sp**2 + ml / sl**2) * want_sd**2
    t0 = res.samples["b.t0"]
    assert abs(np.std(t0) / want_sd - 1) < 0.12, (np.std(t0), want_sd)
    assert abs(np.mean(t0) - want_mean) < 0.2 * want_sd
    # the radius keeps the likelihood's width (t0 and p are nearly uncorrelated)
    assert abs(np.std(res.samples["b.radius"]) / fit.errors[1] - 1) < 0.2


def test_user_priors_are_checked_and_a_prior_on_a_keeps_plain_coordinates():
    import numpyro.distributions as dist

    from jaxppo.inference._model import Model
    from jaxppo.inference._coords import Coordinates, default_priors, start_q
    from jaxppo.inference._sample import _check_priors

    truth, lc = _one_planet()
    free = ("b.t0", "b.a", "b.inc", "b.radius")
    with pytest.raises(ValueError, match="not free parameters"):
        jp.sample(truth, lc, free=free, priors={"c.t0": dist.Normal(0.0, 1.0)})
    with pytest.raises(ValueError, match="inclination is not supported"):
        jp.sample(truth, lc, free=free, priors={"b.inc": dist.Normal(89.0, 1.0)})
    with pytest.raises(ValueError, match="outside the prior's support"):
        jp.sample(truth, lc, free=free, priors={"b.a": dist.Uniform(25.0, 30.0)})
    with pytest.raises(ValueError, match="scalar numpyro distribution"):
        jp.sample(truth, lc, free=free, priors={"b.a": 20.0})
    model = Model(truth, lc, free)
    user = {"b.a": dist.TruncatedNormal(20.0, 1.0, low=1.2)}
    with pytest.warns(UserWarning, match="plain coordinates"):
        _check_priors(model, truth, user)
    coords = Coordinates(model, default_priors(model, user), user)
    assert not coords.duration and coords.plain == [0]
    q = start_q(model, truth)
    assert np.allclose(np.asarray(coords.to_q(coords.from_q(q))), q, rtol=1e-12)
    # the prior's own density is what the potential adds for a (identity-free check: a
    # TruncatedNormal on a through numpyro's bijection onto (1.2, inf))
    assert float(coords.maps[1](coords.from_q(q)[1])) == pytest.approx(20.0, rel=1e-12)


def test_rank_diagnostics_equal_arviz_and_never_negative():
    """R-hat and bulk / tail ESS against arviz (the reference implementation
    of Vehtari et al. 2021), including short anticorrelated chains, for which
    the unclamped Geyer sum gave a negative ESS (-141 where arviz gives
    N log10 N = 115.6)."""
    import arviz as az

    from jaxppo.inference._diagnostics import rank_diagnostics

    rng = np.random.default_rng(1)
    iid = rng.normal(size=(4, 16))
    ar = iid.copy()
    for i in range(1, 16):
        ar[:, i] = 0.8 * ar[:, i - 1] + 0.6 * ar[:, i]
    anti = 0.1 * iid + np.where(np.arange(16) % 2 == 0, 1.0, -1.0)[None, :]
    # (2, 51): odd chains, whose middle draw the split drops
    for x in (iid, ar, anti, rng.normal(size=(2, 400)), rng.normal(size=(2, 51)), rng.normal(size=(4, 101))):
        d = rank_diagnostics(x)
        assert d["ess_bulk"] > 0 and d["ess_tail"] > 0
        assert np.isclose(d["ess_bulk"], _az_ess(x, "bulk"), rtol=1e-6)
        assert np.isclose(d["ess_tail"], _az_ess(x, "tail"), rtol=1e-6)
        assert np.isclose(d["r_hat"], float(az.rhat(x)), rtol=1e-6)


# ---- issue 22 item 0: right from an off-truth start ----

def test_a_posterior_cut_by_its_default_prior_window_is_named(tmp_path):
    """The default t0 prior is a window of +-0.05 d about the start: started
    86 min late, the draws piled against its edge (t0 = start - 0.05 d, sd
    3 s, the radius biased by 2 %) while R-hat, ESS and the optimiser all
    said converged, and nothing warned. Now a UserWarning names t0,
    ``start["prior_bound"]`` lists it, ``problems()`` (which the CLI
    prints) says so, and it survives save / load; the radius, whose
    log-uniform prior is a physical bound, is not listed."""
    truth, lc = _one_planet()
    pl = truth.planets[0]
    late = truth.replace(planets=(pl.replace(t0=0.06),))
    with pytest.warns(UserWarning, match=r"posterior of b.t0 .* lies against the bound 0.01 of its default prior"):
        res = jp.sample(late, lc, free=("b.t0", "b.radius"), num_warmup=60, num_samples=60, num_chains=2, seed=0,
                        progress_bar=False)
    assert res.start["prior_bound"] == ["b.t0"]
    assert any("default prior window for ['b.t0']" in line for line in res.problems())
    assert jp.SampleResult.load(res.save(tmp_path / "r.npz")).start["prior_bound"] == ["b.t0"]
    # a user prior is the user's choice: not listed (the window check is for the defaults)
    from jaxppo.inference._coords import window_priors
    from jaxppo.inference._model import Model

    model = Model(late, lc, ("b.t0", "b.period", "b.radius", "star.u1"))
    assert sorted(window_priors(model)) == ["b.period", "b.t0", "star.u1"]
    assert window_priors(Model(late, lc, ("b.radius", "star.q1", "lc.jitter"))) == {}  # physical bounds
    import numpyro.distributions as dist
    assert sorted(window_priors(model, {"b.t0": dist.Normal(0.06, 1.0)})) == ["b.period", "star.u1"]


@pytest.mark.runs_programs  # 129 s at XLA's level 0, 73 s at the default (CI, 2 workers)
def test_from_an_off_truth_start_the_posterior_is_folded_and_covers_the_truth():
    """One transit at 1-minute cadence, started 3 min off in t0, 5 % off in
    a/R* and the radius and at inc 88 deg for a true 88.3 deg (b = 0.31,
    whose posterior reaches b = 0). The light curve depends on |cos i|
    only, so the signed impact parameter the sampler used to move gave
    two mirrored modes: draws above 90 deg and an interval of inc around
    neither (old code, this data: draws up to 100.5 deg). Now every
    inclination is folded into [0, 90], the chains start at the posterior
    mode with its Laplace metric and cover the truth.

    150 + 150 iterations: the signed coordinate (fold_inc=False) already
    puts draws at 96-98 deg there (seeds 0, 1); that the chains agree (R-hat
    below 1.05 takes 600 draws per chain, 2.5 minutes) is checked by
    ``python benchmarks/nuts_off_truth.py``, the same case at full length."""
    truth = jp.System(jp.Star.quadratic(0.4, 0.26), [jp.Planet(period=3.7, t0=0.0, a=10.6, inc=88.3, radius=0.03,
                                                                   name="b")])
    t = np.arange(-0.2, 0.2, 1.0 / 1440.0)
    lc = jp.LightCurve(t, np.asarray(truth.flux(t)) + np.random.default_rng(5).normal(0.0, 5e-4, t.size),
                       np.full(t.size, 5e-4))
    pl = truth.planets[0]
    start = truth.replace(planets=(pl.replace(t0=3.0 / 1440.0, a=10.6 * 1.05, radius=0.03 * 1.05, inc=88.0),))
    free = ("b.t0", "b.period", "b.a", "b.inc", "b.radius")
    # the data put t0's posterior 2.1-2.5 sd from the truth at every length
    # and seed tried (0-3 at 100 + 100, 0-2 at 150 + 150, 0 at 500 + 600)
    res = jp.sample(start, lc, free=free, num_warmup=150, num_samples=150, num_chains=4, seed=0, progress_bar=False)
    inc = res.samples["b.inc"]
    assert np.all(inc <= 90.0), inc.max()
    assert res.start["optimised"] and res.start["converged"], res.start
    # one transit does not measure the period: its posterior is the prior's
    # +-0.1 % window, and is named (t0, a, inc and the radius are the data's)
    assert res.start["prior_bound"] == ["b.period"], res.start
    for n in free:
        med, sd = np.median(res.samples[n]), np.std(res.samples[n])
        want = float(getattr(pl, n.split(".")[1]))
        assert abs(med - want) < 3 * sd, (n, med, sd, want)
    med, lo, hi = res.intervals["b.inc"]
    assert lo < 88.3 < hi or abs(med - 88.3) < 2 * np.std(inc), res.intervals["b.inc"]
    # fold_inc=False keeps the old, signed coordinate: the mirrored mode is sampled too
    # (checked cheaply: the coordinate map, not a run)
    from jaxppo.inference._model import Model
    from jaxppo.inference._coords import Coordinates, default_priors, start_q

    model = Model(start, lc, free)
    q = start_q(model, start.replace(planets=(start.planets[0].replace(inc=92.0),)))
    for fold, sign in ((True, 1.0), (False, -1.0)):
        coords = Coordinates(model, default_priors(model), (), fold)
        back = np.asarray(coords.to_q(coords.from_q(q)))
        assert np.sign(back[3]) == sign and abs(back[3]) == pytest.approx(abs(q[3]), rel=1e-12)


def test_widened_at_covers_what_each_draw_needs():
    """``Model.widened_at`` (the vectorised frames of many parameter
    vectors, which ``sample`` checks every distinct draw with) gives the
    frames ``widened`` finds system by system: on star within 0.05 R*, and
    none to add for a parameter vector the model already covers."""
    from jaxppo.inference._model import Model

    truth, lc = _one_planet()
    model = Model(truth, lc, ("b.t0", "b.a"), active_margin=0.0)
    th0 = np.asarray(model.to_theta(truth))
    moved = [th0 + np.array([dt, 0.0]) for dt in (-0.03, 0.0, 0.02)]
    fast = model.widened_at(np.stack(moved))
    slow = model.widened([model.to_system(th) for th in moved])
    assert fast is not None and slow is not None
    np.testing.assert_array_equal(fast.active_idx, slow.active_idx)
    np.testing.assert_array_equal(fast.union_idx, slow.union_idx)
    assert fast.active_idx.size > model.active_idx.size
    assert fast.widened_at(np.stack(moved)) is None


def test_sample_never_keeps_draws_scored_on_frames_it_did_not_compute(monkeypatch):
    """The frames a run computes are fixed; draws that reach others are
    scored as if no planet were there. ``sample`` runs again with those
    frames, and where the draws still reach new frames after its last run
    it says so (``start["frames_complete"]`` False and a warning). The old
    code ran three times and then returned the last run without a word."""
    import jaxppo.inference._sample as smp

    truth, lc = _one_planet()
    calls = []
    real = smp._wider

    def always_wider(model, user, fold, us):
        calls.append(len(us))
        got = real(model, user, fold, us)
        return got if got is not None else model.with_frames(active=[0])  # pretend the draws reach frame 0

    monkeypatch.setattr(smp, "_wider", always_wider)
    with pytest.warns(UserWarning, match="still reach frames the model did not compute"):
        res = jp.sample(truth, lc, free=("b.radius",), num_warmup=20, num_samples=10, num_chains=1,
                        progress_bar=False)
    assert res.start["frames_complete"] is False and len(calls) == 5  # before sampling, then after each of 4 runs
    monkeypatch.setattr(smp, "_wider", real)
    res = jp.sample(truth, lc, free=("b.radius",), num_warmup=20, num_samples=10, num_chains=1, progress_bar=False)
    assert res.start["frames_complete"] is True


def test_sample_says_where_chi2_at_the_mode_says_flux_err_is_off():
    """flux_err 3 times too small: the posterior is 3 times too narrow and
    sample said nothing (fit now warns); the mode's chi^2 / (N - k) is a
    UserWarning and a line of problems()."""
    star = jp.Star.quadratic(0.4, 0.25)
    truth = jp.System(star, [jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")])
    lc = jp.simulate(truth, np.linspace(-0.15, 0.15, 200), noise=1e-3, seed=1)
    lc = jp.LightCurve(lc.time, lc.flux, lc.flux_err / 3.0)
    with pytest.warns(UserWarning, match=r"sample: at the posterior mode chi\^2 / \(N - k\) = 7\.[0-9]+ .*too small"):
        res = jp.sample(truth, lc, free=("b.t0", "b.radius"), num_warmup=30, num_samples=30, num_chains=1,
                        progress_bar=False)
    assert any("too small by about a factor 2." in p for p in res.problems())
