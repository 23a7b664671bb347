"""The settings ``relight bench report`` measures (kept apart from :mod:`viewer.lab.bench.methods`,
whose code the cached error rows depend on: a new setting computes only its own rows)."""

from __future__ import annotations

from dataclasses import replace

from viewer.lab.bench.methods import Method


def sweep(quick: bool, presets) -> list[Method]:
    """The knobs, one at a time around the balanced preset, plus the presets, corner settings for
    choosing them, and the baselines (directional at every N, SH, the twin at the balanced setting)."""
    base = Method.from_preset(presets["balanced"])
    counts = (4, 16, 64) if quick else (4, 8, 16, 32, 64)
    methods = [replace(base, lights=n) for n in counts]
    methods += [replace(base, shadow_resolution=r) for r in ((256, 1024) if quick else (256, 512, 1024, 2048))]
    methods += [replace(base, terms=m) for m in (2, 4, 8)]
    methods += [replace(base, prefilter=p) for p in ("pyramid", "exact")]
    methods += [replace(base, shadow_step=s) for s in ((1, 4) if quick else (1, 2, 4, 6))]
    methods += [replace(base, leave_out=False)]
    methods += [replace(base, sigma_scale=k) for k in ((0.5,) if quick else (0.25, 0.5))]  # 0 is the directional baseline
    # both soft-shadow methods at every N (against the directional baseline at the same N), and
    # whether the contact-hardening penumbrae are sized right (its sigma read as an angle, x 0.5 to x 3)
    for soft in ("csm", "pcss"):
        methods += [replace(base, soft=soft, lights=n) for n in counts]
    methods += [replace(base, soft="pcss", sigma_scale=k) for k in ((2.0,) if quick else (0.5, 1.5, 2.0, 3.0))]
    if not quick:  # the paper's CSM: more terms, and less softness (its bleeding grows with the blur)
        methods += [replace(base, soft="csm", terms=8), replace(base, soft="csm", sigma_scale=0.5)]
    if not quick:  # corners: cheap and expensive combinations the one-knob sweep does not reach
        for n in (8, 16, 32, 64):  # (terms: for a CSM base; one PCSS setting ignores them)
            methods += [replace(base, lights=n, shadow_resolution=256, terms=2),
                        replace(base, lights=n, shadow_resolution=1024, terms=8)]
    methods += [Method.from_preset(p) for p in presets.values()]
    methods += [replace(base, kind="directional", lights=n) for n in counts]
    methods += [Method("sh"), replace(base, kind="twin")]
    unique = []
    for m in methods:
        if m not in unique:
            unique.append(m)
    return unique
