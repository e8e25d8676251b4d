"""The guard on importance averages: Kish ESS and the Pareto k-hat against
arviz (an independent implementation of Vehtari et al. 2024), and the
marginal scan withholding probabilities that rest on a few draws."""

import math
import warnings

import numpy as np
import pytest

from jaxppo.inference._importance import importance_reliability, khat_threshold, kish_ess, pareto_khat


@pytest.mark.parametrize("n", [64, 1000])
@pytest.mark.parametrize("kind", ["normal", "t3", "lognormal3", "cauchy"])
def test_pareto_khat_against_arviz(n, kind):
    az = pytest.importorskip("arviz")
    rng = np.random.default_rng(n)
    lw = {"normal": lambda: rng.normal(0, 0.5, n), "t3": lambda: np.log(np.abs(rng.standard_t(3, n))),
          "lognormal3": lambda: rng.normal(0, 3, n), "cauchy": lambda: np.log(np.abs(rng.standard_cauchy(n)))}[kind]()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, k_ref = az.psislw(lw.copy())
    assert pareto_khat(lw) == pytest.approx(float(k_ref), abs=1e-9)


def test_kish_ess_and_edge_cases():
    assert kish_ess(np.zeros(40)) == pytest.approx(40.0)
    assert kish_ess(np.array([0.0, -800.0, -900.0])) == pytest.approx(1.0)
    assert kish_ess(np.log([1.0, 1.0, 2.0])) == pytest.approx(16 / 6)
    assert pareto_khat(np.zeros(100)) == -math.inf  # equal weights: no tail
    assert pareto_khat(np.zeros(10)) == math.inf  # a tail of 2 draws: no estimate
    assert khat_threshold(64) == pytest.approx(1 - 1 / math.log10(64))
    assert khat_threshold(10**6) == 0.7


def test_reliability_per_group():
    """One draw carrying one geometry's mass makes the case unreliable even
    when the total looks well spread."""
    rng = np.random.default_rng(1)
    n, a = 200, 36
    lw = rng.normal(0, 0.1, (n, a))
    pro = np.arange(a) < 18
    ok = importance_reliability(lw, {"pro": pro, "ret": ~pro})
    assert ok["reliable"] and ok["reason"] is None
    lw2 = lw.copy()
    lw2[:, ~pro] -= 50.0
    lw2[7, ~pro] += 60.0  # draw 7 alone carries the retrograde mass
    bad = importance_reliability(lw2, {"pro": pro, "ret": ~pro})
    assert not bad["reliable"] and "ret" in bad["reason"]
    assert bad["groups"]["ret"]["ess"] < 1.1
    assert importance_reliability(lw[:10], {"pro": pro})["reliable"] is False  # 10 draws: never
    # a heavy tail behind a fair ESS: 400 draws, log-normal weights (sd 1.6)
    heavy = rng.normal(0, 1.6, (400, 1)) + np.zeros((1, a))
    r = importance_reliability(heavy, {"pro": pro})
    assert r["groups"]["total"]["ess"] > 25 and r["groups"]["total"]["khat"] > 0.7
    assert not r["reliable"] and "k-hat" in r["reason"]


def test_broken_weights_are_never_reliable():
    """A NaN or +inf weight gives ESS 0 (the old check `ess < min_ess` let a
    NaN ESS through); a draw of zero weight (-inf) is a draw without weight."""
    lw = np.random.default_rng(2).normal(0, 0.1, (40, 12))
    pro = np.arange(12) < 6
    assert importance_reliability(lw, {"pro": pro, "ret": ~pro})["reliable"]
    for bad in (np.nan, np.inf):
        lw2 = lw.copy()
        lw2[3, 4] = bad
        r = importance_reliability(lw2, {"pro": pro, "ret": ~pro})
        assert not r["reliable"] and r["groups"]["pro"]["ess"] == 0.0
    lw3 = lw.copy()
    lw3[3] = -np.inf
    r = importance_reliability(lw3, {"pro": pro, "ret": ~pro})
    assert r["reliable"] and r["groups"]["total"]["ess"] == pytest.approx(39.0, rel=0.01)
    assert kish_ess(np.full(5, -np.inf)) == 0.0
