"""``relight bench report [--quick] [--data HELDOUT]``: error against run time for the whole
pipeline, temporal stability, and the quality presets chosen from the Pareto front.

1. **Cases**: the sample scene under every map at several yaws, the bundled photo's inferred bundle
   under every map, and (``--data``) held-out synthetic people under every map plus their own
   records' lightings (:mod:`viewer.lab.bench.cases`).
2. **Reference**: Mitsuba's converged direct-lighting render of each bundle's depth mesh under the
   whole turned map; the dataset's full-geometry ground truth where a lighting has one.
3. **Sweep** (:mod:`viewer.lab.bench.methods`): the engine's knobs one at a time around the balanced
   preset, corner settings, the presets, and the baselines, each rendered for every case and
   lighting; errors (RMSE, SSIM, FLIP) after the reference's exposure (its 99th percentile of
   luminance -> 0.9) on the mask less its border.
4. **Time**: every method on the sample scene on this machine in this run: median full frame (the
   lighting turned) and update (one light edited).
5. **Pareto front** of (full frame time, RMSE); the presets' rules applied to it; the targets.
6. **Temporal stability**: dRMSE at steps 1, 2, 4 of turntables of two maps, presets and baselines,
   against the ray-traced turntable, with the reference's own Monte Carlo floor.

Writes ``results.json``, ``results.md`` and two PNG figures into the output folder (``out/report/``,
or ``out/report-quick/`` for ``--quick``, the small configuration CI runs to catch a broken harness;
``-o docs/results`` refreshes the committed report).
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_text
from viewer.lab.bench.cases import (
    REFERENCE_VERSION,
    Case,
    Lighting,
    MapStore,
    find_maps,
    heldout_cases,
    interior,
    photo_case,
    reference,
    sample_case,
    scene_hash,
)
from viewer.lab.bench.contact import ContactConfig, contact_errors, penumbra_widths
from viewer.lab.bench.methods import Method, Renderer
from viewer.lab.bench.sweep import sweep
from viewer.lighting.lightfit.cache import cache_dir
from viewer.progress import StageBars
from viewer.resources import asset_dir, sample_scene_dir

INTERACTIVE_MS = 90.0  # interactive preset: full frame within this (>= 10 fps with margin)
FINAL_MS = 1000.0  # final preset: full frame within this
ROWS_VERSION = 1  # bump when the error rows change meaning in this module (masks, exposure); code elsewhere is hashed
BALANCED_SLACK = 0.05  # balanced preset: error within this fraction of the 64-light setting's
QUICK_CONTACT = ContactConfig(heights=(0.05, 0.3), size=64, spp=64)
REFERENCE = "reference (Mitsuba)"  # the reference's picture among the examples


@dataclass(frozen=True)
class ReportConfig:
    quick: bool
    sample_size: int  # pixels of the sample scene (errors and times)
    yaws: tuple  # lightings of the sample scene
    spp: int  # reference samples per pixel
    photo: bool  # include the bundled photo's inferred bundle
    people: int  # held-out people (with --data)
    timing_maps: int  # maps the times are measured under
    repeats: int  # timed frames per map and kind of frame
    temporal_frames: int
    temporal_size: int
    temporal_spp: int
    temporal_maps: tuple
    fit_method: str  # how the area lights are fitted to the maps (cached)


FULL = ReportConfig(quick=False, sample_size=512, yaws=(0.0, 180.0), spp=128, photo=True, people=4, timing_maps=3,
                    repeats=3, temporal_frames=128, temporal_size=256, temporal_spp=64,
                    temporal_maps=("immenstadter_horn_1k", "studio_small_03_1k"), fit_method="fast")
QUICK = ReportConfig(quick=True, sample_size=128, yaws=(0.0,), spp=16, photo=False, people=1, timing_maps=2,
                     repeats=2, temporal_frames=16, temporal_size=64, temporal_spp=8,
                     temporal_maps=("immenstadter_horn_256", "studio_small_03_256"), fit_method="median-cut")


def _exposure(ref: np.ndarray, mask: np.ndarray) -> float:
    import torch

    from viewer.nets.photo import exposure_scale

    img = torch.from_numpy(np.ascontiguousarray(ref.transpose(2, 0, 1)))[None]
    return float(exposure_scale(img, torch.from_numpy(mask)[None, None].float()))


def _machine(ctx) -> dict:
    from viewer.gl.context import describe

    return {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(), "system": platform.platform(),
            "python": platform.python_version(), "gl": describe(ctx)}


def _lights_by_map(maps: MapStore, names, counts, method: str, progress) -> dict:
    from viewer.lighting.lightfit.cache import lights_for_map

    out = {}
    jobs = [(m, n) for m in names for n in counts]
    for k, (m, n) in enumerate(jobs):
        out[m, n] = lights_for_map(maps[m], n, method)[0]
        progress("fitting area lights (cached)", k + 1, len(jobs))
    return out


def _cases(config: ReportConfig, maps: MapStore, names, data) -> list[Case]:
    from viewer.scene.bundle import load_scene
    from viewer.scene.resampling import resample_scene

    scene = load_scene(sample_scene_dir())
    if max(scene.width, scene.height) != config.sample_size:
        scene = resample_scene(scene, config.sample_size)
    cases = [sample_case(scene, names, config.yaws)]
    if config.photo:
        photos = asset_dir() / "photos"
        cases.append(photo_case(photos / "underpass.jpg", photos / "underpass.mask.png", names, 0.0))
    if data is not None:
        held = heldout_cases(Path(data), names, config.people)
        if (Path(data) / "maps").is_dir():  # the maps of the dataset's own records
            maps.add(find_maps(Path(data) / "maps"))
        cases += held
    return cases


def renderer_code_hash() -> str:
    """A hash of the code an error row depends on: the shaders, the engine, the twin, the baselines
    and the metrics (any change there computes the rows again)."""
    import hashlib

    from viewer.resources import shader_dir

    product, here = Path(__file__).resolve().parents[2], Path(__file__).resolve().parent
    files = sorted(shader_dir().glob("*.glsl")) + sorted((product / "gl").rglob("*.py")) + sorted((product / "twin").rglob("*.py"))
    files += sorted((product / "scene").rglob("*.py")) + [product / "lighting" / "sh.py"]
    files += [here / name for name in ("methods.py", "metrics.py", "cases.py")]
    h = hashlib.sha256()
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def _saved_rows(key: str, method: Method, case: Case, config: ReportConfig, code: str) -> Path:
    """Where one method's error rows on one case are kept, so a report that stopped (or one with
    a new setting) redoes only what is missing; times are always measured afresh."""
    import hashlib

    what = json.dumps([key, asdict(method), [asdict(l) for l in case.lightings], config.spp, config.fit_method,
                       REFERENCE_VERSION, ROWS_VERSION, code], default=str)
    return cache_dir().with_name("report") / f"{hashlib.sha256(what.encode()).hexdigest()[:24]}.json"


def _error_rows(ctx, cases, methods, maps: MapStore, lights, config, progress, examples: dict) -> list[dict]:
    """Every method's errors on every case and lighting; ``examples`` ({label: None}) gets the
    display images of the first case's first lighting for its labels (``REFERENCE``: the reference)."""
    from viewer.files.imageio import read_exr
    from viewer.lab.bench.metrics import metrics, srgb

    rows = []
    code = renderer_code_hash()
    total = sum(len(c.lightings) for c in cases)
    done = 0
    for case in cases:
        key = scene_hash(case.scene)
        mask = interior(case.scene.mask)
        refs, truths, envs = [], [], []
        for lighting in case.lightings:
            ref = reference(case.scene, key, maps, lighting, config.spp)
            refs.append((ref, _exposure(ref, mask)))
            truths.append(read_exr(lighting.truth)[..., :3] if lighting.truth is not None else None)
            envs.append(maps[lighting.map_name].rotated(lighting.yaw) if any(m.kind == "sh" for m in methods) else None)
            done += 1
            progress("ray-traced references (cached)", done, total)
        if case is cases[0] and REFERENCE in examples:
            ref, s = refs[0]
            examples[REFERENCE] = srgb(s * ref)
        for k, method in enumerate(methods):
            saved = _saved_rows(key, method, case, config, code)
            if saved.is_file() and not (case is cases[0] and method.label in examples):
                reused = json.loads(saved.read_text())
                rows += [{**r, "reused": True} for r in reused]
                progress(f"rendering {case.name}", k + 1, len(methods))
                continue
            mine = []
            renderer = Renderer(ctx, method, case.scene)
            try:
                for j, (lighting, (ref, s), truth, env) in enumerate(zip(case.lightings, refs, truths, envs)):
                    ls = lights[lighting.map_name, method.lights].rotated(lighting.yaw) if method.uses_lights else None
                    img = renderer.image(ls, env)
                    shown = np.clip(s * img, 0.0, 1.0)
                    if case is cases[0] and j == 0 and method.label in examples:
                        examples[method.label] = srgb(shown)
                    row = {"method": method.label, "case": case.name, "group": case.group, "map": lighting.map_name,
                           "yaw": lighting.yaw, **metrics(shown, np.clip(s * ref, 0.0, 1.0), mask, flip=True)}
                    if truth is not None:
                        row["truth"] = metrics(shown, np.clip(s * truth, 0.0, 1.0), mask, flip=True)
                    mine.append(row)
            finally:
                renderer.release()
            rows += mine
            saved.parent.mkdir(parents=True, exist_ok=True)
            write_text(saved, json.dumps(mine))
            progress(f"rendering {case.name}", k + 1, len(methods))
    return rows


def _timings(ctx, scene, methods, maps: MapStore, lights, names, config, progress) -> dict:
    out = {}
    for k, method in enumerate(methods):
        renderer = Renderer(ctx, method, scene)
        full, update = [], []
        try:
            for name in names:
                env = maps[name] if method.kind == "sh" else None
                f, u = renderer.times(lights[name, method.lights] if method.uses_lights else None, env, config.repeats)
                full += f
                update += u
        finally:
            renderer.release()
        out[method.label] = {"full_ms": float(np.median(full) * 1000), "update_ms": float(np.median(update) * 1000)}
        progress("timing on the sample scene", k + 1, len(methods))
    return out


def _summaries(methods, rows, times) -> list[dict]:
    out = []
    for method in methods:
        mine = [r for r in rows if r["method"] == method.label]
        summary = {"label": method.label, "method": asdict(method), **times[method.label]}
        for metric in ("rmse", "ssim", "flip"):
            summary[metric] = float(np.mean([r[metric] for r in mine]))
        summary["groups"] = {g: float(np.mean([r["rmse"] for r in mine if r["group"] == g]))
                             for g in sorted({r["group"] for r in mine})}
        truth = [r["truth"] for r in mine if "truth" in r]
        if truth:
            summary["truth"] = {metric: float(np.mean([t[metric] for t in truth])) for metric in ("rmse", "ssim", "flip")}
        out.append(summary)
    return out


def pareto(points) -> list[bool]:
    """Whether each (time, error) point is on the front: no other point is at least as fast and as
    accurate and better in one of the two."""
    flags = []
    for t, e in points:
        flags.append(not any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for t2, e2 in points))
    return flags


def choose_presets(summaries: list[dict], n64_label: str) -> dict:
    """The presets' rules (viewer/gl/presets.py) applied to the engine's measured settings."""
    # a preset keeps the fitted sigmas (the viewer's sliders tune them), so scaled ones are not candidates
    engine = [s for s in summaries if s["method"]["kind"] == "engine" and s["method"]["sigma_scale"] == 1.0]
    n64 = next(s for s in engine if s["label"] == n64_label)
    fast = [s for s in engine if s["full_ms"] <= INTERACTIVE_MS]
    slow = [s for s in engine if s["full_ms"] <= FINAL_MS]
    close = [s for s in engine if s["rmse"] <= n64["rmse"] * (1 + BALANCED_SLACK)]
    pick = {
        "interactive": min(fast, key=lambda s: (s["rmse"], s["full_ms"])) if fast else min(engine, key=lambda s: s["full_ms"]),
        "balanced": min(close, key=lambda s: s["full_ms"]),
        "final": min(slow or engine, key=lambda s: (s["rmse"], s["full_ms"])),
    }
    return {name: s["label"] for name, s in pick.items()}


def targets(summaries: list[dict], presets, n64_label: str) -> dict:
    by_label = {s["label"]: s for s in summaries}
    balanced = by_label[Method.from_preset(presets["balanced"]).label]
    interactive = by_label[Method.from_preset(presets["interactive"]).label]
    n64 = by_label[n64_label]
    out = {"balanced_vs_64": {"balanced_rmse": balanced["rmse"], "n64_rmse": n64["rmse"],
                              "excess": balanced["rmse"] / n64["rmse"] - 1.0}}
    out["balanced_vs_64"]["met"] = out["balanced_vs_64"]["excess"] <= 0.10
    for kind in ("sh", "directional"):
        family = [s for s in summaries if s["method"]["kind"] == kind]
        rivals = [s for s in family if s["full_ms"] <= balanced["full_ms"]]  # baselines at equal or lower time
        best = min(rivals or family, key=lambda s: s["rmse"])
        out[f"balanced_vs_{kind}"] = {"baseline": best["label"], "baseline_rmse": best["rmse"], "baseline_ms": best["full_ms"],
                                      "balanced_rmse": balanced["rmse"], "balanced_ms": balanced["full_ms"],
                                      "baselines_at_equal_or_lower_time": len(rivals),
                                      "met": balanced["rmse"] < min(s["rmse"] for s in (rivals or family))}
    out["interactive_fps"] = {"full_ms": interactive["full_ms"], "fps": 1000.0 / interactive["full_ms"],
                              "met": interactive["full_ms"] <= 100.0}
    out.update(soft_shadow_targets(summaries, balanced))
    return out


def soft_shadow_targets(summaries: list[dict], balanced: dict) -> dict:
    """The soft shadows' targets: the default soft shadows at N = 16 at least 5 % below hard shadows at the
    same N; no slower than the fastest hard-shadow setting of the same error; and at every time
    budget the best setting that uses lights (engine or directional) uses area lights."""
    n = balanced["method"]["lights"]
    hard = next(s for s in summaries if s["method"]["kind"] == "directional" and s["method"]["lights"] == n)
    out = {"soft_vs_hard": {"lights": n, "soft_rmse": balanced["rmse"], "hard_rmse": hard["rmse"],
                            "gain": 1.0 - balanced["rmse"] / hard["rmse"]}}
    out["soft_vs_hard"]["met"] = out["soft_vs_hard"]["gain"] >= 0.05
    as_good = [s for s in summaries if s["method"]["kind"] == "directional" and s["rmse"] <= balanced["rmse"]]
    fastest = min(as_good, key=lambda s: s["full_ms"]) if as_good else None
    out["soft_vs_hard_equal_error"] = {
        "soft_ms": balanced["full_ms"], "hard": fastest["label"] if fastest else None,
        "hard_ms": fastest["full_ms"] if fastest else None,
        "met": fastest is None or balanced["full_ms"] <= fastest["full_ms"]}
    lit = [s for s in summaries if s["method"]["kind"] in ("engine", "directional")]
    front = [s for s, on in zip(lit, pareto([(s["full_ms"], s["rmse"]) for s in lit])) if on]
    out["front_uses_area_lights"] = {"front": [s["label"] for s in sorted(front, key=lambda s: s["full_ms"])],
                                     "hard_on_front": [s["label"] for s in front if s["method"]["kind"] == "directional"
                                                       or s["method"]["sigma_scale"] == 0.0]}
    out["front_uses_area_lights"]["met"] = not out["front_uses_area_lights"]["hard_on_front"]
    return out


def _low_sun(case: Case, lights, count: int) -> Lighting:
    """The case's lighting whose brightest light is lowest above the horizon (a low sun: long shadows)."""
    def elevation(lighting):
        ls = lights[lighting.map_name, count].rotated(lighting.yaw)
        d = ls.direction[ls.brightest]
        return d[1] if d[1] > 0.0 else np.inf  # camera space: +y is up
    return min(case.lightings, key=elevation)


def _soft_shadow_comparison(ctx, cases, maps: MapStore, lights, config, balanced: Method) -> dict:
    """Hard, CSM, PCSS and the ray-traced reference, side by side on the mask's box, with each
    method's absolute error (linear, after the report's exposure): the sample scene and the first
    held-out person (else the last case), each under its lowest sun."""
    from viewer.lab.bench.metrics import srgb
    from viewer.photo.frames import person_box

    held = [c for c in cases if c.group == "held-out"] or cases[-1:]
    picks = [(case, _low_sun(case, lights, balanced.lights)) for case in (cases[0], held[0])]
    methods = {"hard shadows": replace(balanced, kind="directional"), "CSM (the paper's)": replace(balanced, soft="csm"),
               "PCSS (contact-hardening)": replace(balanced, soft="pcss")}
    rows, error_rows, titles = [], [], []
    for case, lighting in picks:
        ref = reference(case.scene, scene_hash(case.scene), maps, lighting, config.spp)
        s = _exposure(ref, interior(case.scene.mask))
        top, left, height, width = person_box(case.scene.mask)
        y, h, x, w = max(top - 4, 0), height + 8, max(left - 4, 0), width + 8
        row, errors = {}, {}
        truth = np.clip(s * ref, 0.0, 1.0)[y:y + h, x:x + w]
        for label, method in methods.items():
            renderer = Renderer(ctx, method, case.scene)
            try:
                img = renderer.image(lights[lighting.map_name, method.lights].rotated(lighting.yaw))
            finally:
                renderer.release()
            shown = np.clip(s * img, 0.0, 1.0)[y:y + h, x:x + w]
            row[label] = srgb(shown)
            errors[label] = np.abs(shown - truth).mean(axis=-1)  # where each method's error sits
        row["ray-traced (Mitsuba)"] = srgb(truth)
        rows.append(row)
        error_rows.append(errors)
        titles.append(f"{case.name}, {lighting.map_name} at yaw {lighting.yaw:g}")
    return {"rows": rows, "errors": error_rows, "titles": titles, "lights": balanced.lights}


def _temporal(ctx, config, maps: MapStore, lights, presets, progress) -> dict:
    """dRMSE of the presets and baselines against the ray-traced turntable of each map."""
    from viewer.lab.bench.metrics import srgb
    from viewer.lab.data.reference import render_bundle_reference
    from viewer.output.render import turntable_yaws
    from viewer.output.temporal import drmse
    from viewer.scene.bundle import load_scene
    from viewer.scene.resampling import resample_scene

    scene = resample_scene(load_scene(sample_scene_dir()), config.temporal_size)
    key = scene_hash(scene)
    balanced = Method.from_preset(presets["balanced"])
    methods = {name: Method.from_preset(p) for name, p in presets.items()}
    methods.update({"SH order 2": Method("sh"), f"{balanced.lights} directional, hard": replace(balanced, kind="directional"),
                    "torch twin (balanced)": replace(balanced, kind="twin")})
    yaws = turntable_yaws(0.0, 360.0, config.temporal_frames)
    out = {"frames": config.temporal_frames, "size": config.temporal_size, "spp": config.temporal_spp, "maps": {}}
    for name in config.temporal_maps:
        refs = []
        for t, yaw in enumerate(yaws):
            refs.append(reference(scene, key, maps, Lighting(name, float(yaw)), config.temporal_spp, seed=t))
            progress(f"ray-traced turntable {name}", t + 1, len(yaws))
        refs = np.stack(refs)
        s = _exposure(refs.reshape(-1, refs.shape[2], 3), np.tile(scene.mask, (len(yaws), 1)))
        ref_display = srgb(s * refs)
        # the reference's own noise: frame 0 again with other samples (a perfect method scores this)
        again = render_bundle_reference(scene, maps[name], yaw=float(yaws[0]), spp=config.temporal_spp, seed=10_000,
                                        images=("full",))["full"]
        floor = float(np.sqrt(np.mean((srgb(s * again) - ref_display[0]) ** 2)))
        rows = {"reference noise floor": {"drmse": {1: floor, 2: floor, 4: floor}}}
        for k, (label, method) in enumerate(methods.items()):
            renderer = Renderer(ctx, method, scene)
            try:
                frames = []
                for yaw in yaws:
                    ls = lights[name, method.lights].rotated(float(yaw)) if method.uses_lights else None
                    env = maps[name].rotated(float(yaw)) if method.kind == "sh" else None
                    frames.append(srgb(s * renderer.image(ls, env)))
            finally:
                renderer.release()
            rows[label] = {"drmse": drmse(np.stack(frames), ref_display)}
            progress(f"turntables {name}", k + 1, len(methods))
        out["maps"][name] = rows
    return out


def run_report(quick: bool = False, data=None, out_dir=None, maps_dir=None) -> dict:
    from viewer.gl import create_headless_context
    from viewer.gl.presets import PRESETS
    from viewer.lab.bench.report_doc import (
        COMPARISON_FIGURE,
        CONTACT_FIGURE,
        EXAMPLES_FIGURE,
        write_comparison,
        write_contact_figure,
        write_examples,
        write_figures,
        write_markdown,
    )

    config = QUICK if quick else FULL
    out_dir = Path(out_dir or ("out/report-quick" if quick else "out/report"))
    start = time.perf_counter()
    ctx = create_headless_context()
    if quick:
        maps = MapStore(find_maps(asset_dir() / "envmaps"))
    else:
        maps = MapStore(find_maps(maps_dir))
    names = sorted(maps.paths)
    methods = sweep(quick, PRESETS)
    balanced = Method.from_preset(PRESETS["balanced"])
    counts = sorted({m.lights for m in methods if m.uses_lights})
    with StageBars("report: ") as progress:
        cases = _cases(config, maps, names, data)
        lights = _lights_by_map(maps, sorted({l.map_name for c in cases for l in c.lightings} | set(config.temporal_maps)),
                                counts, config.fit_method, progress)
        shown = {REFERENCE: REFERENCE, **{p: Method.from_preset(PRESETS[p]).label for p in PRESETS},
                 "SH order 2": Method("sh").label, "directional": replace(balanced, kind="directional").label}
        examples = dict.fromkeys(shown.values())
        rows = _error_rows(ctx, cases, methods, maps, lights, config, progress, examples)
        timing_names = names[:: max(len(names) // config.timing_maps, 1)][: config.timing_maps]
        times = _timings(ctx, cases[0].scene, methods, maps, lights, timing_names, config, progress)
        temporal = _temporal(ctx, config, maps, lights, PRESETS, progress)
        progress("penumbra width at contact (box over a plane)", 0, 1)
        contact = penumbra_widths(ctx, QUICK_CONTACT if quick else ContactConfig())
        progress("penumbra width at contact (box over a plane)", 1, 1)
        comparison = _soft_shadow_comparison(ctx, cases, maps, lights, config, balanced)
    summaries = _summaries(methods, rows, times)
    for s, on in zip(summaries, pareto([(s["full_ms"], s["rmse"]) for s in summaries])):
        s["pareto"] = on
    n64 = replace(balanced, lights=64).label
    result = {
        "quick": quick, "out_dir": str(out_dir), "config": asdict(config), "machine": _machine(ctx),
        "date": time.strftime("%Y-%m-%d"),
        "cases": [{"name": c.name, "group": c.group, "size": [c.scene.width, c.scene.height], "lightings": len(c.lightings),
                   "with_truth": sum(l.truth is not None for l in c.lightings)} for c in cases],
        "maps": names, "timing_maps": timing_names,
        "methods": summaries, "rows": rows, "temporal": temporal, "reused_rows": sum(bool(r.get("reused")) for r in rows),
        "presets": {name: {"label": Method.from_preset(p).label, "lights": p.lights, "rule": p.rule} for name, p in PRESETS.items()},
        "rule_picks": choose_presets(summaries, n64), "n64": n64,
        "targets": targets(summaries, PRESETS, n64),
        "contact": {**contact, "errors": contact_errors(contact)},
        "comparison": comparison["titles"],
    }
    result["seconds"] = round(time.perf_counter() - start, 1)
    result = json.loads(json.dumps(result))  # the pages read what the JSON holds (string keys)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text(out_dir / "results.json", json.dumps(result, separators=(",", ":")) + "\n")  # every row: compact
    write_figures(result, out_dir)
    first = cases[0]
    pictures = {name: examples[label] for name, label in shown.items() if examples.get(label) is not None}
    write_examples(pictures, f"{first.name}, {first.lightings[0].map_name} at yaw {first.lightings[0].yaw:g}",
                   out_dir / EXAMPLES_FIGURE)
    write_comparison(comparison, out_dir / COMPARISON_FIGURE)
    write_contact_figure(result["contact"], out_dir / CONTACT_FIGURE)
    write_markdown(result, out_dir / "results.md")
    return result
