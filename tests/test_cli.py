"""The command line."""

import json
import subprocess
import sys

import pytest

from jaxppo.cli import main


@pytest.mark.parametrize("sub", ["scan", "plot", "simulate", "demo", "fit", "sample"])
def test_help(sub, capsys):
    with pytest.raises(SystemExit) as e:
        main([sub, "--help"])
    assert e.value.code == 0
    assert "usage" in capsys.readouterr().out


def test_default_scan_and_plot(tmp_path):
    out = tmp_path / "run"
    assert main(["scan", "--out", str(out), "--quiet"]) == 0
    for name in ("scan.csv", "summary.json", "fig4_multitransits.png", "fig5_delta_chi2.png", "fig6_cutout.png",
                 "fig7_paths.png", "probabilities.png"):
        assert (out / name).exists(), name
    header = (out / "scan.csv").read_text().splitlines()[0]
    assert header == "case,alpha,chi2,delta_chi2,posterior"
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["chi2_0"]) == {"same", "opposite"}
    assert len(summary["multi_transits"]) == 7
    (out / "fig5_delta_chi2.png").unlink()
    assert main(["plot", str(out)]) == 0
    assert (out / "fig5_delta_chi2.png").exists()


def test_simulate_writes_csv(tmp_path):
    assert main(["simulate", "--out", str(tmp_path / "d.csv"), "--noise", "1e-4", "--alpha", "151"]) == 0
    assert (tmp_path / "d.csv").read_text().startswith("time,flux,flux_err")


def test_bad_config_exits_with_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[star]\nlaw = 'quadratic'\ncoefficients = [0.4]\n")
    proc = subprocess.run([sys.executable, "-m", "jaxppo.cli", "scan", str(bad), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "error" in proc.stderr and "bad.toml" in proc.stderr


def test_fit_and_sample_commands(tmp_path, capsys):
    assert main(["fit", "--free", "b.t0", "c.radius", "--out", str(tmp_path / "fit.json")]) == 0
    fitted = json.loads((tmp_path / "fit.json").read_text())
    assert fitted["success"] and len(fitted["errors"]) == 2
    assert main(["sample", "--free", "c.radius", "--warmup", "20", "--samples", "20", "--quiet",
                 "--out", str(tmp_path / "s.npz")]) == 0
    assert "r_hat" in capsys.readouterr().out
