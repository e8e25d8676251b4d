"""`jaxppo scan` draws its figures in a second process while it fits the
PPO-or-spot alternatives: the files are those drawn in one process, byte
for byte; a job's error and warnings reach the command as if it ran there;
a drawing process that dies, or is switched off, leaves the work to the
command."""

import json
import os
import warnings

import pytest

from jaxppo.cli import main
from jaxppo.obliquity._worker import Drawer


@pytest.fixture(autouse=True)
def _drawing_process_on(monkeypatch):  # tests/conftest.py switches it off for the other tests
    monkeypatch.setenv("JAXPPO_DRAW_PROCESS", "1")


def test_jobs_run_in_another_process_and_report_as_if_run_here():
    with Drawer() as drawer:
        assert drawer.separate
        assert drawer.run(os.getpid)() != os.getpid()
        with pytest.raises(ValueError, match="invalid literal for int"):
            drawer.run(int, "x")()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert drawer.run(warnings.warn, "drawn with care", RuntimeWarning)() is None
        assert [(str(w.message), w.category) for w in caught] == [("drawn with care", RuntimeWarning)]
        assert drawer.run(sum, [1, 2, 3])() == 6  # still serving after an error


def test_a_dead_or_switched_off_drawing_process_leaves_the_job_here(monkeypatch):
    with Drawer() as drawer:
        drawer._proc.kill()
        drawer._proc.wait()
        assert drawer.run(os.getpid)() == os.getpid()
        assert not drawer.separate
    monkeypatch.setenv("JAXPPO_DRAW_PROCESS", "0")
    with Drawer() as drawer:
        assert not drawer.separate and drawer.run(os.getpid)() == os.getpid()


def warn_with_a_local_category():
    """A job whose warning's category cannot be pickled (a local class)."""
    class Local(UserWarning):
        pass

    warnings.warn("a local kind of warning", Local)
    return 7


def test_what_cannot_travel_travels_as_text_and_the_process_goes_on():
    with Drawer() as drawer:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert drawer.run(warn_with_a_local_category)() == 7
        assert [(str(w.message), w.category) for w in caught] == [("a local kind of warning", UserWarning)]
        pid = drawer.run(os.getpid)()
        assert pid != os.getpid() and drawer.separate


def test_another_copy_of_jaxppo_in_the_drawing_process_leaves_the_job_here(monkeypatch):
    """The drawing process imports the command's jaxppo (its sys.path);
    where it still finds another copy it stops, and the command draws."""
    import jaxppo

    monkeypatch.setattr(jaxppo, "__file__", "/elsewhere/jaxppo/__init__.py")
    with Drawer() as drawer:
        assert drawer.run(os.getpid)() == os.getpid()


def test_the_drawing_process_ends_with_the_command(tmp_path):
    """A command killed (not by Ctrl-C) leaves no drawing process behind to
    write into its folder."""
    import subprocess
    import sys
    import time

    # the command dies while its drawing process is busy with a long job
    script = ("import os, time; from jaxppo.obliquity._worker import Drawer; d = Drawer(); "
              "print(d._proc.pid, flush=True); d.run(os.getpid)(); d.run(time.sleep, 60); os._exit(0)")
    env = dict(os.environ, JAXPPO_DRAW_PROCESS="1")
    # (stderr not captured: the drawing process inherits it, and reading it would wait for that process)
    run = subprocess.run([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                         timeout=120, env=env)
    child = int(run.stdout.split()[0])
    for _ in range(100):
        try:
            os.kill(child, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        raise AssertionError(f"drawing process {child} outlived its command")


def test_scan_figures_drawn_in_a_second_process_are_those_of_one(tmp_path, monkeypatch):
    """The default scan (real Kepler-20 data: its dips are fitted by the
    PPO-or-spot alternatives meanwhile), with and without the drawing
    process: the same PNG files, byte for byte, and the same summary."""
    used = []
    run = Drawer.run

    def spy(self, fn, *args):
        used.append(self.separate)
        return run(self, fn, *args)

    monkeypatch.setattr(Drawer, "run", spy)
    args = ["scan", "--quiet", "--alpha", "0", "360", "5"]
    assert main(args + ["--out", str(tmp_path / "two")]) == 0
    monkeypatch.setenv("JAXPPO_DRAW_PROCESS", "0")
    assert main(args + ["--out", str(tmp_path / "one")]) == 0
    assert used == [True, False]
    one, two = (json.loads((tmp_path / d / "summary.json").read_text()) for d in ("one", "two"))
    pngs = [os.path.basename(f) for f in one["figures"]] + ["ppo_or_spot.png"]
    assert len(pngs) == 6 and one["ppo_or_spot"]["dips"]
    for name in pngs:
        assert (tmp_path / "two" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name

    def same(s, d):  # the run's own: its time, its folder's paths
        s = {k: v for k, v in s.items() if k != "seconds"}
        return json.loads(json.dumps(s).replace(str(tmp_path / d), "OUT"))

    assert same(one, "one") == same(two, "two")
