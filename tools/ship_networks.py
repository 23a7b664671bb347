"""Ship trained networks: copy ``<net>.safetensors`` and their JSON cards from a training folder into
``assets/networks/`` and write the model card ``docs/model-card.md`` from those cards and the
held-out evaluation (``docs/results/bench_networks.json``, from ``relight bench networks``).

    .venv/bin/python tools/ship_networks.py RUN_DIR [--bench docs/results/bench_networks.json]

The cards keep what the training wrote (configuration, data folders, epochs, time, per-epoch
losses); the model card summarizes them for a reader.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NETWORKS = ("inverse", "depth", "refine")
LIMIT_MB = 45.0  # issue 18's budget for all weights
WHAT = {
    "inverse": "photo with its background + mask -> normal; albedo, specular, roughness; 16 area lights",
    "depth": "person + mask -> depth (sigmoid, 1 m around the median)",
    "refine": "per light: hard and soft visibility (trained on CSM; the product feeds it PCSS), sigma, depth -> visibility",
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="training output folder (relight train --out)")
    parser.add_argument("--bench", default=str(ROOT / "docs" / "results" / "bench_networks.json"))
    args = parser.parse_args()
    run, dest = Path(args.run), ROOT / "assets" / "networks"
    dest.mkdir(parents=True, exist_ok=True)
    total = sum((run / f"{n}.safetensors").stat().st_size for n in NETWORKS) / 1e6
    if total > LIMIT_MB:
        raise SystemExit(f"the weights take {total:.1f} MB, over the {LIMIT_MB:.0f} MB budget")
    from viewer.errors import InputError
    from viewer.files.imageio import write_text
    from viewer.nets.weights import load_network

    with tempfile.TemporaryDirectory(dir=dest) as staging:  # nothing replaced until all of them load
        staging = Path(staging)
        for net in NETWORKS:
            for suffix in (".safetensors", ".json"):
                shutil.copyfile(run / f"{net}{suffix}", staging / f"{net}{suffix}")
            try:
                load_network(staging / f"{net}.safetensors")  # what the product will read
            except InputError as exc:
                raise SystemExit(f"not shipped: {exc}") from None
        for net in NETWORKS:
            for suffix in (".safetensors", ".json"):
                os.replace(staging / f"{net}{suffix}", dest / f"{net}{suffix}")
    cards = {net: json.loads((dest / f"{net}.json").read_text()) for net in NETWORKS}
    bench = json.loads(Path(args.bench).read_text()) if Path(args.bench).is_file() else None
    write_text(ROOT / "docs" / "model-card.md", model_card(cards, total, bench))  # atomically
    print(f"shipped {', '.join(NETWORKS)} ({total:.1f} MB) to {dest}; wrote docs/model-card.md")
    return 0


def model_card(cards: dict, total_mb: float, bench: dict | None) -> str:
    from viewer.lab.train import training_stage

    lines = ["# Model card: the shipped networks", "",
             "Written by `tools/ship_networks.py` from the training cards in `assets/networks/*.json` and the held-out",
             "evaluation `docs/results/bench_networks.json`. Method and losses: [networks.md](networks.md).", "",
             "| network | what | parameters | size | resolution | epochs | batch | training time | device | final validation loss |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for net, c in cards.items():
        size = (ROOT / "assets" / "networks" / f"{net}.safetensors").stat().st_size / 1e6
        last = c["history"][-1]
        what = WHAT[net] + (" (+ the mask's silhouette prior)" if "silhouette" in c["model"].get("inputs", ()) else "")
        before = c.get("lineage", [])
        epochs = str(c.get("epochs_done", c["epochs"])) + (f" (after {' + '.join(str(st['epochs']) for st in before)})" if before else "")
        minutes = (c["seconds"] + sum(st["seconds"] or 0 for st in before)) / 60
        lines.append(f"| {net} | {what} | {c['parameters'] / 1e6:.2f} M (width {c['model']['width']}, "
                     f"{c['model']['levels']} levels) | {size:.1f} MB | {c['resolution']}^2 | {epochs} | "
                     f"{c['batch']} | "
                     f"{minutes:.0f} min | {c['device']}, {c['torch_threads']} thread(s) x {c.get('processes', 1)} process(es) | "
                     f"{last['val']:.4f} |")
    c = cards["inverse"]
    lines += ["", f"All weights: {total_mb:.1f} MB (budget {LIMIT_MB:.0f} MB), float32 safetensors.", "",
              "## Data",
              f"- Training: {c['train_items']} (person, lighting) pairs; validation: {c['val_items']} pairs of other people",
              f"  (every tenth person). Folders: {', '.join(c['data'] if isinstance(c['data'], list) else [c['data']])}.",
              "- Synthetic people (anny bodies, procedural clothes, hair and skin) ray traced by Mitsuba 3 under",
              "  procedural maps (docs/dataset.md). No real photo and no held-out map was seen in training.",
              "- Learning rate: cosine-annealed Adam (betas 0.5, 0.999) from "
              f"{c['lr'][0]:g} to {c['lr'][1]:g}; mirror and exposure augmentation."]
    staged = [net for net in cards if cards[net].get("lineage")]
    if staged:
        lines += ["- Fine-tuned: each stage started from the weights of the one before (`relight train --init`); "
                  "epochs and time above add up all stages, newest last:"]
        for net in staged:
            stages = [*reversed(cards[net]["lineage"]), training_stage(cards[net])]
            lines.append(f"  - {net}: " + "; then ".join(
                f"{st['epochs']} epoch{'' if st['epochs'] == 1 else 's'} on {st['train_items']} pairs "
                f"({', '.join(st['data'] if isinstance(st['data'], list) else [st['data']])}), "
                f"lr {st['lr'][0]:g} to {st['lr'][1]:g}, {(st['seconds'] or 0) / 60:.0f} min" for st in stages) + ".")
    for net in ("depth", "inverse"):
        last = cards[net]["history"][-1]
        if net == "depth":
            lines.append(f"- Depth validation: {last['val_metres'] * 100:.2f} cm median-aligned L1, against "
                         f"{last['val_flat_metres'] * 100:.2f} cm for a flat figure at the median depth.")
        else:
            lines.append(f"- Inverse validation: albedo L1 {last['val_albedo']:.3f}, normal {last['val_normal_degrees']:.1f} degrees, "
                         f"diffuse shading L1 {last['val_diffuse_shading']:.3f} (exposed units).")
    if bench is not None:
        from viewer.lab.bench.networks import table

        lines += ["", "## Held-out evaluation", "", table(bench)]
    lines += ["", "## Limits",
              f"- Trained on {cards['inverse']['train_items']} synthetic images, on {cards['inverse']['device']}: far less data and "
              "training than the paper",
              "  (which trains at 1024^2 on a GPU). Expect soft, smoothed maps on real photos.",
              "- The camera is assumed (50 mm on a 36 mm sensor, person at 4 m, as in the paper); depth is relative.",
              "- No hair strands, loose clothes or accessories beyond the synthetic outfits; skin has no subsurface",
              "  scattering.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
