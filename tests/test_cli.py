"""The command line."""

import json
import subprocess
import sys

import pytest

from jaxppo.cli import main


@pytest.mark.parametrize("sub", ["scan", "plot", "simulate", "demo", "fit", "sample", "init"])
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
    # the default is the real long-cadence data: all nine b + c double
    # transits of Q1-Q17 (the paper's seven plus BKJD 160.33 and 496.77),
    # detrended per window, errors from the out-of-transit scatter
    mids = [round(m["mid"], 1) for m in summary["multi_transits"]]
    assert len(mids) == 9 and mids[0] == 160.3 and mids[2] == 496.8
    assert all(abs(m["mid"] - p) < 0.1 for p in (334.02, 670.45, 844.13, 1017.82, 1180.56, 1354.25, 1527.93)
               for m in [min(summary["multi_transits"], key=lambda m: abs(m["mid"] - p))])
    assert summary["exposure"] == 0.0204335982 and summary["supersampling"] > 1
    assert 0.8 < summary["chi2_0"]["same"] / summary["points"] < 1.3
    assert "estimated" in summary["detrending"]["flux_err"]
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


def test_write_failure_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "taken"
    blocker.write_text("a file where the output folder should be")
    cfg = tmp_path / "s.toml"
    from jaxppo._phoenix import data_path

    text = data_path("kepler20_synthetic.toml").read_text().replace('path = "', f'path = "{data_path("")}/')
    cfg.write_text(text.replace("alpha = [0.0, 360.0, 1.0]", "alpha = [0.0, 360.0, 30.0]"))
    assert main(["scan", str(cfg), "--out", str(blocker / "sub"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("jaxppo scan: error: cannot read or write") and "taken" in err
