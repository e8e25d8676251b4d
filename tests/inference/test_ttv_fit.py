"""Fits of planets with transit times: the times are kept exactly (a fit
that dropped them would miss the transits by minutes); a free t0 of such a
planet (it cancels) and free transit times are refused by name."""

import numpy as np
import pytest

import jaxppo as jp

STAR = jp.Star("quadratic", [0.45, 0.2])


def _truth():
    b = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.5, radius=0.1, name="b",
                  transit_times=[0.01, 9.985, 20.02, 30.0])
    c = jp.Planet(period=13.0, t0=-6.0, a=25.0, inc=89.6, radius=0.08, name="c")
    return jp.System(STAR, [b, c])


def _data(system):
    t = np.concatenate([tc + np.arange(-0.3, 0.3, 1.0 / 1440) for tc in (0.01, 9.985, 20.02, 30.0, 7.0, 33.0)])
    t = np.sort(t)
    return jp.LightCurve(t, np.asarray(system.flux(t)), np.full(t.size, 1e-4))


def test_fit_with_fixed_transit_times_recovers_exact_parameters():
    truth = _truth()
    lc = _data(truth)
    b, c = truth.planets
    start = truth.replace(planets=[b.replace(radius=0.097, period=10.001), c.replace(radius=0.082)])
    res = jp.fit(start, lc, free=("b.radius", "b.period", "c.radius"))
    assert res.success, res.message
    assert np.allclose(res.values, [0.1, 10.0, 0.08], rtol=0, atol=1e-7), res.values - [0.1, 10.0, 0.08]
    assert res.system.planets[0].transit_epochs == (0, 1, 2, 3)
    assert np.array_equal(np.asarray(res.system.planets[0].transit_times), np.asarray(b.transit_times))


@pytest.mark.parametrize("free, match", [
    (("b.t0",), "planet 'b' has transit_times, which fix its mid-times"),
    (("b.tc[2]",), "free transit times are not supported yet"),
])
def test_fit_and_sample_refuse_what_transit_times_make_meaningless(free, match):
    truth = _truth()
    lc = _data(truth)
    with pytest.raises(ValueError, match=match):
        jp.fit(truth, lc, free=free)
    with pytest.raises(ValueError, match=match):
        jp.sample(truth, lc, free=free, num_warmup=2, num_samples=2)
    # c has no transit times: its t0 may be free
    from jaxppo.inference._model import Model

    Model(truth, lc, ("c.t0",), 0.0, "same")
