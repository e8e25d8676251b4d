"""The scan under several JAX processes (jax.distributed, CPU collectives
over gloo), as a user starts it from the command line: the same numbers as
one process, the folder written once (by process 0), an interrupted run
resumed consistently by every process, one report printed; every other
command computes in every process and writes its files once (process 0);
bad settings are refused, named."""

import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(tmp_path, **extra):
    from helpers import one_device_env  # (here: the workers below import this module without tests/ on sys.path)

    return one_device_env(JAXPPO_CACHE_DIR=str(tmp_path / "cache"), **extra)


SCAN = [sys.executable, "-m", "jaxppo.cli", "scan", "--alpha", "0", "360", "2", "--quiet"]


def test_two_processes_resume_and_write_the_scan_of_one(tmp_path):
    from jaxppo.cli import main

    one, two = tmp_path / "one", tmp_path / "two"
    assert main(SCAN[3:] + ["--out", str(one)]) == 0  # one process: this one
    # an interrupted run: the progress file holds the header and the first block only
    two.mkdir()
    lines = (one / "scan_progress.jsonl").read_text().splitlines(keepends=True)
    (two / "scan_progress.jsonl").write_text("".join(lines[:2]))
    shutil.copy(one / "config.json", two / "config.json")
    # process 1 runs where --out does not exist (as on another host without
    # a shared file system): process 0 alone reads and writes it
    host1 = tmp_path / "host1"
    host1.mkdir()
    outs = _two_processes(tmp_path, ["--out", "two"], (tmp_path, host1))

    def report(text):  # what jaxppo printed (gloo's C++ library prints its connection line itself)
        return [ln for ln in text.splitlines() if not ln.startswith("[Gloo]")]

    assert any("prograde" in ln for ln in report(outs[0][0]))  # process 0 reports
    assert report(outs[1][0]) == []  # process 1 prints nothing
    a = np.genfromtxt(one / "scan.csv", delimiter=",", names=True, dtype=None, encoding=None)
    b = np.genfromtxt(two / "scan.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert list(a["case"]) == list(b["case"])
    for col in ("alpha", "chi2", "delta_chi2", "posterior"):
        np.testing.assert_allclose(b[col], a[col], rtol=1e-12, atol=1e-12)
    s1, s2 = (json.loads((d / "summary.json").read_text()) for d in (one, two))
    assert (s1["devices"], s1["processes"]) == (1, 1)
    assert (s2["devices"], s2["processes"]) == (2, 2)
    assert s2["resumed"]["alphas_done_before"] == 60 and s2["resumed"]["alphas_total"] == 360
    assert s2["probabilities"] == s1["probabilities"]
    # written once: the progress file holds each block once, no temporary file is left behind
    recs = [json.loads(ln) for ln in (two / "scan_progress.jsonl").read_text().splitlines()[1:]]
    keys = [(r["case"], a) for r in recs for a in r["alpha"]]
    assert len(keys) == len(set(keys)) == 360
    assert not list(two.glob("*.tmp*"))
    assert {f.name for f in two.iterdir()} >= {f.name for f in one.iterdir()}
    assert not any(host1.iterdir())
    # an error of process 0 while it reads the folder (another config's results) stops both, by name
    outs = _two_processes(tmp_path, ["--out", "two", "--alpha", "0", "360", "3"], (tmp_path, host1), check=False)
    for out, err in outs:
        assert "holds results of a different configuration" in err, err[-2000:]
    # a write of process 0 that fails after the scan (scan.csv cannot be
    # replaced: here a folder; on a cluster a full disk) stops both, by name
    # (old code: process 0 raised alone, process 1 waited in the final barrier);
    # the scan itself resumes from one's finished progress (every alpha done:
    # the chi^2 blocks are not computed a third time), its analysis and the
    # write of its tables then run as in any scan
    (tmp_path / "three" / "scan.csv").mkdir(parents=True)
    for name in ("scan_progress.jsonl", "config.json"):
        shutil.copy(one / name, tmp_path / "three" / name)
    outs = _two_processes(tmp_path, ["--out", "three"], (tmp_path, host1), check=False)
    for out, err in outs:
        assert "process 0 failed while writing the scan's tables into three" in err, err[-2000:]


def _two_processes(tmp_path, args, cwds, check=True, command=SCAN):
    """Run ``command`` (default ``jaxppo scan``) ``args`` as two JAX
    processes (gloo on localhost) in the folders ``cwds``; their (stdout,
    stderr)."""
    port = str(_free_port())
    procs = [subprocess.Popen(command + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
                              env=_env(tmp_path, JAXPPO_DISTRIBUTED="2", JAXPPO_PROCESS_ID=str(i),
                                       JAX_COORDINATOR_ADDRESS="127.0.0.1:" + port))
             for i, cwd in enumerate(cwds)]
    try:
        outs = [p.communicate(timeout=600) for p in procs]
    finally:  # a hung process (the failure these tests guard) must not outlive the test
        for p in procs:
            p.kill()
    if check:
        assert all(p.returncode == 0 for p in procs), "\n".join(o[1][-3000:] for o in outs)
    else:
        assert all(p.returncode == 2 for p in procs), "\n".join(o[1][-3000:] for o in outs)
    return outs


def _printed(text) -> list:
    """What jaxppo printed (gloo's C++ library prints its connection line itself)."""
    return [ln for ln in text.splitlines() if not ln.startswith("[Gloo]")]


def test_every_command_runs_under_two_processes_and_writes_once(tmp_path):
    """`fit`, `simulate`, `init`, `ttv` and `plot` under two JAX processes
    (process 1 in a folder without the outputs, as on another host): the
    numbers of one process, each file written once, by process 0, one
    report (old code: every command but the scan refused; with the
    refusal lifted, each process wrote every file)."""
    import jaxppo as jp

    cli = [sys.executable, "-m", "jaxppo.cli"]
    a, b = tmp_path / "host0", tmp_path / "host1"
    a.mkdir(), b.mkdir()
    outs = _two_processes(tmp_path, ["fit", "--quiet", "--out", "fit.json"], (a, b), command=cli)
    assert any("wrote fit.json" in ln for ln in _printed(outs[0][0])) and _printed(outs[1][0]) == []
    from jaxppo.cli import main

    assert main(["fit", "--quiet", "--out", str(tmp_path / "fit_one.json")]) == 0
    two, one = jp.FitResult.load(a / "fit.json"), jp.FitResult.load(tmp_path / "fit_one.json")
    np.testing.assert_allclose(two.values, one.values, rtol=1e-12, atol=0)
    np.testing.assert_allclose(two.errors, one.errors, rtol=1e-9, atol=0)
    assert two.chi2 == pytest.approx(one.chi2, rel=1e-12)
    _two_processes(tmp_path, ["simulate", "--out", "sim.csv", "--alpha", "150"], (a, b), command=cli)
    assert main(["simulate", "--out", str(tmp_path / "sim_one.csv"), "--alpha", "150"]) == 0
    assert (a / "sim.csv").read_text() == (tmp_path / "sim_one.csv").read_text()
    _two_processes(tmp_path, ["init", "cfg.toml"], (a, b), command=cli)
    assert "[system]" in (a / "cfg.toml").read_text()
    # ttv: the transit times of one planet of the bundled real Kepler-51 data
    cfg = Path(jp.__file__).parent / "data" / "kepler51" / "kepler51_llc.toml"
    _two_processes(tmp_path, ["ttv", str(cfg), "--planets", "d", "--out", "ttv", "--quiet"], (a, b), command=cli)
    assert main(["ttv", str(cfg), "--planets", "d", "--out", str(tmp_path / "ttv_one"), "--quiet"]) == 0
    from astropy.table import Table

    t2, t1 = (Table.read(d / "transit_times.ecsv") for d in (a / "ttv", tmp_path / "ttv_one"))
    assert len(t1) == 9
    np.testing.assert_allclose(np.asarray(t2["tc"]), np.asarray(t1["tc"]), rtol=0, atol=1e-10)
    assert sorted(p.name for p in (a / "ttv").iterdir()) == ["oc_d.png", "transit_times.ecsv", "ttv_summary.json"]
    # plot: the figures of a finished scan in process 0's folder (process 1 has none)
    assert main(SCAN[3:] + ["--out", str(a / "scan")]) == 0
    for f in (a / "scan").glob("*.png"):
        f.unlink()
    outs = _two_processes(tmp_path, ["plot", "scan"], (a, b), command=cli)
    assert len(list((a / "scan").glob("fig*.png"))) == 4 and _printed(outs[1][0]) == []
    assert sorted(p.name for p in b.iterdir()) == []
    assert not list(a.rglob("*.tmp*"))


def test_bad_distributed_settings_are_refused_by_name(tmp_path):
    run = subprocess.run(SCAN + ["--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=120,
                         env=_env(tmp_path, JAXPPO_DISTRIBUTED="two"))
    assert run.returncode == 2 and "JAXPPO_DISTRIBUTED='two'" in run.stderr
    run = subprocess.run(SCAN + ["--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=120,
                         env=_env(tmp_path, JAXPPO_DISTRIBUTED="2", JAXPPO_PROCESS_ID="2",
                                  JAX_COORDINATOR_ADDRESS="127.0.0.1:1"))
    assert run.returncode == 2 and "JAXPPO_PROCESS_ID=2" in run.stderr
    assert not (tmp_path / "x").exists()


def stand_in_nuts(system, data, free, density, alpha, case, draws, *args, **kwargs):
    """A stand-in for the NUTS draws of the marginal scan: ``draws`` draws
    around ``system``'s values, shifted by 1e-7 relative times the JAX
    process index. A replicated sampler need not agree bit for bit across
    hosts; process 0's draws must be the ones every process uses."""
    import jax

    rng = np.random.default_rng(0)
    shift = 1.0 + 1e-7 * jax.process_index()
    by_name = {pl.name: pl for pl in system.planets}
    samples = {}
    for name in free:
        pl, attr = name.split(".")
        v = float(getattr(by_name[pl], attr))
        scale = 1e-4 if attr in ("t0", "period") else 1e-3 * abs(v)
        samples[name] = (v + scale * rng.standard_normal(draws)) * shift
    return samples, {"method": "stand-in (tests/obliquity/test_processes.py)"}


MARGINAL = r"""
import json, sys
import jax
jax.config.update("jax_enable_x64", True)
out, pid, port, here = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
if port != "-":
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address="127.0.0.1:" + port, num_processes=2, process_id=pid)
from importlib.resources import files
sys.path.insert(0, here)
import jaxppo as jp
import jaxppo.obliquity._marginal as marginal
from test_processes import stand_in_nuts
marginal.nuts_draws = stand_in_nuts
cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 30])
res = jp.marginal_scan(cfg, **{OPTIONS}, out=out)
print("RESULT " + json.dumps({"table": res.table.tolist(), "summary": res.summary}, default=str))
"""
OPTIONS = dict(draws=4, chunk=2, min_ess=1, progress=False)
MARGINAL = MARGINAL.replace("{OPTIONS}", repr(OPTIONS))


def _marginal(tmp_path, outs, cwds, ports):
    """``jp.marginal_scan`` (4 draws of ``stand_in_nuts``) run by two JAX
    processes, writing ``outs`` from ``cwds``; what each returned."""
    here = os.path.dirname(os.path.abspath(__file__))
    procs = [subprocess.Popen([sys.executable, "-c", MARGINAL, out, str(i), port, here], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, cwd=cwd, env=_env(tmp_path))
             for i, (out, cwd, port) in enumerate(zip(outs, cwds, ports))]
    got = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), "\n".join(e[-3000:] for _, e in got)
    return [json.loads(next(ln for ln in o.splitlines() if ln.startswith("RESULT "))[7:]) for o, _ in got]


def test_two_processes_resume_and_write_the_marginal_scan_of_one(tmp_path, monkeypatch):
    """The marginal scan (issue 26): its draws (sampled in every process,
    process 0's used by all), its chi^2 per draw and its importance weights
    are those of one process to 1e-12; process 0 alone writes, and an
    interrupted run (two of four draws' chi^2 done, the draws not yet
    stored) resumes in both processes. (The real NUTS sampler ran the same
    way by hand; here a stand-in keeps the test short.)"""
    from importlib.resources import files

    import jaxppo as jp
    import jaxppo.obliquity._marginal as marginal

    monkeypatch.setattr(marginal, "nuts_draws", stand_in_nuts)
    cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 30])
    res = jp.marginal_scan(cfg, **OPTIONS, out=tmp_path / "one")  # one process: this one
    one = {"table": res.table.tolist(), "summary": json.loads(json.dumps(res.summary, default=str))}
    two = tmp_path / "two"
    two.mkdir()
    lines = (tmp_path / "one" / "marginal_progress.jsonl").read_text().splitlines(keepends=True)
    per_draw = 2 + 2 * 2  # null, ref, then per case its chi^2 curve and chi^2_0
    (two / "marginal_progress.jsonl").write_text("".join(lines[:1 + 2 * per_draw]))
    host1 = tmp_path / "host1"  # process 1 runs where the folder does not exist (another host)
    host1.mkdir()
    port = str(_free_port())
    got = _marginal(tmp_path, ["two", "two"], [tmp_path, host1], [port, port])
    assert not any(host1.iterdir())  # process 1 never touched a folder
    d1, d2 = (json.loads((tmp_path / d / "marginal_draws.json").read_text())["samples"] for d in ("one", "two"))
    assert set(d1) == set(d2)
    for name in d1:
        np.testing.assert_array_equal(d2[name], d1[name])
    for res in got:
        np.testing.assert_allclose([r[1:] for r in res["table"]], [r[1:] for r in one["table"]], rtol=1e-12,
                                   atol=1e-12)
        assert res["summary"]["seconds"]["draws_computed"] == 2
        assert res["summary"]["probabilities"] == one["summary"]["probabilities"]
    s1, s2 = (json.loads((tmp_path / d / "marginal.json").read_text()) for d in ("one", "two"))
    assert (s1["devices"], s1["processes"], s2["devices"], s2["processes"]) == (1, 1, 2, 2)
    recs = [json.loads(ln) for ln in (two / "marginal_progress.jsonl").read_text().splitlines()[1:]]
    assert len(recs) == len({r["case"] for r in recs}) == 4 * per_draw  # every draw's records written once
    assert (two / "marginal.png").is_file() and not list(two.glob("*.tmp*"))


def stand_in_joint_smc(system, data, free, density, case, alpha_ref, *, n_particles, seed, cess, n_moves,
                       progress=None, found=None):
    """The joint sampler of one case on a stand-in target: the real
    tempered SMC (its particles split over every device of every JAX
    process) on a Gaussian in two transit coordinates times a bump in alpha
    at 147 deg over a plateau, which costs a small fraction of the model."""
    import jax.numpy as jnp

    from jaxppo.inference._smc import tempered_smc

    def log_gamma(w, alpha):
        d = (alpha - 147.0 + 180.0) % 360.0 - 180.0
        return -0.5 * jnp.sum(w ** 2) + jnp.log(0.05 + jnp.exp(-0.5 * (d / 4.0) ** 2))

    out = tempered_smc(log_gamma, 2, n_particles=n_particles, seed=seed, cess=cess, n_moves=n_moves, progress=progress)
    # a model that fits, at least as well as the fixed scan's parameters (the reach check)
    out.update(modes={"stand_in": True}, found=None, chi2_best=0.95 * float(len(data)))
    return out


JOINT = r"""
import json, sys
import jax
jax.config.update("jax_enable_x64", True)
out, pid, port, here = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
jax.config.update("jax_cpu_collectives_implementation", "gloo")
jax.distributed.initialize(coordinator_address="127.0.0.1:" + port, num_processes=2, process_id=pid)
from importlib.resources import files
sys.path.insert(0, here)
import jaxppo as jp
import jaxppo.obliquity._joint as joint
from test_processes import stand_in_joint_smc
joint.joint_case_smc = stand_in_joint_smc
cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 30])
res = jp.joint_scan(cfg, particles=32, seeds=(0, 1), n_moves=2, out=out, progress=False)
print("RESULT " + json.dumps(res, default=str))
"""


def test_two_processes_resume_and_write_the_joint_scan_of_one(tmp_path, monkeypatch):
    """The joint sampler (issue 26): its particles split over two JAX
    processes give the runs of one process to 1e-12 (every process then
    holds every likelihood and takes the same steps); process 0 alone
    writes joint.json, joint.csv and joint.png, and a run interrupted after
    one of its four SMC runs resumes in both processes."""
    from importlib.resources import files

    import jaxppo as jp
    import jaxppo.obliquity._joint as joint

    monkeypatch.setattr(joint, "joint_case_smc", stand_in_joint_smc)
    cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 30])
    one = jp.joint_scan(cfg, particles=32, seeds=(0, 1), n_moves=2, out=tmp_path / "one", progress=False)
    rec1 = json.loads((tmp_path / "one" / "joint.json").read_text())
    two = tmp_path / "two"
    two.mkdir()
    first = next(iter(rec1["runs"]))
    (two / "joint.json").write_text(json.dumps({"settings": rec1["settings"],
                                                "runs": {first: rec1["runs"][first]}}))
    host1 = tmp_path / "host1"  # process 1 runs where the folder does not exist (another host)
    host1.mkdir()
    port = str(_free_port())
    here = os.path.dirname(os.path.abspath(__file__))
    procs = [subprocess.Popen([sys.executable, "-c", JOINT, "two", str(i), port, here], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, cwd=cwd, env=_env(tmp_path))
             for i, cwd in enumerate((tmp_path, host1))]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), "\n".join(e[-3000:] for _, e in outs)
    got = [json.loads(next(ln for ln in o.splitlines() if ln.startswith("RESULT "))[7:]) for o, _ in outs]
    assert not any(host1.iterdir())
    rec2 = json.loads((two / "joint.json").read_text())
    assert set(rec2["runs"]) == set(rec1["runs"])
    for key, run in rec1["runs"].items():
        for name in ("alpha", "weights", "log_z", "ess", "steps", "calls"):
            np.testing.assert_allclose(rec2["runs"][key][name], run[name], rtol=1e-12, atol=1e-12, err_msg=key)
    assert rec2["runs"][first]["seconds"] == rec1["runs"][first]["seconds"]  # kept, not rerun
    for res in got:
        for case, c in one["cases"].items():
            assert res["cases"][case]["geometries"] == c["geometries"]
            assert res["cases"][case]["alpha_peak"] == c["alpha_peak"] and abs(c["alpha_peak"] - 147.0) < 3.0
        assert (res["processes"], res["devices"]) == (2, 2)
    assert (one["processes"], one["devices"]) == (1, 1)
    assert {f.name for f in two.iterdir()} == {"joint.json", "joint.csv", "joint.png"}


def test_an_error_of_process_0_in_the_folder_stops_both_by_name(tmp_path):
    """What process 0 alone reads or writes fails (the marginal scan's out
    is a file; joint.json holds a JSON list): both processes stop with the
    error, none waits in a collective for the other (old code: the second
    hung until killed)."""
    (tmp_path / "afile").write_text("not a folder\n")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "joint.json").write_text("[]")
    host1 = tmp_path / "host1"
    host1.mkdir()
    here = os.path.dirname(os.path.abspath(__file__))
    for script, out, want in ((MARGINAL, "afile", "process 0 could not read"),
                              (JOINT, "bad", "is not a joint run's record")):
        port = str(_free_port())
        procs = [subprocess.Popen([sys.executable, "-c", script, out, str(i), port, here], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, cwd=cwd, env=_env(tmp_path))
                 for i, cwd in enumerate((tmp_path, host1))]
        try:
            outs = [p.communicate(timeout=300) for p in procs]
        finally:
            for p in procs:
                p.kill()
        for p, (_, err) in zip(procs, outs):
            assert p.returncode != 0 and want in err, err[-2000:]
    assert not any(host1.iterdir())
