"""The examples run, with small settings."""

import importlib.util
from pathlib import Path

import numpy as np


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_scan_example(tmp_path):
    res = _load("scan_kepler20").main(["--out", str(tmp_path / "o"), "--step", "4"])
    assert (tmp_path / "o" / "scan.csv").exists() and (tmp_path / "o" / "delta_chi2_api.png").exists()
    assert res.summary["points"] > 100 and 0.8 < res.chi2_0["same"] / res.summary["points"] < 1.3  # real data, errors from scatter
    # the README's scan (the config's [scan] settings; the example once dropped them: 125 points, 146.2)
    assert res.summary["points"] == 111 and abs(res.chi2_0["same"] - 130.4) < 0.05, (res.summary["points"], res.chi2_0)


def test_injected_ppo_example():
    res = _load("injected_ppo").main(["--alpha", "151", "--step", "1"])
    assert abs(res.summary["cases"]["same"]["min_delta_chi2"]["alpha"] - 151) <= 2


def test_sensitivity_example():
    out = _load("sensitivity").main(["--scales", "1.45", "--noises", "4e-4", "--step", "6"])
    assert 0.5 <= list(out.values())[0] < 1.0


def test_fit_q1_example(tmp_path):
    res = _load("fit_kepler20_q1").main(["--out", str(tmp_path / "f.png")])
    assert res.success and (tmp_path / "f.png").exists()
    assert 0.6 < res.reduced_chi2 < 1.6


def _execute(page):
    """A page's Python blocks run by the docs build's executor (docs/hooks.py:
    in order, as one script, from the repository root; what they print and
    draw goes into the build cache the site is then made from)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_hooks", EXAMPLES.parent / "docs" / "hooks.py")
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    result, namespace = hooks.execute_page(page, force=True)
    assert len(result["blocks"]) >= 1
    return result, namespace


def test_tutorial_runs_top_to_bottom():
    """docs/tutorial.md's Python blocks, in order, as one script; the page
    shows their outputs and figures (the site is built from this run)."""
    result, namespace = _execute("tutorial.md")
    assert namespace["res"] is not None and namespace["post"].samples
    assert any(b["figures"] for b in result["blocks"]) and any(b["stdout"] for b in result["blocks"])


def test_getting_started_shows_a_ppo_and_its_gradient():
    """docs/getting-started.md's quickstart: the PPO bump near BKJD 334 at
    alpha = 150 deg (case same), its figure, and d flux / d alpha on the
    bump's flank equal to the central difference."""
    result, namespace = _execute("getting-started.md")
    assert result["blocks"][0]["figures"] and "PPO bump" in result["blocks"][0]["stdout"]
    assert 1e-4 < namespace["bump"].max() < 1e-3
    assert abs(namespace["slope"] - namespace["central"]) <= 1e-6 * abs(namespace["central"]) + 1e-10
    assert abs(namespace["slope"]) > 1e-5


def test_marginal_doc_example_recovers_the_injected_tilt():
    """docs/marginal.md's executed example: with c's t0 4 min late and b's
    a/R* 3 % large the fixed scan's best tilt is far from the injected
    147 deg; the marginal posterior peaks within 3 deg of it."""
    result, namespace = _execute("marginal.md")
    a, d = namespace["a"], namespace["d"]
    assert abs(a[np.argmin(d)] - 147.0) > 90
    peak = namespace["m"].cases["same"]["peak"]
    assert peak is not None and abs(peak["alpha"] - 147.0) <= 3.0, peak
    assert "posterior peak alpha" in result["blocks"][0]["stdout"]


def test_ttv_doc_examples_run():
    """docs/ttv.md's Python blocks, in order, as one script from the
    repository root (the TESS example measures Kepler-51 d's transit)."""
    _, namespace = _execute("ttv.md")
    table = namespace["table"]
    assert len(table) == 1 and abs(float(table["tc"][0]) - 3856.99) < 0.01
    assert namespace["b"].transit_epochs == (0, 1, 2)


def test_scan_doc_three_planet_example_finds_the_ppo_in_its_pair():
    """docs/scan.md's three-planet example: pair t+b's lowest Delta chi^2
    at the injected 10 deg, pair t+d without a detection."""
    _, namespace = _execute("scan.md")
    pairs = namespace["result"].summary["pairs"]
    assert pairs["t+b"]["cases"]["same"]["min_delta_chi2"]["alpha"] == 10.0
    assert pairs["t+d"]["cases"]["same"]["min_delta_chi2"]["value"] > -10.0
