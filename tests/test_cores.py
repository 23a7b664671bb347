"""Threads sized to the cores the program really gets (viewer/cores.py), and the time-left estimate
of long work (viewer/progress.py)."""

import io
import os
import subprocess
import sys
import time

import pytest

from viewer.cores import allowed_cores, idle_cores, work_threads
from viewer.progress import StageBars, TimeLeft


def test_busy_cores_are_not_counted_as_free():
    busy = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(allowed_cores())]
    try:
        time.sleep(0.5)
        assert idle_cores(0.2) < 0.75  # every core taken
        assert work_threads() == 1
        assert work_threads(reserve=1) == 1  # never below one
    finally:
        for p in busy:
            p.kill()
            p.wait()
    assert 1 <= work_threads() <= allowed_cores()


def test_size_pools_sizes_torch_opencv_and_what_loads_later():
    code = ("from viewer.cores import size_pools; import cv2, torch; size_pools(1); "
            "import os; print(torch.get_num_threads(), cv2.getNumThreads(), os.environ['LP_NUM_THREADS'], "
            "os.environ['OMP_NUM_THREADS'])")
    env = {k: v for k, v in os.environ.items() if k not in ("LP_NUM_THREADS", "OMP_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout.split()
    assert out == ["1", "1", "1", "1"]
    # a user's own LP_NUM_THREADS is kept
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**env, "LP_NUM_THREADS": "3"},
                         check=True).stdout.split()
    assert out[2] == "3"


def test_time_left_weights_stages_by_their_shares():
    left = TimeLeft({"a": 1.0, "b": 3.0})
    assert left.update("a", 1, 2) == pytest.approx(0.125)
    assert left.seconds_left() is None or left.seconds_left() >= 0  # 12.5 % done: an estimate
    assert left.update("b", 0, 10) == pytest.approx(0.25)
    assert left.update("b", 5, 10) == pytest.approx(0.625)
    assert left.update("a", 2, 2) == pytest.approx(0.625)  # never goes back
    assert left.update("unknown", 1, 1) == pytest.approx(0.625)
    fresh = TimeLeft({"a": 1.0})
    fresh.update("a", 1, 100)
    assert fresh.seconds_left() is None  # 1 %: too early to say
    time.sleep(0.2)
    fresh.update("a", 50, 100)
    assert 0.1 < fresh.seconds_left() < 1.0  # half done in ~0.2 s: ~0.2 s left


def test_stage_lines_give_the_time_left_of_the_whole_work():
    out = io.StringIO()
    with StageBars(prefix="fitting: ", stream=out, shares={"one": 1.0, "two": 1.0}) as bars:
        for stage in ("one", "two"):
            for i in range(5):
                time.sleep(0.02)
                bars(stage, i + 1, 5)
    first, second = out.getvalue().splitlines()
    assert first.startswith("fitting: one: 5/5 in") and first.endswith("left")
    assert "left" not in second  # the work is done


def test_the_contention_benchmark_reads_the_time_left_the_fit_said():
    from viewer.lab.bench.contention import time_left_checks

    lines = ["fitting 16 lights to m.hdr: reference: 2/2 in 0.2 s, about 3 s left",
             "fitting 16 lights to m.hdr: directions: 150/150 in 1.5 s, under a second left",
             "fitting 16 lights to m.hdr: sigma: 16/16 in 0.4 s"]
    assert time_left_checks(lines) == [{"after": "reference", "said_s": 3.0, "took_s": 1.9},
                                       {"after": "directions", "said_s": 0.5, "took_s": 0.4}]
