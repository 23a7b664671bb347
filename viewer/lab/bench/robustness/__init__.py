"""``relight bench robustness``: the bad-input campaign, rerunnable. Hostile files and options are
made in a scratch folder (empty, truncated, random, wrongly encoded, deeply nested, huge-claiming,
out-of-range, escaping the bundle, folders where files belong, a user's files beside the outputs,
sizes past the memory budget), the real command line runs on each in its own process, and every
case is judged (:func:`.case.judge`):

- clean exit: 0 when the case is valid, 2 with one ``relight: error:`` (or argparse's usage error)
  line when not, and no other line but progress; never a traceback, never killed by a timeout;
- nothing written on an error (the ``-o`` target absent or as it was), every input file and every
  user's file beside the outputs unchanged;
- a successful render is not black unless the case says so (a black map, with its warning line);
- its peak memory (the kernel's count for that process) under the budget the program holds itself
  to (:func:`viewer.memory_needs.memory_budget`).

Scenarios (:mod:`.scenarios`) kill real processes at random moments, fill a disk and race two
writers. Prints how many cases were tried and how many ended cleanly, and writes them to JSON.
"""

from __future__ import annotations

import json
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict
from pathlib import Path

from viewer.files.imageio import write_text
from viewer.lab.bench.robustness.case import Case, Scenario, run_case, run_scenario
from viewer.lab.bench.robustness.first_campaign import Campaign, first_campaign
from viewer.lab.bench.robustness.fourth_campaign import fourth_campaign
from viewer.lab.bench.robustness.scenarios import scenarios
from viewer.lab.bench.robustness.second_campaign import second_campaign
from viewer.lab.bench.robustness.third_campaign import third_campaign
from viewer.memory_needs import memory_budget


def make_cases(work: Path, seed: int = 17) -> list[Case | Scenario]:
    """Every case, its files made in ``work``; ``seed`` the generators' (another one: new variants of
    every generated class)."""
    from viewer.lab.bench.robustness.case import run_command

    kit = Campaign(work, seed)
    first_campaign(kit)
    photo_bundle = kit.work / "bundles" / "inferred"
    code, _, err, _, _ = run_command(["infer", kit.photo, "--mask", kit.mask, "--size", "64", "--max-size", "256", "-o",
                                      photo_bundle])
    if code != 0:
        raise RuntimeError(f"the campaign's photo bundle could not be inferred: {err[-300:]}")
    second_campaign(kit, photo_bundle)
    third_campaign(kit)
    fourth = fourth_campaign(kit)
    return kit.cases + scenarios(seed + 16) + fourth  # (33 for the default seed, as before)


def run_robustness_benchmark(work=None, output="out/bench_robustness.json", jobs: int = 2, progress=None, seed: int = 17,
                             part: tuple[int, int] = (0, 1)) -> dict:
    """Every case, run ``jobs`` at a time; ``part`` (k, n): only every n-th case from the k-th (the
    test suite runs the campaign in two halves, one on each of its workers)."""
    import tempfile

    budget = memory_budget()
    with tempfile.TemporaryDirectory(prefix="relight-robustness-") as tmp:
        work = Path(work or tmp)
        start = time.perf_counter()
        cases = make_cases(work, seed)[part[0]::part[1]]

        def run(c):
            return run_scenario(c, work) if isinstance(c, Scenario) else run_case(c, work)

        with ThreadPoolExecutor(max_workers=max(jobs, 1)) as pool:
            for case, result in zip(cases, pool.map(run, cases)):
                if result["peak_mb"] * 1024 * 1024 > budget:
                    result["problems"].append(f"peak {result['peak_mb']} MB over the budget")
                    result["clean"] = False
                case.result = result
                if progress is not None:
                    progress(case)
        groups: dict = {}
        for c in cases:
            g = groups.setdefault(c.group, {"tried": 0, "clean": 0, "peak_mb": 0})
            g["tried"] += 1
            g["clean"] += int(c.result["clean"])
            g["peak_mb"] = max(g["peak_mb"], c.result["peak_mb"])
        report = {"tried": len(cases), "clean": sum(c.result["clean"] for c in cases), "groups": groups,
                  "tracebacks": sum("traceback" in c.result["problems"] for c in cases),
                  "memory_budget_mb": round(budget / 2**20), "seed": seed, "part": list(part),
                  "seconds": round(time.perf_counter() - start, 1),
                  "cases": [_summary(c) for c in cases]}
    write_text(output, json.dumps(report, indent=1) + "\n")
    return report


def _summary(case) -> dict:
    if isinstance(case, Scenario):
        return {"group": case.group, "name": case.name, "command": "scenario", "result": case.result}
    return {k: v for k, v in asdict(case).items() if k != "args"} | {"command": " ".join(case.args[:1])}
