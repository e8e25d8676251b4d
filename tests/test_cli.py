"""The command line."""

import json
import subprocess
import sys

import numpy as np
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
    # the default is the real long-cadence data: the eight clean b + c double
    # transits of Q1-Q17 (the paper's seven plus 496.77; 160.33 is a b + c + e
    # triple), detrended per window, errors from the out-of-transit scatter
    mids = [round(m["mid"], 1) for m in summary["multi_transits"]]
    assert len(mids) == 8 and mids[0] == 334.0 and mids[1] == 496.8 and 160.3 not in mids
    assert all(abs(m["mid"] - p) < 0.1 for p in (334.02, 670.45, 844.13, 1017.82, 1180.56, 1354.25, 1527.93)
               for m in [min(summary["multi_transits"], key=lambda m: abs(m["mid"] - p))])
    assert summary["exposure"] == 0.0204335982 and summary["supersampling"] > 1
    assert 0.8 < summary["chi2_0"]["same"] / summary["points"] < 1.3
    assert "estimated" in summary["detrending"]["flux_err"]
    (out / "fig5_delta_chi2.png").unlink()
    assert main(["plot", str(out)]) == 0
    assert (out / "fig5_delta_chi2.png").exists()
    # the demo numbers its seven events as this scan does
    import jaxppo as jp
    from jaxppo.obliquity._demo import demo_events as _demo_events

    events, numbers = _demo_events(jp.kepler20_system())
    by_mid = {round(m["mid"], 2): m["number"] for m in summary["multi_transits"]}
    assert numbers == [by_mid[round(e.mid, 2)] for e in events] == [1, 3, 4, 5, 6, 7, 8]
    assert summary["data"]["report"]["kept"] == 64792 and "64792 of 64792 points kept" in summary["data"]["loaded"]
    assert (out / "scan.ecsv").exists()


def test_simulate_writes_csv_and_says_which_transits_carry_the_injected_ppo(tmp_path, capsys):
    """A tilt was injected without a word on whether it gives a PPO: 147 deg
    (the docs' example, which needs --radius-scale 2) gives none in any of
    the seven double transits, and a recovery test then found a flat
    posterior. Now simulate says where the injected tilt occults."""
    assert main(["simulate", "--out", str(tmp_path / "d.csv"), "--noise", "1e-4", "--alpha", "141"]) == 0
    assert (tmp_path / "d.csv").read_text().startswith("time,flux,flux_err")
    assert "PPO at alpha 141 deg (case same) in 1 of 7 double transits (BKJD 1017.82)" in capsys.readouterr().out
    assert main(["simulate", "--out", str(tmp_path / "d.csv"), "--alpha", "147"]) == 0
    assert "no PPO at alpha 147 deg (case same) in any of the 7 double transits" in capsys.readouterr().out
    assert main(["simulate", "--out", str(tmp_path / "d.csv"), "--alpha", "147", "--radius-scale", "2"]) == 0
    assert "in 2 of 7 double transits (BKJD 334.02, 1017.82)" in capsys.readouterr().out


def test_warnings_print_as_one_line(monkeypatch, capsys):
    """The installed command (``run``) prints a warning as its errors are
    printed: one line, no Python file, line number and source echo."""
    from jaxppo.cli import show_warning

    monkeypatch.setattr("sys.argv", ["jaxppo", "scan", "--out", "x"])
    show_warning(UserWarning("draws = 16 is below\n min_ess = 25"), UserWarning, "/x/cli.py", 140, line="m = ...")
    assert capsys.readouterr().err == "jaxppo scan: warning: draws = 16 is below min_ess = 25\n"


def test_an_interrupted_command_says_whether_it_resumes(monkeypatch, capsys):
    import jaxppo.cli as cli

    def stop(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "cmd_simulate", stop)
    assert main(["simulate", "--out", "d.csv"]) == 130
    assert "jaxppo simulate: interrupted (this command does not resume: run it again)" in capsys.readouterr().err


def test_bad_config_exits_with_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[star]\nlaw = 'quadratic'\ncoefficients = [0.4]\n")
    proc = subprocess.run([sys.executable, "-m", "jaxppo.cli", "scan", str(bad), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "error" in proc.stderr and "bad.toml" in proc.stderr


def test_fit_and_sample_commands(tmp_path, capsys):
    import jaxppo as jp

    assert main(["fit", "--free", "b.t0", "c.radius", "--out", str(tmp_path / "fit.json")]) == 0
    fitted = json.loads((tmp_path / "fit.json").read_text())
    assert fitted["success"] and len(fitted["errors"]) == 2
    back = jp.FitResult.load(tmp_path / "fit.json")
    assert back.names == ("b.t0", "c.radius") and back.success
    captured = capsys.readouterr()
    assert "fit: " in captured.err and "Levenberg-Marquardt pass 1" in captured.err  # progress, one line per stage
    # the same fit quietly: its model's compiled programs are the first fit's
    assert main(["fit", "--free", "b.t0", "c.radius", "--quiet"]) == 0
    assert "fit: " not in capsys.readouterr().err
    assert main(["sample", "--free", "c.radius", "--warmup", "20", "--samples", "20", "--quiet",
                 "--out", str(tmp_path / "s.npz")]) == 0
    assert "r_hat" in capsys.readouterr().out
    post = jp.SampleResult.load(tmp_path / "s.npz")
    assert post.names == ("c.radius",) and post.chains["c.radius"].shape == (4, 20)


@pytest.mark.parametrize("cmd", ["fit", "sample"])
def test_repeated_free_options_add_up(cmd, monkeypatch, capsys):
    """Issue 24 item 4: "--free b.t0 --free c.t0" fitted only c.t0 (the
    second option replaced the first)."""
    import jaxppo as jp

    seen = []

    def fake(system, lc, free, **kw):
        seen.append(free)
        raise ValueError("stop here")

    monkeypatch.setattr(jp, cmd, fake)
    for argv, free in ((["--free", "b.t0", "--free", "c.t0"], ("b.t0", "c.t0")),
                       (["--free", "b.t0", "c.t0", "--free", "b.radius"], ("b.t0", "c.t0", "b.radius")),
                       (["--free", "b.t0", "c.t0"], ("b.t0", "c.t0")),
                       ([], ("b.t0", "b.radius", "c.t0", "c.radius"))):
        assert main([cmd, *argv]) == 2 and seen[-1] == free, argv
    n = len(seen)
    assert main([cmd, "--free", "b.t0", "--free", "b.t0", "c.t0"]) == 2 and len(seen) == n
    assert "--free names b.t0 more than once" in capsys.readouterr().err


def test_default_free_names_follow_the_config(tmp_path, monkeypatch):
    """Without --free: the config's [fit] free, else every planet's t0 and
    radius, and a planet with transit times has its times free ("b.tc"):
    the default "b.t0" of such a planet failed with an error about a name
    the user never gave."""
    import jaxppo as jp
    from jaxppo.obliquity._config import synthetic_config_path

    seen = []

    def fake(system, lc, free, **kw):
        seen.append(free)
        raise ValueError("stop here")

    monkeypatch.setattr(jp, "fit", fake)
    text = synthetic_config_path().read_text().replace(
        'path = "kepler20_synthetic_bc.csv"', f'path = "{synthetic_config_path().parent / "kepler20_synthetic_bc.csv"}"')
    cfg = tmp_path / "c.toml"
    times = 'transit_times = [134.501962, 138.198073]\n'
    cfg.write_text(text.replace('name = "b"\n', 'name = "b"\n' + times, 1))
    assert main(["fit", str(cfg)]) == 2 and seen[-1] == ("b.tc", "b.radius", "c.t0", "c.radius")
    cfg.write_text(text + '\n[fit]\nfree = ["c.inc", "b.radius"]\n')
    assert main(["fit", str(cfg)]) == 2 and seen[-1] == ("c.inc", "b.radius")


def test_sample_prior_option(monkeypatch, capsys):
    import numpyro.distributions as dist

    import jaxppo as jp

    seen = {}

    def fake_sample(system, lc, **kw):
        seen.update(kw)
        raise ValueError("stop here")

    monkeypatch.setattr(jp, "sample", fake_sample)
    assert main(["sample", "--free", "b.t0", "b.radius", "--prior", "b.t0", "normal", "131.5", "1e-4",
                 "--prior", "b.radius", "loguniform", "0.01", "0.05"]) == 2
    pr = seen["priors"]
    assert isinstance(pr["b.t0"], dist.Normal) and float(pr["b.t0"].loc) == 131.5 and float(pr["b.t0"].scale) == 1e-4
    assert isinstance(pr["b.radius"], dist.LogUniform) and float(pr["b.radius"].low) == 0.01
    capsys.readouterr()
    assert main(["sample", "--prior", "b.t0", "gamma", "1", "2"]) == 2
    assert "unknown kind 'gamma'" in capsys.readouterr().err
    assert main(["sample", "--prior", "b.t0", "normal", "1", "-2"]) == 2
    assert "SD must be > 0" in capsys.readouterr().err


def test_fit_windows_are_the_scans_detrended_windows(monkeypatch, capsys):
    """On the real Kepler-20 data, --windows must fit the scan's detrended
    windows (flux divided by each window's out-of-transit polynomial), not
    the raw PDCSAP flux with its stellar variability."""
    import jaxppo as jp
    from jaxppo.obliquity._config import default_config_path, load_config
    from jaxppo.obliquity._windows import scan_windows

    seen = {}

    def fake_fit(system, lc, free, **kw):
        seen["lc"] = lc
        raise ValueError("stop here")

    monkeypatch.setattr(jp, "fit", fake_fit)
    assert main(["fit", str(default_config_path()), "--windows", "--free", "b.t0"]) == 2
    wins = scan_windows(load_config())
    lc = seen["lc"]
    t = np.concatenate([w.time for w in wins])
    assert len(lc) == np.unique(t).size
    ref = {float(ti): float(fi) for w in wins for ti, fi in zip(w.time, w.flux)}
    assert np.array_equal(lc.flux, np.array([ref[float(ti)] for ti in lc.time]))
    assert "detrended multi-transit windows" in capsys.readouterr().out


def test_write_failure_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "taken"
    blocker.write_text("a file where the output folder should be")
    cfg = tmp_path / "s.toml"
    from jaxppo.model._phoenix import data_path

    text = data_path("kepler20_synthetic.toml").read_text().replace('path = "', f'path = "{data_path("")}/')
    cfg.write_text(text.replace("alpha = [0.0, 360.0, 1.0]", "alpha = [0.0, 360.0, 30.0]"))
    assert main(["scan", str(cfg), "--out", str(blocker / "sub"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("jaxppo scan: error: --out ") and "taken is a file, not a folder" in err


# ---- item 10: version, help, --alpha, one-line errors, plot anywhere, resume ----------

def test_version(capsys):
    import jaxppo

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"jaxppo {jaxppo.__version__}"


def test_every_option_has_help_with_its_default():
    from jaxppo.cli import build_parser

    parser = build_parser()
    subs = next(a for a in parser._actions if a.dest == "command").choices
    for name in ("scan", "plot", "init", "simulate", "demo", "fit", "sample"):
        for action in subs[name]._actions:
            if action.dest == "help":
                continue
            assert action.help, (name, action.dest)
            if not action.required and action.nargs != "?" or action.default is not None:
                assert "default" in action.help, (name, action.dest, action.help)
    helps = {(n, a.dest): a.help for n in ("scan", "simulate") for a in subs[n]._actions}
    assert "[deg]" in helps[("scan", "alpha")] and "[deg]" in helps[("simulate", "alpha")]
    assert "[relative flux]" in helps[("simulate", "noise")]
    desc = subs["fit"].description
    assert all(u in desc for u in ("[d]", "[deg]", "[R*]", "[relative flux]", "q1 q2", "lc.jitter", "lc.baseline"))


def _synthetic_copy(folder):
    """The bundled synthetic config and data, copied (relative data path)."""
    from jaxppo.model._phoenix import data_path

    folder.mkdir()
    for name in ("kepler20_synthetic.toml", "kepler20_synthetic_bc.csv"):
        (folder / name).write_bytes(data_path(name).read_bytes())
    return folder / "kepler20_synthetic.toml"


def test_alpha_option_plot_anywhere_and_finished_rerun(tmp_path, monkeypatch, capsys):
    """--alpha replaces the config's grid (and is part of the digest); plot
    works from another folder with a config given by a relative path (the
    old plot re-read the relative path from the current folder and failed);
    a rerun of a finished scan says so and recomputes and redraws nothing."""
    import jaxppo.obliquity._figures
    import jaxppo.obliquity._scan

    cfg = _synthetic_copy(tmp_path / "cfg")
    monkeypatch.chdir(tmp_path / "cfg")
    assert main(["scan", cfg.name, "--out", "../run", "--alpha", "0", "360", "45", "--quiet"]) == 0
    run = tmp_path / "run"
    rows = (run / "scan.csv").read_text().splitlines()[1:]
    assert len(rows) == 16 and [float(r.split(",")[1]) for r in rows[:8]] == [0, 45, 90, 135, 180, 225, 270, 315]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["alpha"] == {"start": 0.0, "stop": 360.0, "step": 45.0}
    first = capsys.readouterr().out
    assert "data: 2926 of 2926 points kept" in first and "scanned 2 case(s) x 8 alphas" in first
    stamps = {p.name: p.stat().st_mtime_ns for p in run.iterdir() if p.suffix in (".png", ".csv", ".ecsv")}

    def boom(*a, **k):
        raise AssertionError("recomputed or redrawn")

    with monkeypatch.context() as m:
        m.setattr(jaxppo.obliquity._scan, "no_ppo_model", boom)
        m.setattr(jaxppo.obliquity._scan, "grid_chi2", boom)
        m.setattr(jaxppo.obliquity._figures, "scan_figures", boom)
        assert main(["scan", cfg.name, "--out", "../run", "--alpha", "0", "360", "45", "--quiet"]) == 0
    again = capsys.readouterr().out
    assert "resumed: the scan in ../run had already finished with this config (16 (case, alpha) points" in again
    assert "nothing recomputed or redrawn" in again and "scanned" not in again
    assert {p.name: p.stat().st_mtime_ns for p in run.iterdir() if p.suffix in (".png", ".csv", ".ecsv")} == stamps
    # a different grid in the same folder is refused, naming what changed and the way out
    assert main(["scan", cfg.name, "--out", "../run", "--alpha", "0", "360", "90", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "different configuration" in err and "changed: scan.alpha)" in err and "--restart" in err
    # plot from an unrelated folder
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    (run / "fig5_delta_chi2.png").unlink()
    assert main(["plot", str(run)]) == 0
    assert (run / "fig5_delta_chi2.png").exists()


@pytest.mark.parametrize("argv, needle", [
    (["scan", "--alpha", "0", "360", "7"], "error: --alpha = [0, 360, 7]: alpha covers 0 .. 357 deg"),
    (["scan", "--alpha", "0", "180", "1"], "error: --alpha = [0, 180, 1]: alpha covers 0 .. 179 deg"),
    (["scan", "--alpha", "0", "360", "0"], "error: --alpha step must be > 0"),
    (["scan", "--alpha", "0", "x", "1"], "error: argument --alpha: not a number: 'x'"),
    (["scan", "--alpha", "0", "360"], "error: argument --alpha: expected 3 arguments"),
    (["simulate", "--out", "d.csv", "--noise", "nan"], "error: argument --noise: must be a finite number, got 'nan'"),
    (["simulate", "--out", "d.csv", "--noise", "-1"], "error: --noise must be > 0"),
    (["simulate", "--out", "d.csv", "--radius-scale", "0"], "error: --radius-scale must be > 0"),
    (["simulate", "--out", "missing/d.csv"], "the folder missing does not exist"),
    (["simulate", "--out", "."], "is a folder; give a file name"),
    (["simulate", "--out", "d.csv", "--seed", "1.5"], "argument --seed: must be an integer, got '1.5'"),
    (["plot", "nowhere"], "error: DIR nowhere: no such folder"),
    (["plot", "a_file"], "error: DIR a_file is a file"),
    (["plot", "."], "holds no finished scan (summary.json missing)"),
    (["scan", "."], "error: config . is a folder, not a TOML file"),
    (["scan", "--out", "a_file/sub"], "error: --out a_file/sub: a_file is a file, not a folder"),
    (["demo", "--out", "a_file"], "error: --out a_file: a_file is a file, not a folder"),
    (["init", "sub/x.toml"], "error: PATH sub/x.toml: the folder sub does not exist"),
    (["simulate", "--out", "a_file/x.csv"], "error: --out a_file/x.csv: a_file is a file, not a folder"),
    (["scan", "--qiet"], "error: unrecognized arguments: --qiet"),
    (["activity", "--spots", "-2"], "error: --spots must be an integer in 1..6, got -2"),
    (["activity", "--period-min", "9", "--period-max", "3"], "error: --period-min and --period-max must satisfy"),
])
def test_errors_are_one_line(argv, needle, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_file").write_text("x")
    try:
        rc = main(argv)
    except SystemExit as e:  # argparse errors
        rc = e.code
    assert rc == 2
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err.count("\n") == 1 and "Traceback" not in cap.err, cap.err
    assert cap.err.startswith(f"jaxppo {argv[0]}: error: ") and needle in cap.err, cap.err


def test_unexpected_errors_are_one_line(tmp_path, monkeypatch, capsys):
    import jaxppo.obliquity._config

    def broken(*a, **k):
        raise KeyError("x")

    monkeypatch.setattr(jaxppo.obliquity._config, "load_config", broken)
    assert main(["scan", "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("jaxppo scan: internal error: KeyError") and "report" in err


def test_activity_command(tmp_path, capsys):
    """`jaxppo activity` on the bundled real data: the rotation period lies
    in the documented range (docs/activity.md), strict JSON and figures are
    written, and a bad --spot-chunk is one error line naming the option."""
    import json

    from jaxppo.cli import main

    assert main(["activity", "--out", str(tmp_path / "a"), "--bootstrap", "0"]) == 0
    printed = capsys.readouterr().out
    assert "rotation period" in printed
    rep = json.loads((tmp_path / "a" / "activity.json").read_text(), parse_constant=lambda c: 1 / 0)
    assert 26.0 < rep["rotation"]["period_d"] < 29.0
    assert (tmp_path / "a" / "activity_map.png").is_file()
    assert main(["activity", "--out", str(tmp_path / "b"), "--spot-chunk", "x"]) == 2
    assert "--spot-chunk must be a chunk index or 'all'" in capsys.readouterr().err


def test_activity_of_another_file_says_what_the_kepler20_mask_took(tmp_path, capsys):
    """`jaxppo activity --data FILE` masks the transits of Kepler-20 b-f by
    their bundled ephemerides, whatever star FILE holds (a review: 18 % of
    another star's points gone, said in activity.json alone): the output
    says how many points the mask took and how to keep them."""
    from jaxppo.cli import main

    t = np.arange(131.5, 400.0, 0.0204)
    f = 1e4 * (1.0 + 2e-3 * np.sin(2 * np.pi * t / 11.3))
    np.savetxt(tmp_path / "star.csv", np.column_stack([t, f]), delimiter=",", header="time,flux", comments="")
    assert main(["activity", "--data", str(tmp_path / "star.csv"), "--out", str(tmp_path / "a"), "--bootstrap",
                 "0"]) == 0
    printed = capsys.readouterr().out
    line = next(ln for ln in printed.splitlines() if ln.startswith("masked the transits of Kepler-20 b-f"))
    masked = int(line.split(": ")[1].split(" of ")[0])
    assert 0 < masked < t.size and f"of {t.size} points (--no-transit-mask keeps them" in line
    assert main(["activity", "--data", str(tmp_path / "star.csv"), "--out", str(tmp_path / "b"), "--bootstrap",
                 "0", "--no-transit-mask"]) == 0
    assert "masked the transits" not in capsys.readouterr().out


def test_scan_marginalize_and_joint_options_call_their_workflows(tmp_path, monkeypatch, capsys):
    """--marginalize N runs jp.marginal_scan after the plain scan with the
    config's [fit] free and the fixed scan's result (the marginal scan itself
    is tested in tests/obliquity/test_marginal.py); a negative N is one error line."""
    import jaxppo.obliquity._marginal as marginal
    from jaxppo.cli import main

    seen = {}

    class Fake(dict):
        summary = {"cases": {"same": {"reliable": False}}}

        def summary_lines(self):
            return ["marginal: fake"]

    def fake(cfg, draws, out, fixed, free, restart, progress):
        seen.update(draws=draws, fixed=fixed.summary["config_digest"] == cfg.digest, free=free)
        return Fake()

    import jaxppo.obliquity._joint as joint

    case = {"geometries": {"g1": {"probability": 0.25, "error": 0.01}, "g2": {"probability": 0.75, "error": 0.01}},
            "favoured": "g2", "jeffreys": "substantial", "alpha_peak": 147.5, "alpha_68": [146.0, 149.0],
            "log_z": -10.0, "log_z_error": 0.1, "ess": [200.0, 210.0], "posterior": [1 / 360] * 360,
            "particles": {"alpha": [147.0], "weight": [1.0]}}
    fake_joint = {"method": "fake SMC", "seconds": 1.0, "cases": {"same": case, "opposite": case},
                  "case_bayes_factors": {"same/opposite": 1.0}, "case_log_bayes_factors": {"same/opposite": 0.0}}

    def fake_joint_scan(cfg, particles, out, free, restart, progress, fixed):
        seen.update(particles=particles, joint_fixed=fixed is not None and fixed.config_digest == cfg.digest)
        return fake_joint

    monkeypatch.setattr(marginal, "marginal_scan", fake)
    monkeypatch.setattr(joint, "joint_scan", fake_joint_scan)
    assert main(["scan", "--out", str(tmp_path / "o"), "--quiet", "--alpha", "0", "360", "10",
                 "--marginalize", "3", "--joint", "64"]) == 0
    assert seen == {"draws": 3, "fixed": True, "free": None, "particles": 64, "joint_fixed": True}
    printed = capsys.readouterr().out
    assert "marginal: fake" in printed and "g2: 75.00 +- 1.00 %" in printed and "alpha peak 147.5" in printed
    # summary.json carries the marginal block (issue 22: marginal.cases.<case>...) and the
    # joint block (without the particles) beside it
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["marginal"] == Fake.summary and "probabilities" in summary
    assert summary["joint"]["cases"]["same"]["geometries"]["g2"]["probability"] == 0.75
    assert "particles" not in summary["joint"]["cases"]["same"]
    for bad in (["--marginalize", "-2"], ["--joint", "8"], ["--joint", "x"]):
        with pytest.raises(SystemExit) as exit_:
            main(["scan", "--out", str(tmp_path / "o")] + bad)
        assert exit_.value.code == 2 and bad[0] in capsys.readouterr().err


def test_persistent_compilation_cache(tmp_path):
    """Commands keep JAX's compiled programs in JAXPPO_CACHE_DIR (a second
    run does not recompile); JAXPPO_CACHE=0 switches the cache off."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, JAXPPO_CACHE_DIR=str(tmp_path / "cache"), JAXPPO_CACHE="1")
    cmd = [sys.executable, "-m", "jaxppo.cli", "simulate", "--out", str(tmp_path / "d.csv")]
    subprocess.run(cmd, env=env, check=True, capture_output=True)
    assert any((tmp_path / "cache").iterdir())
    env = dict(os.environ, JAXPPO_CACHE_DIR=str(tmp_path / "off"), JAXPPO_CACHE="0")
    subprocess.run(cmd, env=env, check=True, capture_output=True)
    assert not (tmp_path / "off").exists()


def test_scan_order_and_no_deprecation_notes(tmp_path, capsys):
    """jaxppo scan runs the scan, then the figures, then the PPO-or-spot
    step (its block in summary.json), and jaxppo's own code reads results
    through attributes: no DeprecationWarning note on stderr."""
    from jaxppo.cli import main

    out = tmp_path / "s"
    assert main(["scan", str(_synthetic_copy(tmp_path / "cfg")), "--out", str(out), "--alpha", "0", "360", "30", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "deprecated" not in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary)[-3:] == ["table5_files", "figures", "ppo_or_spot"]
    assert len(summary["figures"]) == 5 and "dips" in summary["ppo_or_spot"]


def test_bad_input_is_a_usage_error_naming_the_option(tmp_path, capsys):
    """A tilt grid of 3.6e11 angles ended in "internal error: MemoryError"
    (exit 1); a negative seed named neither the option nor the value."""
    assert main(["scan", "--out", str(tmp_path / "o"), "--alpha", "0", "360", "1e-9"]) == 2
    err = capsys.readouterr().err
    assert "--alpha" in err and "at most 360000" in err and "MemoryError" not in err
    with pytest.raises(SystemExit) as exit_:
        main(["simulate", "--out", str(tmp_path / "d.csv"), "--seed", "-5"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "--seed" in err and "-5" in err


def test_plot_names_a_truncated_scan_csv(tmp_path, capsys):
    assert main(["scan", "--out", str(tmp_path / "o"), "--quiet", "--alpha", "0", "360", "10"]) == 0
    csv_path = tmp_path / "o" / "scan.csv"
    lines = csv_path.read_text().splitlines()
    csv_path.write_text("\n".join(lines[:5]) + "\n" + lines[5].split(",")[0] + ",12\n")
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "scan.csv" in err and "rerun" in err


def test_outputs_are_what_the_scan_says(tmp_path, monkeypatch, capsys):
    """The scan printed "5 figures" and wrote 6 (ppo_or_spot.png); summary.json
    held paths relative to the working directory; --restart kept the old
    ppo_or_spot.png. Now the count is the files, every path resolves from
    anywhere, and a restart with no dip to judge leaves no stale figure."""
    import json as _json
    from pathlib import Path

    monkeypatch.chdir(tmp_path)
    assert main(["scan", "--out", "o", "--quiet", "--alpha", "0", "360", "10"]) == 0
    said = capsys.readouterr().out
    pngs = sorted(p.name for p in (tmp_path / "o").glob("*.png"))
    assert f"and {len(pngs)} figures" in said and "ppo_or_spot.png" in pngs
    summary = _json.loads((tmp_path / "o" / "summary.json").read_text())
    paths = summary["figures"] + summary["table5_files"] + [summary["ppo_or_spot"]["figure"]]
    assert all(Path(p).is_absolute() and Path(p).is_file() for p in paths), paths
    # docs/cli.md names every file the scan leaves and every column of table5.csv
    # (table5.csv/.md and ppo_or_spot.png were missing, the columns undocumented)
    doc = (Path(__file__).resolve().parents[1] / "docs" / "cli.md").read_text()
    written = sorted(p.name for p in (tmp_path / "o").iterdir() if p.is_file())
    assert [n for n in written if f"`{n}`" not in doc] == [], written
    columns = (tmp_path / "o" / "table5.csv").read_text().splitlines()[0].split(",")
    assert [c for c in columns if f"`{c}`" not in doc] == [], columns
    (tmp_path / "o" / "ppo_or_spot.png").write_bytes(b"stale")
    from jaxppo.obliquity._scan import _clear_outputs

    _clear_outputs(tmp_path / "o")
    assert not (tmp_path / "o" / "ppo_or_spot.png").exists()


def test_ttv_on_real_kepler51_recovers_published_times(tmp_path, capsys):
    """`jaxppo ttv` on the bundled REAL Kepler-51 long cadence: 51 transits
    of b, c and d measured together (the shapes fixed, a jitter free); the
    times agree with jnkepler's published Kepler-51 times within their
    errors (every epoch within 2 sigma, median |z| < 1), the O-C of every
    planet is far from a linear ephemeris, and chi^2 per point is near 1."""
    from pathlib import Path

    import jaxppo

    cfg = Path(jaxppo.__file__).parent / "data" / "kepler51" / "kepler51_llc.toml"
    assert main(["ttv", str(cfg), "--out", str(tmp_path), "--quiet"]) == 0
    summary = json.loads((tmp_path / "ttv_summary.json").read_text())
    assert summary["fit"]["success"] and 0.9 < summary["fit"]["reduced_chi2"] < 1.1
    assert {p: e["transits"] for p, e in summary["planets"].items()} == {"b": 29, "c": 13, "d": 9}
    assert all(e["chi2_linear"] > 3 * e["transits"] for e in summary["planets"].values())
    ref = summary["reference"]["kepler51_transit_times_jnkepler.csv"]
    for planet, c in ref.items():
        assert c["n"] >= 9 and c["within_2sigma"] == 1.0 and c["median_abs_z"] < 1.0, (planet, c)
    assert sorted(summary["figures"]) == ["oc_b.png", "oc_c.png", "oc_d.png"]
    from astropy.table import Table

    table = Table.read(tmp_path / "transit_times.ecsv")
    assert table.colnames == ["planet", "epoch", "tc", "tc_err", "chi2", "n_points"] and len(table) == 51
    assert "against kepler51_transit_times_jnkepler.csv" in capsys.readouterr().out


def test_the_installed_command_freezes_its_objects_before_it_exits(monkeypatch, capsys):
    """The console script is ``jaxppo.cli:run``: ``main``'s status, then
    ``gc.freeze()`` (the interpreter's last collection has nothing to walk);
    ``main`` itself leaves the collector alone."""
    import gc
    import tomllib
    from pathlib import Path

    from jaxppo import cli

    pyproject = tomllib.loads((Path(cli.__file__).parents[1] / "pyproject.toml").read_text())
    assert pyproject["project"]["scripts"]["jaxppo"] == "jaxppo.cli:run"
    frozen = []
    monkeypatch.setattr(gc, "freeze", lambda: frozen.append(True))
    monkeypatch.setattr("sys.argv", ["jaxppo", "plot", "/no/such/folder"])
    assert main(["plot", "/no/such/folder"]) == 2 and not frozen
    assert cli.run() == 2 and frozen == [True]
    assert "no such folder" in capsys.readouterr().err


def test_python_m_jaxppo_is_the_command():
    """``python -m jaxppo`` runs the same command (no module ran before)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "jaxppo", "plot", "/no/such/folder"], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 2 and "no such folder" in out.stderr and "jaxppo plot" in out.stderr, out
    help_text = subprocess.run([sys.executable, "-m", "jaxppo", "--help"], capture_output=True, text=True, timeout=120)
    assert help_text.returncode == 0 and help_text.stdout.startswith("usage: jaxppo"), help_text


@pytest.mark.parametrize("argv", [["fit", "--out", "{data}"], ["sample", "--out", "{config}"],
                                  ["sample", "--netcdf", "{data}"]])
def test_fit_and_sample_never_write_over_their_inputs(argv, tmp_path, capsys):
    """``jaxppo fit --out DATA.csv`` replaced the light curve it had just
    read with the fit's JSON."""
    cfg = _synthetic_copy(tmp_path / "c")
    files = {"config": cfg, "data": cfg.parent / "kepler20_synthetic_bc.csv"}
    before = {k: p.read_bytes() for k, p in files.items()}
    args = [argv[0], str(cfg), *(a.format(**files) for a in argv[1:])]
    if "--netcdf" in argv:
        pytest.importorskip("arviz")
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "that file is an input of this run" in err and err.count("\n") == 1, err
    assert {k: p.read_bytes() for k, p in files.items()} == before


def test_ttv_and_demo_never_write_over_inputs_or_a_scans_summary(tmp_path, capsys):
    """``jaxppo ttv`` replaced a [ttv] reference table that lay where it
    writes transit_times.ecsv (an earlier run's, as docs/ttv.md suggests
    using them); ``jaxppo demo --out`` replaced a finished scan's
    summary.json; a config's data given as a list was not protected."""
    from jaxppo.model._phoenix import data_path
    from jaxppo.obliquity._config_files import config_inputs

    src = data_path("kepler51/kepler51_llc.toml").parent
    for name in ("kepler51_llc.toml", "kepler51_llc_no_overlap.csv", "kepler51_transit_times_jnkepler.csv"):
        (tmp_path / name).write_bytes((src / name).read_bytes())
    text = (tmp_path / "kepler51_llc.toml").read_text()
    text = text.replace('reference = ["kepler51_transit_times_holczer2016.csv", "kepler51_transit_times_jnkepler.csv"]',
                        'reference = ["out/transit_times.ecsv"]')
    (tmp_path / "k.toml").write_text(text)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "transit_times.ecsv").write_bytes((tmp_path / "kepler51_transit_times_jnkepler.csv").read_bytes())
    assert main(["ttv", str(tmp_path / "k.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert "ttv would write" in capsys.readouterr().err
    (tmp_path / "scan").mkdir()
    (tmp_path / "scan" / "summary.json").write_text('{"config_digest": "x"}')
    (tmp_path / "scan" / "scan_progress.jsonl").write_text("")
    assert main(["demo", "--out", str(tmp_path / "scan")]) == 2
    assert "holds a summary.json the demo did not write" in capsys.readouterr().err
    assert (tmp_path / "scan" / "summary.json").read_text() == '{"config_digest": "x"}'
    (tmp_path / "l.toml").write_text(text.replace('path = "kepler51_llc_no_overlap.csv"', 'path = ["a.csv", "b.csv"]'))
    assert {(tmp_path / n).resolve() for n in ("a.csv", "b.csv")} <= config_inputs(tmp_path / "l.toml")
