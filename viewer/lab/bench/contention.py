"""The product's long commands on a busy machine: each run as a user runs it (a fresh process, empty
caches), idle and beside one and two busy processes (``python -c 'while 1: pass'``, each taking a
core), so that what a user sees on a shared laptop is measured, not what an idle benchmark machine
gives. The commands: ``relight fit-lights`` of a 1k map (16 lights, instant), ``relight infer`` of
the bundled photo, and a turntable video of the bundled sample scene. Each is timed from start to exit
(``repeats`` times, alternating the loads, medians reported); the fit's own progress lines (stage,
time left) are kept, so the estimate it showed can be checked against the time it took."""

from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_text

LOADS = (0, 1, 2)
TARGET_RATIO = 2.5  # beside two busy processes, at most this times the idle time


def _commands(work: Path, hdri: Path) -> dict:
    from viewer.resources import asset_dir, sample_scene_dir

    relight = [sys.executable, "-m", "viewer.cli.main"]
    return {
        "fit": relight + ["fit-lights", str(hdri / "kiara_1_dawn_1k.hdr"), "-n", "16", "-o", str(work / "fit.lights.json")],
        "infer": relight + ["infer", str(asset_dir() / "photos" / "underpass.jpg"), "-o", str(work / "bundle")],
        "turntable": relight + ["render", str(sample_scene_dir()), "--env", str(asset_dir() / "envmaps" / "immenstadter_horn_256.hdr"),
                                "--frames", "24", "-o", str(work / "turntable.mp4")],
    }


def _busy(count: int) -> list:
    return [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(count)]


def run_once(command: list, load: int, env: dict) -> dict:
    busy = _busy(load)
    try:
        time.sleep(0.5)  # the busy processes running before the command starts
        start = time.perf_counter()
        proc = subprocess.run(command, env=env, capture_output=True, text=True)
        seconds = time.perf_counter() - start
    finally:
        for p in busy:
            p.kill()
            p.wait()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(command[2:4])} failed ({proc.returncode}): {proc.stderr.strip()[-800:]}")
    return {"seconds": seconds, "stderr": proc.stderr.strip().splitlines()}


def run_contention_benchmark(hdri: Path, repeats: int = 3, output: str = "out/bench_contention.json",
                             progress=print) -> dict:
    results: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(repeats):
            for load in LOADS if repeat % 2 == 0 else LOADS[::-1]:  # alternating, so a drift of the machine is shared
                for name in ("fit", "infer", "turntable"):
                    work = Path(tmp) / f"{name}_{load}_{repeat}"
                    work.mkdir()
                    env = {**os.environ, "RELIGHT_CACHE": str(work / "cache")}  # empty: the fit fits, the photo is inferred
                    r = run_once(_commands(work, hdri)[name], load, env)
                    results.setdefault(name, {}).setdefault(str(load), []).append(r)
                    progress(f"{name} beside {load} busy: {r['seconds']:.1f} s")
    summary = {}
    for name, by_load in results.items():
        med = {load: float(np.median([r["seconds"] for r in runs])) for load, runs in by_load.items()}
        summary[name] = {"median_s": med, "ratio_to_idle": {load: s / med["0"] for load, s in med.items()},
                         "met": med["2"] / med["0"] <= TARGET_RATIO}
        if name == "fit":  # the time left it showed against the time it then took, every run
            summary[name]["time_left"] = {load: [time_left_checks(r["stderr"]) for r in runs] for load, runs in by_load.items()}
    result = {"machine": {"cpu": platform.machine(), "cores": os.cpu_count(), "python": platform.python_version(),
                          "loadavg_before": os.getloadavg()},
              "method": "each command a fresh process with an empty cache, timed start to exit, beside 0/1/2 "
                        "`python -c 'while 1: pass'` processes; medians of the repeats",
              "target": f"beside two busy processes at most {TARGET_RATIO}x the idle time",
              "summary": summary, "runs": results}
    path = write_text(output, json.dumps(result, indent=1) + "\n")
    progress(f"wrote {path}")
    return result


STAGE_LINE = re.compile(r": (?P<stage>[^:]+): \d+/\d+ in (?P<seconds>[\d.]+) s"
                        r"(?:, (?P<left>about (?P<n>[\d.]+) s left|under a second left))?$")


def time_left_checks(lines: list) -> list:
    """The fit's stage lines (``stage: d/t in X s, about N s left``) as what it said was left after
    each stage against what was (the stages after it): ``under a second`` counts as 0.5 s."""
    stages = [m for m in (STAGE_LINE.search(line) for line in lines) if m]
    out = []
    for k, m in enumerate(stages):
        if m["left"] is None:
            continue
        said = 0.5 if m["n"] is None else float(m["n"])
        out.append({"after": m["stage"], "said_s": said, "took_s": round(sum(float(x["seconds"]) for x in stages[k + 1:]), 2)})
    return out


def table(result: dict) -> str:
    lines = ["| command | idle | beside 1 busy | beside 2 busy | 2 busy / idle |", "|---|---|---|---|---|"]
    for name, s in result["summary"].items():
        m, r = s["median_s"], s["ratio_to_idle"]
        lines.append(f"| {name} | {m['0']:.1f} s | {m['1']:.1f} s ({r['1']:.2f}x) | {m['2']:.1f} s | "
                     f"{r['2']:.2f}x {'(met)' if s['met'] else '(NOT met)'} |")
    return "\n".join(lines)
