"""The pages of ``relight bench report``: ``results.md`` and its figures, from ``results.json``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viewer.files.imageio import atomic_path, write_text

KNOBS = ("lights", "shadow_resolution", "shadow_step", "terms", "prefilter", "leave_out", "sigma_scale", "soft")
KIND_STYLE = {"engine": ("tab:blue", "o"), "directional": ("tab:orange", "s"), "sh": ("tab:green", "D"), "twin": ("tab:red", "^")}
ERROR_FIGURE = "results_error_vs_time.png"
TEMPORAL_FIGURE = "results_drmse.png"
EXAMPLES_FIGURE = "results_examples.png"
COMPARISON_FIGURE = "results_soft_shadows.png"
CONTACT_FIGURE = "results_contact.png"


def _preset_of(result: dict) -> dict:
    return {p["label"]: name for name, p in result["presets"].items()}


def write_figures(result: dict, out_dir: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = result["methods"]
    presets = _preset_of(result)
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    for ax, metric in zip(axes, ("rmse", "flip")):
        for kind, (color, marker) in KIND_STYLE.items():
            pts = [m for m in methods if m["method"]["kind"] == kind]
            ax.scatter([m["full_ms"] for m in pts], [m[metric] for m in pts], c=color, marker=marker, s=28,
                       label={"engine": "GL engine settings", "directional": "baseline: directional lights, hard shadows",
                              "sh": "baseline: SH order 2, no shadows", "twin": "baseline: torch twin"}[kind], zorder=3)
        front = sorted((m for m in methods if m["pareto"]), key=lambda m: m["full_ms"])
        if metric == "rmse":
            ax.step([m["full_ms"] for m in front], [m["rmse"] for m in front], where="post", color="k", lw=1,
                    alpha=0.6, label="Pareto front (RMSE)", zorder=2)
        for m in methods:
            if m["label"] in presets:
                ax.scatter([m["full_ms"]], [m[metric]], s=220, marker="*", c="gold", edgecolors="k", zorder=4)
                ax.annotate(presets[m["label"]], (m["full_ms"], m[metric]), textcoords="offset points", xytext=(6, 6),
                            fontsize=9, weight="bold")
        ax.set_xscale("log")
        ax.set_xlabel(f"full frame (ms, median), sample scene {result['config']['sample_size']}^2")
        ax.set_ylabel({"rmse": "RMSE vs ray-traced reference", "flip": "FLIP vs ray-traced reference"}[metric])
        ax.axvline(100.0, color="grey", ls=":", lw=1)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7, loc="upper right")
    m = result["machine"]
    fig.suptitle(f"Error against run time ({m['cores']} cores, {m['gl']}); stars: presets; dotted: 100 ms", fontsize=10)
    fig.tight_layout()
    with atomic_path(out_dir / ERROR_FIGURE) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)

    temporal = result["temporal"]["maps"]
    labels = [k for k in next(iter(temporal.values()))]
    fig, axes = plt.subplots(1, len(temporal), figsize=(6.5 * len(temporal), 4.2), squeeze=False)
    for ax, (name, rows) in zip(axes[0], temporal.items()):
        x = np.arange(len(labels))
        for j, step in enumerate(("1", "2", "4")):
            ax.bar(x + (j - 1) * 0.27, [rows[label]["drmse"][step] for label in labels], 0.27, label=f"step {step}")
        ax.set_xticks(x, labels, rotation=30, ha="right", fontsize=8)
        ax.set_title(name, fontsize=10)
        ax.set_ylabel("dRMSE (display values)")
        ax.grid(alpha=0.3, axis="y")
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"Temporal stability: {result['temporal']['frames']}-frame turntables against the ray-traced one", fontsize=10)
    fig.tight_layout()
    with atomic_path(out_dir / TEMPORAL_FIGURE) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def write_examples(images: dict, title: str, path: Path):
    """A row of display images (label -> (H, W, 3) in [0, 1]) with their labels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(images), figsize=(2.6 * len(images), 3.2), squeeze=False)
    for ax, (label, img) in zip(axes[0], images.items()):
        ax.imshow(np.clip(img, 0, 1))
        ax.set_title(label, fontsize=8)
        ax.axis("off")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def write_comparison(comparison: dict, path: Path):
    """Rows of (hard, CSM, PCSS, ray-traced) crops, one row per lighting."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = comparison["rows"]
    cols = list(rows[0])
    fig, axes = plt.subplots(2 * len(rows), len(cols), figsize=(2.9 * len(cols), 8.4 * len(rows)), squeeze=False)
    for r, (row, errors, title) in enumerate(zip(rows, comparison["errors"], comparison["titles"])):
        top = max(float(np.percentile(e, 99.5)) for e in errors.values()) or 1.0
        for c, label in enumerate(cols):
            ax = axes[2 * r][c]
            ax.imshow(np.clip(row[label], 0, 1))
            ax.set_title(label if c else f"{title}\n{label}", fontsize=8)
            ax.axis("off")
            ax = axes[2 * r + 1][c]
            ax.axis("off")
            if label in errors:
                ax.imshow(errors[label], cmap="magma", vmin=0.0, vmax=top)
                ax.set_title(f"|error|, mean {errors[label].mean():.4f}", fontsize=8)
    fig.suptitle(f"{comparison['lights']} fitted lights: hard shadows, the paper's CSM, contact-hardening PCSS, "
                 "and the ray-traced reference of the same depth mesh", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


CONTACT_STYLE = {"truth": ("k", "o", "ray-traced (Mitsuba)"), "pcss": ("tab:blue", "s", "PCSS (contact-hardening)"),
                 "csm": ("tab:red", "^", "CSM (the paper's)"), "hard": ("tab:orange", "D", "hard shadow map")}


def write_contact_figure(contact: dict, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.2, 4.2))
    heights = [100.0 * h for h in contact["heights"]]
    for key, (color, marker, label) in CONTACT_STYLE.items():
        ax.plot(heights, [w * contact["pixel_mm"] / 10.0 for w in contact[key]], color=color, marker=marker, label=label)
    ax.set_xlabel("blocker-receiver distance (cm)")
    ax.set_ylabel("penumbra width on the plane (cm)")
    ax.set_title(f"A box over a plane, one Gaussian light of {contact['angle_deg']:.1f} deg (sigma {contact['sigma']:g})",
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def _contact_lines(contact: dict) -> list[str]:
    px = contact["pixel_mm"] / 10.0
    lines = ["| method | " + " | ".join(f"{100 * h:g} cm" for h in contact["heights"]) + " | mean abs. error | error at the lowest |",
             "|---|" + "---|" * (len(contact["heights"]) + 2)]
    for key, (_, _, label) in CONTACT_STYLE.items():
        err = contact["errors"].get(key)
        tail = f" | {err['mean_abs_px'] * px:.1f} cm | {err['lowest_abs_px'] * px:.1f} cm |" if err else " | - | - |"
        lines.append(f"| {label} | " + " | ".join(f"{w * px:.1f}" for w in contact[key]) + tail)
    return lines


def _f(x, digits=4):
    return f"{x:.{digits}f}"


def _knob_rows(result: dict) -> list[str]:
    """One line per knob: the values the sweep tried around the balanced setting."""
    label = result["presets"]["balanced"]["label"]
    base = next(m for m in result["methods"] if m["label"] == label)["method"]
    lines = []
    for knob in KNOBS:
        pts = [m for m in result["methods"] if m["method"]["kind"] == "engine"
               and all(m["method"][k] == base[k] for k in KNOBS if k != knob)]
        pts.sort(key=lambda m: m["method"][knob])
        cells = ", ".join(f"{m['method'][knob]}: {m['full_ms']:.0f} ms / {m['rmse']:.4f}" for m in pts)
        lines.append(f"| {knob} | {cells} |")
    return lines


def _groups(result: dict) -> list[str]:
    return sorted({r["group"] for r in result["rows"]})


SOFT_HARD = (("CSM", {"kind": "engine", "soft": "csm"}), ("PCSS", {"kind": "engine", "soft": "pcss"}),
             ("hard", {"kind": "directional"}))


def _soft_hard_rows(result: dict, groups: list[str]) -> list[str]:
    """Per N: the engine with each soft-shadow method at the balanced options against the
    directional baseline (hard shadows) at the same N."""
    base = next(m for m in result["methods"] if m["label"] == result["presets"]["balanced"]["label"])["method"]
    lines = []
    for n in sorted({m["method"]["lights"] for m in result["methods"] if m["method"]["kind"] == "directional"}):
        cells = []
        for _, change in SOFT_HARD:
            want = {**base, **change, "lights": n}
            hit = [m for m in result["methods"] if m["method"] == want]
            if not hit:
                break
            mine = [r for r in result["rows"] if r["method"] == hit[0]["label"]]
            cells.append(f"{hit[0]['full_ms']:.0f} ms")
            for g in groups:
                rows = [r for r in mine if r["group"] == g]
                cells.append(f"{np.mean([r['rmse'] for r in rows]):.4f} / {np.mean([r['flip'] for r in rows]):.4f}")
        if len(cells) == len(SOFT_HARD) * (1 + len(groups)):
            lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return lines


def write_markdown(result: dict, path: Path):
    m = result["machine"]
    config = result["config"]
    presets = _preset_of(result)
    by_label = {s["label"]: s for s in result["methods"]}
    groups = _groups(result)
    lines = [
        "# Error against run time, temporal stability and the quality presets",
        "",
        f"Generated by `relight bench report{' --quick' if result['quick'] else ''}` on {result['date']} in "
        f"{result['seconds'] / 60:.1f} minutes. Machine: {m['cores']} cores ({m['cpu']}, {m['system']}), OpenGL: {m['gl']}, "
        f"Python {m['python']}. Every time below was measured in that one run; "
        + (f"{result['reused_rows']} of the {len(result['rows'])} error rows (deterministic renders of unchanged settings) "
           "were kept from an earlier run of the same settings." if result["reused_rows"] else "so was every error."),
        "",
    ]
    if result["quick"]:
        lines += ["**Quick configuration** (CI's harness check): a small sample, few maps and frames. Its numbers are "
                  "not the report's; `relight bench report` makes the full one in `docs/results/results.md`.", ""]
    lines += [
        "## What is measured",
        "",
        "| case | group | size | lightings | with dataset truth |",
        "|---|---|---|---|---|",
        *[f"| {c['name']} | {c['group']} | {c['size'][0]}x{c['size'][1]} | {c['lightings']} | {c['with_truth']} |"
          for c in result["cases"]],
        "",
        f"- **Lightings**: area lights fitted by `{config['fit_method']}` (cached), the maps {', '.join(result['maps'])}; "
        f"the sample scene at yaws {', '.join(f'{y:g}' for y in config['yaws'])}, "
        "the photo at yaw 0, each held-out person at one random yaw plus its dataset records' own lightings.",
        f"- **Reference**: Mitsuba 3 (`direct` integrator, `principled` BSDF, {config['spp']} spp) of each bundle's own depth mesh "
        "and maps under the whole turned map (docs/reference.md): the exact image the engine approximates. Where a lighting is "
        "a dataset record, also the dataset's ray-traced render of the full 3D person (column *truth*), which no depth-map "
        "method can match at occluded or grazing surfaces.",
        "- **Error**: both images scaled so the reference's 99th percentile of luminance is 0.9 and clipped to [0, 1] (the "
        "displayed range: a sun's highlight 1e5 times brighter than the sky would otherwise be the whole RMSE, and the "
        "reference's Monte Carlo fireflies with it); RMSE over the mask less its one-pixel border; SSIM on the mask's box; "
        "FLIP (NVIDIA, LDR) on the sRGB images. Means over every case and lighting.",
        f"- **Time**: on the sample scene at {config['sample_size']}^2 under {', '.join(result['timing_maps'])}, "
        f"{config['repeats']} frames each; *full*: the lighting turned by 3 degrees (every light moved); *update*: the "
        "brightest light's sigma and intensity edited (a slider). Medians. SH (numpy) and the torch twin cache nothing, so "
        "their update is a full frame.",
        "",
        "## Presets",
        "",
        "| preset | setting | full frame | update | RMSE | SSIM | FLIP | rule | the rule's pick in this run |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, p in result["presets"].items():
        s = by_label[p["label"]]
        pick = result["rule_picks"][name]
        lines.append(f"| **{name}** | {p['label']} | {s['full_ms']:.0f} ms ({1000 / s['full_ms']:.1f} fps) | {s['update_ms']:.0f} ms | "
                     f"{_f(s['rmse'])} | {_f(s['ssim'], 3)} | {_f(s['flip'])} | {p['rule']} | "
                     f"{'the same' if pick == p['label'] else pick} |")
    t = result["targets"]
    b64, bsh, bdir, fps = t["balanced_vs_64"], t["balanced_vs_sh"], t["balanced_vs_directional"], t["interactive_fps"]

    def mark(ok):
        return "met" if ok else "**not met**"

    lines += [
        "",
        "Balanced is the default of the engine (`EngineOptions()`), the viewer and `relight render` "
        "(`--preset` picks another). Where a shipped preset differs from its rule's pick, viewer/gl/presets.py says why.",
        "",
        "## Targets",
        "",
        f"- Balanced within 10 % of the 64-light error: RMSE {_f(b64['balanced_rmse'])} against {_f(b64['n64_rmse'])} "
        f"({100 * b64['excess']:+.1f} %): {mark(b64['met'])}.",
        f"- Balanced against SH order 2 without shadows: RMSE {_f(bsh['balanced_rmse'])} at {bsh['balanced_ms']:.0f} ms against "
        f"{_f(bsh['baseline_rmse'])} at {bsh['baseline_ms']:.0f} ms: {mark(bsh['met'])}.",
        f"- Balanced against directional lights with hard shadows: the best of the {bdir['baselines_at_equal_or_lower_time']} "
        f"settings at equal or lower time is {bdir['baseline']} with RMSE {_f(bdir['baseline_rmse'])} at {bdir['baseline_ms']:.0f} ms: "
        f"{mark(bdir['met'])}.",
        f"- Interactive at >= 10 frames per second at 512^2: full frame {fps['full_ms']:.0f} ms ({fps['fps']:.1f} fps) "
        f"at {config['sample_size']}^2: {mark(fps['met'])}.",
        f"- Soft shadows at N = {t['soft_vs_hard']['lights']} at least 5 % below hard shadows at the same N: RMSE "
        f"{_f(t['soft_vs_hard']['soft_rmse'])} against {_f(t['soft_vs_hard']['hard_rmse'])} "
        f"({100 * t['soft_vs_hard']['gain']:.1f} % lower): {mark(t['soft_vs_hard']['met'])}.",
        "- Soft shadows no slower than hard shadows of the same error: "
        + (f"the fastest hard-shadow setting at least as accurate, {t['soft_vs_hard_equal_error']['hard']}, takes "
           f"{t['soft_vs_hard_equal_error']['hard_ms']:.0f} ms against {t['soft_vs_hard_equal_error']['soft_ms']:.0f} ms"
           if t["soft_vs_hard_equal_error"]["hard"] else "no hard-shadow setting reaches the balanced error")
        + f": {mark(t['soft_vs_hard_equal_error']['met'])}.",
        "- At every time budget the best setting with lights uses area lights (the Pareto front of the engine and "
        "directional settings): "
        + (f"hard shadows on the front: {', '.join(t['front_uses_area_lights']['hard_on_front'])}"
           if t["front_uses_area_lights"]["hard_on_front"] else "no hard-shadow setting is on it")
        + f": {mark(t['front_uses_area_lights']['met'])}.",
        "",
        f"![error against time]({ERROR_FIGURE})",
        "",
        "## Each knob around the balanced setting (full frame / RMSE)",
        "",
        "| knob | values |",
        "|---|---|",
        *_knob_rows(result),
        "",
        "## Soft shadows (area lights) against hard shadows (directional lights) at equal N",
        "",
        "Same fitted lights, same engine; *CSM* is the paper's convolutional shadow maps, *PCSS* the contact-hardening "
        "soft shadows (docs/engine.md), *hard* sets every sigma to 0 (shadow maps only). RMSE / FLIP per group. "
        "The knob `sigma_scale` above (the fitted sigmas times 0.25 to 3, for the balanced soft shadows) shows whether "
        "the penumbrae are sized right; *Every setting* has the CSM with its sigmas x 0.5 and with M = 8 terms.",
        "",
        "| N | " + " | ".join(f"{name}: full frame | " + " | ".join(f"{name}: {g}" for g in groups) for name, _ in SOFT_HARD) + " |",
        "|---|" + "---|" * (len(SOFT_HARD) * (1 + len(groups))),
        *_soft_hard_rows(result, groups),
        "",
        f"![hard, CSM, PCSS and ray-traced]({COMPARISON_FIGURE})",
        "",
        "## Penumbra width at contact",
        "",
        "A square box face (60 cm) at several heights over a plane, one Gaussian light from the side; the width of the "
        "partial shadow (visibility between 0.15 and 0.85) on the plane beside the box, mean over the middle half of the "
        f"box's rows, in cm ({result['contact']['pixel_mm']:.1f} mm per pixel). Ray-traced: Mitsuba's shadowed diffuse of a "
        "map that is black but for that light (viewer/lab/bench/contact.py).",
        "",
        *_contact_lines(result["contact"]),
        "",
        f"![penumbra width at contact]({CONTACT_FIGURE})",
        "",
        "## Every setting, fastest first",
        "",
        "| setting | full frame | update | RMSE | SSIM | FLIP | RMSE per group | truth RMSE / FLIP | Pareto |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for s in sorted(result["methods"], key=lambda s: s["full_ms"]):
        name = f"**{s['label']}** ({presets[s['label']]})" if s["label"] in presets else s["label"]
        groups = ", ".join(f"{g} {_f(v)}" for g, v in s["groups"].items())
        truth = f"{_f(s['truth']['rmse'])} / {_f(s['truth']['flip'])}" if "truth" in s else "-"
        lines.append(f"| {name} | {s['full_ms']:.1f} ms | {s['update_ms']:.1f} ms | {_f(s['rmse'])} | {_f(s['ssim'], 3)} | "
                     f"{_f(s['flip'])} | {groups} | {truth} | {'yes' if s['pareto'] else ''} |")
    temporal = result["temporal"]
    lines += [
        "",
        "## Temporal stability",
        "",
        f"dRMSE (docs/viewer.md) of {temporal['frames']}-frame turntables of the sample scene at {temporal['size']}^2 "
        f"against the ray-traced turntable ({temporal['spp']} spp, its own samples per frame), in display values (sRGB, "
        "the reference's exposure). *Reference noise floor*: the RMSE between two ray-traced renders of the same frame with "
        "different samples, which a perfect method would also score.",
        "",
        "| method | " + " | ".join(f"{name} step 1 / 2 / 4" for name in temporal["maps"]) + " |",
        "|---|" + "---|" * len(temporal["maps"]),
    ]
    labels = list(next(iter(temporal["maps"].values())))
    for label in labels:
        cells = [" / ".join(_f(rows[label]["drmse"][k]) for k in ("1", "2", "4")) for rows in temporal["maps"].values()]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines += ["", f"![dRMSE]({TEMPORAL_FIGURE})", ""]
    if (path.parent / EXAMPLES_FIGURE).is_file():
        lines += ["## One lighting, side by side", "", f"![examples]({EXAMPLES_FIGURE})", ""]
    write_text(path, "\n".join(lines))
