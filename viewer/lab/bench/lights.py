"""``relight bench lights``: area-light fitting error against run time, per map, N and method.

For every map (the CLI's ``--maps``, by default ``$RELIGHT_DATA/hdri``: the nine CC0 maps) and N in 4, 8, 16, 32, each
method (``instant`` = the default, ``fast``, ``paper``, ``median-cut`` = the initialization alone) fits N lights;
the fit's wall time (including the reference shading it needs, computed once per map and added to
each method that uses it) and the relative L1 shading errors of :mod:`viewer.lab.bench.lightfit_evaluate`
(sphere; sphere-on-plane with shadows; held-out box-on-plane with shadows) are recorded.

Writes ``bench_lights.json`` (every row), ``bench_lights.md`` (tables of medians over the maps, and
per map at N = 16) and ``bench_lights.png`` (error against seconds) into ``out/`` (or beside the
``-o`` path; ``-o docs/results/bench_lights.json`` refreshes the committed ones).
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

import numpy as np
import torch

from viewer.files.imageio import atomic_path, write_text
from viewer.lab.bench.lightfit_evaluate import held_out, shading_errors
from viewer.lighting.envmap import load_envmap
from viewer.lighting.lightfit.fit import METHODS, fit_lights
from viewer.lighting.lightfit.problem import build_problem
from viewer.lighting.lightfit.settings import FitSettings

COUNTS = (4, 8, 16, 32)
VIEWS = ("sphere", "plane", "heldout")


def run_lights_benchmark(maps_dir, counts=COUNTS, methods=METHODS, output="out/bench_lights.json"):
    maps = sorted(Path(maps_dir).glob("*.hdr")) + sorted(Path(maps_dir).glob("*.exr"))
    if not maps:
        raise SystemExit(f"no .hdr/.exr maps in {maps_dir}")
    settings = FitSettings()
    rows = []
    for path in maps:
        env = load_envmap(path)
        start = time.perf_counter()
        problem = build_problem(env, settings)
        reference_s = time.perf_counter() - start
        heldout = held_out(problem)
        for n in counts:
            for method in methods:
                start = time.perf_counter()
                lights = fit_lights(env, n, method, settings, problem=problem)
                # fast and paper fit on the shared reference views: their time includes building them
                # (instant builds its own small ones inside fit_lights; median cut needs none)
                seconds = time.perf_counter() - start + (reference_s if method in ("fast", "paper") else 0.0)
                errors = shading_errors(problem, lights, heldout)
                rows.append({"map": path.stem, "n": n, "method": method, "seconds": round(seconds, 3),
                             **{k: round(v, 5) for k, v in errors.items()}})
                print(f"{path.stem:28s} N={n:2d} {method:10s} {seconds:7.2f} s  " +
                      "  ".join(f"{k} {100 * errors[k]:5.2f}%" for k in VIEWS), flush=True)
        write_results(rows, counts, methods, settings, output)  # after every map: a long run keeps what it measured
    print(markdown_tables(rows, counts, methods))
    print(f"wrote {output} and the .md / .png beside it")
    return rows


def write_results(rows, counts, methods, settings, output):
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    meta = {"machine": f"{platform.machine()}, {torch.get_num_threads()} torch threads, CPU", "settings": vars(settings),
            "error": "relative L1 of linear shading over 7 rotations of the map"}
    write_text(output, json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")
    write_text(output.with_suffix(".md"), markdown_tables(rows, counts, methods))
    plot(rows, methods, output.with_suffix(".png"))


def _median(rows, key):
    return float(np.median([r[key] for r in rows])) if rows else float("nan")


def markdown_tables(rows, counts, methods) -> str:
    lines = ["Medians over the maps (seconds; relative L1 shading error in %):", "",
             "| N | method | seconds | sphere | plane (shadows) | held-out box (shadows) |",
             "|---|---|---|---|---|---|"]
    for n in counts:
        for m in methods:
            sel = [r for r in rows if r["n"] == n and r["method"] == m]
            lines.append(f"| {n} | {m} | {_median(sel, 'seconds'):.1f} | " +
                         " | ".join(f"{100 * _median(sel, v):.2f}" for v in VIEWS) + " |")
    if 16 in counts:
        lines += ["", "Per map, N = 16 (seconds / sphere / plane / held-out, %):", "",
                  "| map | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
        for name in sorted({r["map"] for r in rows}):
            cells = []
            for m in methods:
                r = next((r for r in rows if r["map"] == name and r["n"] == 16 and r["method"] == m), None)
                cells.append("" if r is None else f"{r['seconds']:.1f} s / " +
                             " / ".join(f"{100 * r[v]:.2f}" for v in VIEWS))
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot(rows, methods, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), dpi=100, sharex=True)
    colours = dict(zip(methods, ("tab:red", "tab:blue", "tab:green", "tab:purple")))
    counts = sorted({r["n"] for r in rows})
    markers = dict(zip(counts, "o^sD"))
    for ax, view in zip(axes, VIEWS):
        for m in methods:
            for n in counts:
                sel = [r for r in rows if r["method"] == m and r["n"] == n]
                ax.scatter([max(r["seconds"], 0.01) for r in sel], [100 * r[view] for r in sel], s=14, alpha=0.35,
                           color=colours[m], marker=markers[n])
            med = [(max(_median([r for r in rows if r["method"] == m and r["n"] == n], "seconds"), 0.01),
                    100 * _median([r for r in rows if r["method"] == m and r["n"] == n], view)) for n in counts]
            ax.plot(*zip(*med), color=colours[m], lw=2, label=m)
            for (x, y), n in zip(med, counts):
                ax.annotate(f"N={n}", (x, y), xytext=(4, 3), textcoords="offset points", fontsize=7, color=colours[m])
        ax.set_xscale("log")
        ax.set_xlabel("fitting time (s, this machine)")
        ax.set_ylabel("relative L1 error (%)")
        ax.set_title({"sphere": "sphere (diffuse + specular)", "plane": "sphere on plane, shadows",
                      "heldout": "held-out box on plane, shadows"}[view])
        ax.grid(alpha=0.3)
    axes[0].legend(title="method (lines: medians)")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
