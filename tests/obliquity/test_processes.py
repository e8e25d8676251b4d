"""The scan under several JAX processes (jax.distributed, CPU collectives
over gloo), as a user starts it from the command line: the same numbers as
one process, the folder written once (by process 0), an interrupted run
resumed consistently by every process, one report printed; commands that
run in one process only refuse, naming the setting."""

import json
import os
import shutil
import socket
import subprocess
import sys

import numpy as np


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(tmp_path, **extra):
    env = dict(os.environ, JAX_PLATFORMS="cpu", JAXPPO_CACHE_DIR=str(tmp_path / "cache"), **extra)
    env.pop("XLA_FLAGS", None)
    return env


SCAN = [sys.executable, "-m", "jaxppo.cli", "scan", "--alpha", "0", "360", "2", "--quiet"]


def test_two_processes_resume_and_write_the_scan_of_one(tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    subprocess.run(SCAN + ["--out", str(one)], env=_env(tmp_path), check=True, timeout=600, capture_output=True)
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


def _two_processes(tmp_path, args, cwds, check=True):
    """Run ``jaxppo scan`` ``args`` as two JAX processes (gloo on
    localhost) in the folders ``cwds``; their (stdout, stderr)."""
    port = str(_free_port())
    procs = [subprocess.Popen(SCAN + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
                              env=_env(tmp_path, JAXPPO_DISTRIBUTED="2", JAXPPO_PROCESS_ID=str(i),
                                       JAX_COORDINATOR_ADDRESS="127.0.0.1:" + port))
             for i, cwd in enumerate(cwds)]
    outs = [p.communicate(timeout=600) for p in procs]
    if check:
        assert all(p.returncode == 0 for p in procs), "\n".join(o[1][-3000:] for o in outs)
    else:
        assert all(p.returncode == 2 for p in procs), "\n".join(o[1][-3000:] for o in outs)
    return outs


def test_commands_of_one_process_refuse_distributed_settings(tmp_path):
    run = subprocess.run([sys.executable, "-m", "jaxppo.cli", "fit"], capture_output=True, text=True,
                         env=_env(tmp_path, JAXPPO_DISTRIBUTED="2"), timeout=120)
    assert run.returncode == 2 and "JAXPPO_DISTRIBUTED='2'" in run.stderr and "one process only" in run.stderr
    run = subprocess.run(SCAN + ["--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=120,
                         env=_env(tmp_path, JAXPPO_DISTRIBUTED="two"))
    assert run.returncode == 2 and "JAXPPO_DISTRIBUTED='two'" in run.stderr
    run = subprocess.run(SCAN + ["--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=120,
                         env=_env(tmp_path, JAXPPO_DISTRIBUTED="2", JAXPPO_PROCESS_ID="2",
                                  JAX_COORDINATOR_ADDRESS="127.0.0.1:1"))
    assert run.returncode == 2 and "JAXPPO_PROCESS_ID=2" in run.stderr
    assert not (tmp_path / "x").exists()
