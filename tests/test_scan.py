"""The obliquity scan end to end (paper Sects. 2.1 and 3.3)."""

import json

import numpy as np
import pytest

import jaxppo as jp
from jaxppo._config import load_config
from jaxppo._scan import run_scan

CONFIG = """
[star]
law = "nonlinear"
coefficients = [1.0984732924, -1.74332475724, 2.46865245453, -0.995093958392]

[[planet]]
name = "b"
period = 3.69611590
t0 = 134.501962
a = 10.60
inc = 87.687
radius = {rb}
tilted = true

[[planet]]
name = "c"
period = 10.85408479
t0 = 138.608470
a = 22.764
inc = 89.967
radius = {rc}

[data]
path = "{data}"

[scan]
alpha = [{a0}, {a1}, 1.0]
cases = ["same", "opposite"]
block = {block}
"""


def _config(tmp_path, lc, a0=0.0, a1=360.0, scale=1.0, block=60, name="scan.toml", inc_c=89.967):
    lc.to_csv(tmp_path / "data.csv")
    text = CONFIG.format(rb=0.01805 * scale, rc=0.02878 * scale, data="data.csv", a0=a0, a1=a1, block=block)
    text = text.replace("inc = 89.967", f"inc = {inc_c}")
    (tmp_path / name).write_text(text)
    return tmp_path / name


@pytest.mark.parametrize("case_true", ["same", "opposite"])
def test_injected_ppo_is_recovered(tmp_path, case_true):
    """Planets enlarged 2x, noise 1e-4. Kepler-20 c crosses almost centrally
    (b = 0.013), which makes the two hemisphere cases nearly degenerate; here
    c is given b = 0.40 (i = 88.99 deg) so that the case is identifiable."""
    scale, inc_c = 2.0, 88.99
    system = jp.kepler20_system(radius_scale=scale)
    c = system.planets[1].replace(inc=inc_c)
    system = system.replace(planets=(system.planets[0], c))
    events = [e for e in jp.multi_transits(system, 300, 1600)]
    t = np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1 / 1440) for e in events])
    # inject at the middle of the widest alpha range that gives a PPO
    from jaxppo._scan import ppo_table

    grid = np.arange(0.0, 360.0)
    hit = ppo_table(system, [np.arange(e.start, e.end, 1 / 1440) for e in events], grid, case_true).any(1)
    runs, cur = [], []
    for i in np.nonzero(hit)[0]:
        if cur and i != cur[-1] + 1:
            runs.append(cur)
            cur = []
        cur.append(i)
    runs.append(cur)
    widest = max(runs, key=len)
    alpha_true = float(grid[widest[len(widest) // 2]])
    lc = jp.simulate(system, t, noise=1e-4, alpha=alpha_true, case=case_true, seed=5)
    path = _config(tmp_path, lc, 0.0, 360.0, scale, inc_c=inc_c)
    res = run_scan(load_config(path), tmp_path / "out", progress=False, figures=False)
    other = "opposite" if case_true == "same" else "same"
    best = res["cases"][case_true]["min_delta_chi2"]
    assert abs(best["alpha"] - alpha_true) <= 2.0
    assert best["value"] < res["cases"][other]["min_delta_chi2"]["value"]  # the right case fits better
    prograde = alpha_true <= 90 or alpha_true > 270
    expect = {("same", True): "prograde, same hemisphere", ("same", False): "retrograde, different hemispheres",
              ("opposite", True): "prograde, different hemispheres", ("opposite", False): "retrograde, same hemisphere"}
    assert res["probabilities"][case_true]["favoured"] == expect[(case_true, prograde)]


def test_null_data_is_exactly_flat_without_ppo(tmp_path):
    lc = jp.simulate_kepler20(seed=3, noise=4e-4)
    cfg = load_config(_config(tmp_path, lc, 0.0, 360.0))
    res = run_scan(cfg, tmp_path / "out", progress=False, figures=False)
    rows = np.genfromtxt(tmp_path / "out" / "scan.csv", delimiter=",", names=True, dtype=None, encoding=None)
    for case in ("same", "opposite"):
        sel = rows["case"] == case
        alpha, dchi2 = rows["alpha"][sel], rows["delta_chi2"][sel]
        ppo = res["cases"][case]["ppo_transits"]
        has = np.array([f"{a:g}" in ppo for a in alpha])
        assert np.all(dchi2[~has] == 0.0)  # exactly: no render noise
        assert np.all(dchi2[has] != 0.0)
        post = rows["posterior"][sel]
        assert abs(np.sum(post) * 1.0 - 1.0) < 1e-12
    # case "opposite" shifts the PPO ranges by a few degrees (paper Table 5)
    def first(case, lo, hi):
        return min(float(a) for a in res["cases"][case]["ppo_transits"] if lo < float(a) < hi)
    assert 0 < first("opposite", 60, 120) - first("same", 60, 120) <= 6
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["chi2_0"]["same"] > 0


def test_interrupted_scan_resumes_without_recomputing(tmp_path, monkeypatch):
    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    path = _config(tmp_path, lc, 0.0, 120.0, block=20)
    cfg = load_config(path)
    full = run_scan(cfg, tmp_path / "ref", progress=False, figures=False)

    import jaxppo._scan as scan_mod

    calls = {"n": 0}
    real = scan_mod.sweep

    def flaky(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(scan_mod, "sweep", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_scan(cfg, tmp_path / "out", progress=False, figures=False)
    lines = (tmp_path / "out" / "scan_progress.jsonl").read_text().splitlines()
    assert len(lines) == 1 + 3  # header + three finished blocks kept
    calls["n"] = 10
    res = run_scan(cfg, tmp_path / "out", progress=False, figures=False)
    assert calls["n"] == 10 + 12 - 3 + 1  # 12 blocks in all, 3 already done; +1: the null model
    a = (tmp_path / "ref" / "scan.csv").read_text()
    b = (tmp_path / "out" / "scan.csv").read_text()
    assert a == b and res["chi2_0"] == full["chi2_0"]


def test_changed_config_is_not_mixed(tmp_path):
    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    cfg = load_config(_config(tmp_path, lc, 0.0, 30.0))
    run_scan(cfg, tmp_path / "out", progress=False, figures=False)
    cfg2 = load_config(_config(tmp_path, lc, 0.0, 30.0, scale=1.1, name="other.toml"))
    with pytest.raises(ValueError, match="different configuration"):
        run_scan(cfg2, tmp_path / "out", progress=False, figures=False)
    run_scan(cfg2, tmp_path / "out", restart=True, progress=False, figures=False)


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda t: t.replace("period = 3.69611590\n", ""), r"missing \['period'\]"),
        (lambda t: t.replace('law = "nonlinear"', 'law = "gaussian"'), "unknown limb-darkening law 'gaussian'"),
        (lambda t: t.replace('path = "data.csv"', 'path = "nowhere.csv"'), "file not found"),
        (lambda t: t.replace("alpha = [0.0, 360.0, 1.0]", "alpha = [10.0, 10.0, 1.0]"), "empty"),
        (lambda t: t.replace('cases = ["same", "opposite"]', 'cases = ["sideways"]'), "unknown case"),
        (lambda t: t.replace("radius = 0.01805", "radius = -0.01805"), "radius must be > 0"),
    ],
)
def test_bad_configs_fail_before_work(tmp_path, edit, match):
    lc = jp.simulate_kepler20(seed=1)
    path = _config(tmp_path, lc)
    path.write_text(edit(path.read_text()))
    with pytest.raises(ValueError, match=match):
        load_config(path)


def test_unreadable_data(tmp_path):
    lc = jp.simulate_kepler20(seed=1)
    path = _config(tmp_path, lc)
    (tmp_path / "data.csv").write_text("time,flux,flux_err\n1.0,abc,0.1\n")
    with pytest.raises(ValueError, match="unreadable row"):
        load_config(path)
    (tmp_path / "data.csv").write_text("when,what\n1,2\n")
    with pytest.raises(ValueError, match="no time column"):
        load_config(path)
