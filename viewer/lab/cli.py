"""The lab's commands, ``relight dataset``, ``relight train`` and ``relight bench``: offline work
(synthetic data, ray-traced truth, training, benchmarks) that imports the product and is never
imported by it. The product's command line finds these through the ``relight.commands`` entry
points (pyproject.toml) and loads this module only when one of them runs.

Folders of shared data (the held-out environment maps, the real photos) are arguments; their
default is the folder named by the environment variable ``RELIGHT_DATA`` (``hdri/`` and
``photos/`` inside it; the Makefile sets it to ``../shared/data``, the checkout's neighbour).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from viewer.errors import InputError

DATA_VARIABLE = "RELIGHT_DATA"


def plate_photos(folders) -> list[Path]:
    """The photos (.jpg, .jpeg, .png; not a mask, hand-made or automatic) of ``folders``, sorted: the plates
    bench's people put back into their own photo."""
    return sorted(p for f in folders for p in Path(f).iterdir()
                  if p.suffix.lower() in (".jpg", ".jpeg", ".png") and "mask" not in p.name.lower() and not p.name.startswith("."))


def clip_files(given: list) -> list[Path]:
    """The clips named, a folder's clips (sorted) in its place."""
    from viewer.files.clip_reader import VIDEO_SUFFIXES

    clips = []
    for path in map(Path, given):
        clips += sorted(p for p in path.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES) if path.is_dir() else [path]
    return clips


def shared_folder(given: str | None, part: str, option: str) -> Path:
    """The folder given on the command line, else ``$RELIGHT_DATA/<part>``; one line when neither."""
    if given:
        return Path(given)
    root = os.environ.get(DATA_VARIABLE)
    if not root:
        raise InputError(None, f"give {option} DIR, or set {DATA_VARIABLE} to the shared data folder (the one holding hdri/ "
                               "and photos/, e.g. ../shared/data)")
    return Path(root) / part


def cmd_dataset(args) -> int:
    from viewer.lab.data.dataset import DatasetConfig, make_dataset, parse_shard
    from viewer.progress import StageBars

    cfg = DatasetConfig(out=Path(args.out), count=args.count, res=args.res, seed=args.seed, shard=parse_shard(args.shard),
                        spp=args.spp, lightings=args.lightings, split=args.split, pool=args.pool, frames=args.frames,
                        held_out_dir=shared_folder(args.maps, "hdri", "--maps") if args.split in ("heldout", "clip") else None)
    start = time.perf_counter()
    with StageBars(prefix=f"dataset {cfg.out.name} {args.shard}: ") as bars:
        manifest = make_dataset(cfg, progress=bars)
    seconds = time.perf_counter() - start
    per = manifest["seconds_per_sample_median"]
    what = "clips" if cfg.split == "clip" else "samples"
    print(f"{manifest['made']} {what} made ({manifest['relit_pairs_made']} relit pairs), {manifest['skipped_finished']} "
          f"already there, in {seconds:.0f} s" + (f"; {per:.1f} s per {what[:-1]} (median)" if per else "")
          + f"; peak memory {manifest['peak_memory_mb']:.0f} MB")
    print(f"wrote {manifest['path']}")
    return 0


def cmd_dataset_preview(args) -> int:
    from viewer.lab.data.preview import preview

    if not 1 <= args.count <= 32:
        raise InputError(None, f"--count must be 1 to 32, got {args.count}")
    for path in preview(Path(args.out), args.seed, args.count):
        print(f"wrote {path}")
    return 0


def cmd_train(args) -> int:
    from viewer.lab.train import TrainConfig, train
    from viewer.progress import StageBars

    data = [Path(d) for d in args.data]
    cfg = TrainConfig(task=args.network, data=data if len(data) > 1 else data[0], out=Path(args.out), res=args.res,
                      epochs=args.epochs, batch=args.batch, lr=args.lr, width=args.width, levels=args.levels,
                      device=args.device, seed=args.seed, perceptual_weight=args.perceptual_weight,
                      silhouette=args.silhouette, body_prior=args.body_prior,
                      init=Path(args.init) if args.init else None)
    with StageBars(prefix=f"training {args.network}: ") as bars:
        card = train(cfg, progress=bars)
    if card is None:  # a torchrun worker other than rank 0: rank 0 reports
        return 0
    last = card["history"][-1]
    val = f", validation {last['val']:.4g}" if last.get("val") is not None else ""
    print(f"{args.network}: {card['epochs']} epochs in {card['seconds']:.0f} s on {card['device']} "
          f"({card['parameters'] / 1e6:.2f} M parameters); training loss {last['train']:.4g}{val}")
    print(f"wrote {Path(args.out) / card['weights']} and its card {Path(args.out) / (args.network + '.json')}")
    return 0


def photos_table(result: dict) -> str:
    """The bench photos figures as text."""
    lines = []
    for row in result["photos"]:
        ex = row["explains_photo"]
        mask = row.get("mask", {})
        lines.append(f"{row['photo']}: mask IoU {mask.get('iou', float('nan')):.3f}, mean |difference| "
                     f"{mask.get('mean_abs_percent', float('nan')):.2f} %; the photo's lighting "
                     f"explains it to {ex['fitted']['psnr_db']:.1f} dB / SSIM {ex['fitted']['ssim']:.3f} "
                     f"(the network's guess {ex['network']['psnr_db']:.1f} dB); inference {row['inference_seconds_total']:.1f} s")
        matte = row.get("matte", {})
        if "spill" in matte:
            pink = matte["backdrop"]
            lines.append(f"  matte in the output: spill {matte['spill']:.3f} px, cut {matte['cut']:.3f} px, bleed "
                         f"{matte['bleed']:.3f}; on a pink backdrop: kept {pink['kept']:.3f} px, spill {pink['spill']:.3f}, "
                         f"cut {pink['cut']:.3f}, bleed {pink['bleed']:.3f}; matte {sum(row['matte_seconds'].values()):.2f} s")
        elif matte:
            lines.append(f"  matte in the output: bleed {matte['bleed']:.3f}")
        for method, m in row["methods"].items():
            kept = ", ".join(f"{v:.2f}" for v in m["detail_kept"].values())
            lines.append(f"  {method:>17}: detail kept {kept} (mean {m['detail_kept_mean']:.2f}); light moved {m['light_moved']:.2f}"
                         + (f"; under its own lights {m['own_lights']['psnr_db']:.1f} dB" if "own_lights" in m else "")
                         + (f"; {m['times_ms']}" if "times_ms" in m else ""))
    if "heldout" in result:
        h = result["heldout"]
        lines.append(f"held-out: {h['pairs']} pairs of {h['people']} people at {h['resolution']}^2")
        for method in result["methods"] + ["before"]:
            if method in h:
                d = h[method]["rmse"]["vs_network"]
                lines.append(f"  {method:>17}: RMSE {h[method]['rmse']['mean']:.4f} SSIM {h[method]['ssim']['mean']:.4f} "
                             f"FLIP {h[method]['flip']['mean']:.4f}; RMSE against the network's albedo {d['mean']:+.4f} "
                             f"+- {d['stderr']:.4f}, better in {d['better_pairs']}/{h['pairs']} pairs")
    return "\n".join(lines)


def cmd_bench(args) -> int:
    from viewer.lab.bench.engine import run_engine_benchmark

    output = args.output or f"out/bench_{args.what}.json"  # report and photos take a folder (below)
    if args.what == "engine":
        run_engine_benchmark(sizes=args.sizes, light_counts=args.lights, repeats=args.repeats,
                             output=output, twin=not args.no_twin, twin_device=args.twin_device)
    elif args.what == "timings":
        from viewer.lab.bench.timings import run_timings_benchmark, table

        last = args.last or Path(__file__).resolve().parents[2] / "docs" / "results" / "bench_timings.json"
        print(table(run_timings_benchmark(shared_folder(args.maps, "hdri", "--maps"), output, last_path=last, repeats=args.repeats)))
    elif args.what == "contention":
        from viewer.lab.bench.contention import run_contention_benchmark, table

        print(table(run_contention_benchmark(shared_folder(args.maps, "hdri", "--maps"), repeats=args.repeats, output=output)))
    elif args.what == "viewer":
        from viewer.lab.bench.viewer import run_viewer_benchmark

        photos = shared_folder(args.photos, "photos", "--photos") if args.photos or os.environ.get(DATA_VARIABLE) else None
        maps = shared_folder(args.maps, "hdri", "--maps") if args.maps or os.environ.get(DATA_VARIABLE) else None
        run_viewer_benchmark(sizes=args.sizes, photos=photos, output=output, maps=maps)
    elif args.what == "matte" and args.backdrops:
        from viewer.lab.bench.backdrops import backdrops_table, run_backdrops_benchmark

        output = args.output or "out/bench_backdrops.json"
        result = run_backdrops_benchmark([shared_folder(args.photos, "photos", "--photos"), *(args.set or [])],
                                         shared_folder(args.maps, "hdri", "--maps"), output, before=args.before,
                                         progress=lambda what: print(what, flush=True))
        print(backdrops_table(result))
        print(f"wrote {output} in {result['seconds'] / 60:.1f} min")
    elif args.what == "matte":
        from viewer.lab.bench.matte import run_matte_benchmark, table

        result = run_matte_benchmark(shared_folder(args.photos, "photos", "--photos"), output=output,
                                     repeats=args.repeats, progress=lambda what: print(f"  measured {what}", flush=True))
        print(table(result))
        print(f"wrote {output}")
    elif args.what == "upsample":
        from viewer.lab.bench.upsample import run_upsample_benchmark, table

        out_dir = Path(args.output or "out/bench-upsample")
        result = run_upsample_benchmark(shared_folder(args.photos, "photos", "--photos"), out_dir, repeats=args.repeats,
                                        progress=lambda what: print(f"  measured {what}", flush=True))
        print(table(result))
        print(f"wrote {out_dir / 'upsample.json'}, {out_dir / 'upsample.jpg'}")
    elif args.what == "batch":
        from viewer.batch.plan import collect_photos
        from viewer.lab.bench.batch import BATCH_MAPS, run_batch_benchmark

        maps = shared_folder(args.maps, "hdri", "--maps")
        photos, _ = collect_photos([shared_folder(args.photos, "photos", "--photos")])
        run_batch_benchmark(photos, [maps / m for m in BATCH_MAPS], count=args.count, output=output)
    elif args.what == "ground":
        from viewer.lab.bench.ground import run_ground_benchmark

        run_ground_benchmark(output=output, repeats=args.repeats)
    elif args.what == "light-sizes":
        from viewer.lab.bench.light_sizes import run_light_sizes_benchmark

        run_light_sizes_benchmark(shared_folder(args.maps, "hdri", "--maps"), output=output)
    elif args.what == "clip-memory":
        from viewer.lab.bench.clip_memory import run_clip_memory_benchmark

        maps = shared_folder(args.maps, "hdri", "--maps")
        out = Path(args.output or "out/bench-clip-memory/clip_memory.json")
        result = run_clip_memory_benchmark((args.env and Path(args.env[0])) or maps / "potsdamer_platz_1k.hdr", out.parent, output=out)
        print(f"peak memory grew {100 * result['growth']:.1f} % from {result['runs'][0]['seconds']:g} s to "
              f"{result['runs'][-1]['seconds']:g} s; wrote {out}")
    elif args.what == "plates":
        from viewer.lab.bench.plates import heldout_maps, run_plates_benchmark

        out = Path(args.output or "out/bench-plates/plates.json")
        maps = heldout_maps(out.parent / "maps", args.procedural) if args.procedural else shared_folder(args.maps, "hdri", "--maps")
        photos = None if args.procedural else plate_photos([shared_folder(args.photos, "photos", "--photos"), *(args.set or [])])
        summary = run_plates_benchmark(maps, out, photos=photos)["summary"]
        print(f"person RMSE (means): estimate {summary['estimate']:.4f}, uniform {summary['uniform']:.4f} "
              f"({summary['estimate_over_uniform']:.2f} x), sh {summary['sh']:.4f} ({summary['estimate_over_sh']:.2f} x); per plate, "
              f"the median of its ratio to uniform {summary['estimate_over_uniform_median']:.3f} x, to sh "
              f"{summary['estimate_over_sh_median']:.3f} x; "
              + ("no plate with a dominant light" if summary["direction_deg_median"] is None else
                 f"dominant light off by {summary['direction_deg_median']:.1f} degrees, the brightest direction (5-degree blur) "
                 f"by {summary['brightest_deg_median']:.1f} (medians)")
              + (f"; a person put back into their own photo {summary['identity_median_stops']:+.2f} stops, RMSE "
                 f"{summary['identity_median_rmse_levels']:.1f} levels (medians)" if photos else "") + f"; wrote {out}")
        for label, part in (("plates of maps", summary), ("plates that show people", summary.get("people_plates"))):
            if part:
                print(f"each cue alone on the {label} with a dominant light: " + "; ".join(
                    f"the {name} read a sun on {part[key]['read']} of {part[key]['plates']}"
                    + (f", {part[key]['deg_median']:.1f} degrees off (median)" if part[key]["deg_median"] is not None else "")
                    for name, key in (("clear sky", "sky_cue"), ("people's shadows", "shadows_cue"),
                                      ("people's shading", "shading_cue"))))
        shown = summary.get("people_plates")
        if shown:
            print(f"plates that show people: per plate, the median of the estimate's RMSE over uniform's "
                  f"{shown['estimate_over_uniform_median']:.3f} x, over sh's {shown['estimate_over_sh_median']:.3f} x; "
                  + ("no plate with a dominant light" if shown["brightest_deg_median"] is None else
                     f"the brightest direction (5-degree blur) off by {shown['brightest_deg_median']:.1f} degrees (median)"))
    elif args.what == "video" and args.truth:
        from viewer.lab.bench.clip_truth import run_truth_benchmark, truth_table

        out = Path(args.output or "out/bench-video/truth.json")
        print(truth_table(run_truth_benchmark(Path(args.truth), out.parent, output=out)))
        print(f"wrote {out}")
    elif args.what == "video":
        from viewer.lab.bench.video import run_video_benchmark, synthetic_clip, video_table

        out = Path(args.output or "out/bench-video/video.json")
        clips = ([synthetic_clip(out.parent)] if args.synthetic else []) + \
            clip_files(args.clips or ([] if args.synthetic else [shared_folder(None, "videos", "--clips")]))
        maps = [Path(m) for m in args.env] if args.env else [shared_folder(args.maps, "hdri", "--maps") / f"{m}_1k.hdr"
                                                             for m in ("potsdamer_platz", "rooitou_park")]
        print(video_table(run_video_benchmark(clips, maps, out.parent, args.start, args.end, args.max_size, output=out)))
        print(f"wrote {out}")
    elif args.what == "temporal":
        from viewer.lab.bench.temporal import run_temporal_benchmark

        run_temporal_benchmark(output=output)
    elif args.what == "networks":
        from viewer.lab.bench.networks import run_networks_benchmark, table
        from viewer.progress import StageBars

        if not args.data:
            raise InputError(None, "bench networks needs --data: a held-out dataset (relight dataset make --split heldout)")
        with StageBars(prefix="evaluating: ") as bars:
            result = run_networks_benchmark(args.data if len(args.data) > 1 else args.data[0], args.networks,
                                            output=output, limit=args.limit,
                                            progress=bars, face=not args.no_face)
        print(table(result))
    elif args.what == "bodyfit":
        from viewer.lab.bench.body_fit import run_body_fit_benchmark
        from viewer.progress import StageBars

        if not args.data or len(args.data) > 1:
            raise InputError(None, "bench bodyfit needs --data and one dataset made by relight dataset make")
        if args.limit is not None and args.limit < 1:
            raise InputError(None, f"--limit must be at least 1, got {args.limit}")
        with StageBars(prefix="fitting: ") as bars:
            result = run_body_fit_benchmark(args.data[0], limit=args.limit or 12, output=output, progress=bars)
        s = result["summary"]
        d = s["depth_l1_cm"]

        def num(v, unit=""):
            return "-" if v is None else f"{v:.2f}{unit}"

        print(f"{s['landmarks_found']}/{s['people']} people found by MediaPipe; depth L1 (median-aligned): fitted body "
              f"{num(d['fitted'], ' cm')}, the experiment's prior {num(d['experiment_prior'], ' cm')}, a flat figure "
              f"{num(d['flat'], ' cm')}; mask IoU {num(s['iou']['fitted'])} (prior {num(s['iou']['experiment_prior'])}); "
              f"reprojection {num(s['reprojection_px'], ' px')}; {num(s['seconds_per_fit'], ' s')} per fit; wrote {output}")
    elif args.what == "report":
        from viewer.lab.bench.report import run_report

        if args.data and len(args.data) > 1:
            raise InputError(None, "bench report takes one held-out dataset (--data DIR)")
        result = run_report(quick=args.quick, data=args.data[0] if args.data else None, out_dir=args.output,
                            maps_dir=None if args.quick else shared_folder(args.maps, "hdri", "--maps"))
        for name, p in result["presets"].items():
            s = next(m for m in result["methods"] if m["label"] == p["label"])
            print(f"{name:>11}: {p['label']:<44} {s['full_ms']:7.1f} ms  RMSE {s['rmse']:.4f}  FLIP {s['flip']:.4f}")
        for name, t in result["targets"].items():
            print(f"target {name}: {'met' if t['met'] else 'NOT met'}")
        print(f"wrote {Path(result['out_dir']) / 'results.md'} (+ results.json and figures) in {result['seconds'] / 60:.1f} min")
    elif args.what == "people":
        from viewer.lab.bench.people import people_table, run_people

        out_dir = Path(args.output or "out/bench-people")
        result = run_people(clip_files(args.clips or [shared_folder(None, "videos", "--clips")]), out_dir, min(args.max_size, 1280),
                            progress=lambda line: print(line, flush=True))
        print(people_table(result))
        print(f"wrote {out_dir / 'people.json'} and a strip of frames per clip in {result['seconds'] / 60:.1f} min")
    elif args.what == "spread":
        from viewer.lab.bench.spread import NAMES, RUNS, run_spread_benchmark

        out_dir = Path(args.output or "out/bench-spread")
        maps = shared_folder(args.maps, "hdri", "--maps")
        result = run_spread_benchmark(clip_files(args.clips or [shared_folder(None, "videos", "--clips")]),
                                      Path(args.env[0]) if args.env else maps / "potsdamer_platz_1k.hdr", out_dir, end=args.end,
                                      max_size=min(args.max_size, 1280), repeats=args.repeats,
                                      ways=tuple(r for r in RUNS if NAMES[r] in (args.ways or ["then", "one", "ray"]) + ["one"]),
                                      progress=lambda line: print(line, flush=True))
        print(f"wrote {out_dir / 'spread.json'}")
    elif args.what == "colour":
        from viewer.lab.bench.colour import run_colour

        out_dir = Path(args.output or "out/bench-colour")
        result = run_colour(args.set or [shared_folder(args.photos, "photos", "--photos")], shared_folder(args.maps, "hdri", "--maps"),
                            out_dir, progress=lambda line: print(line, flush=True))
        for group, g in result["summary"].items():
            print(f"{group} ({len(g['photos'])} photos): " + ", ".join(
                f"{k} worst {v['worst']} median {v['median']}" for k, v in g.items() if isinstance(v, dict)))
        print(f"wrote {out_dir / 'colour.json'} and the contact sheets in {result['seconds'] / 60:.1f} min")
    elif args.what == "photos" and args.set:
        from viewer.lab.bench.photo_set import run_photo_set, set_table

        out_dir = Path(args.output or "out/bench-photo-set")
        result = run_photo_set(args.set, shared_folder(args.maps, "hdri", "--maps"), out_dir,
                               before=args.before, progress=lambda what: print(what, flush=True))
        print(set_table(result))
        print(f"wrote {out_dir / 'photo_set.json'} and {len(result['photos'])} contact sheets in {result['seconds'] / 60:.1f} min")
    elif args.what == "photos":
        from viewer.lab.bench.photos import run_photos_benchmark
        from viewer.progress import StageBars

        out_dir = Path(args.output or "out/bench-photos")
        if args.data and len(args.data) > 1:
            raise InputError(None, "bench photos takes one held-out dataset (--data DIR)")
        start = time.perf_counter()
        result = run_photos_benchmark(shared_folder(args.photos, "photos", "--photos"), shared_folder(args.maps, "hdri", "--maps"),
                                      args.data[0] if args.data else None, out_dir, limit=args.limit,
                                      progress=lambda what: print(f"  {what} ({time.perf_counter() - start:.0f} s)", flush=True))
        print(photos_table(result))
        print(f"wrote {out_dir / 'photos.json'}, {out_dir / 'photos_relit.jpg'}, {out_dir / 'photos_detail.jpg'} "
              f"in {result['seconds'] / 60:.1f} min")
    elif args.what == "robustness":
        from viewer.lab.bench.robustness import run_robustness_benchmark

        def show(case):
            r = case.result
            print(f"  {'clean' if r['clean'] else 'NOT CLEAN'}: {case.group}: {case.name} (exit {r['exit']}, {r['seconds']:.1f} s, "
                  f"{r['peak_mb']} MB)"
                  + ("" if r["clean"] else f": {'; '.join(r['problems'])}: {r['last_line']}"), flush=True)

        result = run_robustness_benchmark(output=output, progress=show, seed=args.campaign_seed)
        for group, g in result["groups"].items():
            print(f"{group:>20}: {g['clean']}/{g['tried']} clean, peak {g['peak_mb']} MB")
        print(f"{result['tried']} cases tried, {result['clean']} ended cleanly, {result['tracebacks']} tracebacks, "
              f"memory budget {result['memory_budget_mb']} MB, in {result['seconds'] / 60:.1f} min; wrote {output}")
    elif args.what == "shadows":
        from viewer.lab.bench.shadows import run_shadow_benchmark

        run_shadow_benchmark(repeats=args.repeats, output=output)
    else:
        from viewer.lab.bench.lights import COUNTS, run_lights_benchmark
        from viewer.lighting.lightfit.methods import METHODS

        run_lights_benchmark(maps_dir=shared_folder(args.maps, "hdri", "--maps"), counts=args.counts or COUNTS,
                             methods=tuple(args.methods or METHODS), output=output)
    return 0


def build_parsers() -> dict[str, argparse.ArgumentParser]:
    """One parser per lab command, each named ``relight <command>``."""
    commands: dict[str, argparse.ArgumentParser] = {}
    p = commands["dataset"] = argparse.ArgumentParser(
        prog="relight dataset", description="synthetic training data: people relit by a ray tracer (see docs/dataset.md)")
    dsub = p.add_subparsers(dest="action", required=True)
    q = dsub.add_parser("make", help="make (or resume) a dataset in a directory")
    q.add_argument("--out", required=True, help="dataset directory (outside the repository)")
    q.add_argument("--count", type=int, required=True, help="people (samples) in the whole dataset")
    q.add_argument("--res", type=int, default=256, help="image size in pixels (default 256)")
    q.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    q.add_argument("--shard", default="0/1", help="make samples i, i+n, ... of the dataset (default 0/1: all)")
    q.add_argument("--spp", type=int, default=64, help="ray-tracing samples per pixel (default 64)")
    q.add_argument("--lightings", type=int, default=2, help="environment maps per person (default 2)")
    q.add_argument("--split", choices=("train", "heldout", "key", "clip"), default="train",
                   help="train: procedural maps; heldout: the CC0 maps of --maps, never used for training; "
                        "key: key lights (one small light, a rim light in half), never used for training; "
                        "clip: --count clips of a person turning, filmed under one map of --maps with the truth "
                        "under another (relight bench video --truth)")
    q.add_argument("--frames", type=int, default=24, help="clip: frames of each clip, at 12 a second (default 24)")
    q.add_argument("--pool", type=int, default=32, help="procedural maps in the training pool (default 32)")
    q.add_argument("--maps", help="folder of held-out maps (default $RELIGHT_DATA/hdri)")
    q.set_defaults(func=cmd_dataset)
    q = dsub.add_parser("preview", help="pictures of what the generator makes: random people and procedural maps")
    q.add_argument("--out", required=True, help="folder for dataset_people.png and procedural_envmaps.png")
    q.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    q.add_argument("--count", type=int, default=8, help="people (default 8)")
    q.set_defaults(func=cmd_dataset_preview)

    p = commands["train"] = argparse.ArgumentParser(prog="relight train",
                                                    description="train a network on a dataset made by `relight dataset make`")
    p.add_argument("network", choices=("inverse", "depth", "refine"), help="which network")
    p.add_argument("--data", required=True, nargs="+", help="dataset directory (or several: shards, datasets)")
    p.add_argument("--out", default="runs", help="where checkpoints, loss curves and weights go (default runs/)")
    p.add_argument("--res", type=int, default=256, help="training resolution (default 256)")
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--batch", type=int, default=4)
    p.add_argument("--lr", type=float, default=1e-3, help="initial learning rate, cosine-annealed to 1e-5 (default 1e-3)")
    p.add_argument("--width", type=int, default=16, help="channels of the first U-Net level (network size)")
    p.add_argument("--levels", type=int, default=5, help="U-Net levels (default 5)")
    p.add_argument("--device", default="cpu", help="cpu or cuda (default cpu)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--silhouette", action="store_true",
                   help="inverse and depth: read the mask's silhouette prior (inflation normals, distance to the outline) too")
    p.add_argument("--body-prior", action="store_true",
                   help="inverse and depth, an experiment: read the dataset's body prior too (the product cannot use such weights)")
    p.add_argument("--init", metavar="WEIGHTS",
                   help="fine-tune: start from these weights (e.g. assets/networks/inverse.safetensors) instead of at random")
    p.add_argument("--perceptual-weight", type=float, default=0.1,
                   help="inverse: weight of the Laplacian-pyramid loss that replaces VGG (default 0.1, the paper's)")
    p.set_defaults(func=cmd_train)

    p = commands["bench"] = argparse.ArgumentParser(prog="relight bench", description="benchmarks that print figures and save JSON")
    p.add_argument("what", choices=("report", "engine", "shadows", "lights", "viewer", "contention", "temporal", "networks", "photos",
                                    "robustness",
                                    "bodyfit", "ground", "light-sizes", "matte", "upsample", "batch", "video", "clip-memory", "plates",
                                    "colour", "people", "spread", "timings"),
                   help="timings: the headline timings (torch's import, the instant fit in-process and as a "
                        "command, a balanced frame, a photo's inference) against the last recorded ones (--last, default "
                        "docs/results/bench_timings.json), saying which moved; engine: per-pass times; "
                        "shadows: error against ray-traced ground truth vs time per knob; "
                        "lights: light fitting error vs time on the shared maps; viewer: frame times of the real "
                        "window (drag, stop, sigma slider); temporal: dRMSE and flicker of turntables; "
                        "networks: the networks on a held-out dataset (--data); report: error against time of the "
                        "whole pipeline, temporal stability and the presets -> docs/results/results.md (--quick: a small check); "
                        "photos: real photos relit at their own size (detail kept, light moved, the photo's lighting, "
                        "mask IoU, times; --data adds held-out pairs); robustness: the bad-input campaign (hostile files and options "
                        "against the real CLI: how many cases end cleanly); bodyfit: anny fitted to MediaPipe's landmarks on "
                        "a dataset's photos, as a depth prior (--data, --limit people); ground: the person's shadow on the "
                        "ground against Mitsuba (error and the ground pass's time per shadow method); light-sizes: the area lights' sigmas "
                        "(each light's size on the map, scaled, and 0) against Mitsuba on the person and the ground under --maps; "
                        "matte: the person's matte "
                        "against the hand-made masks (--photos), every step and matting solver, quality and time; upsample: "
                        "the work shading brought to the frame (bilinear) against a work frame as large as the frame; "
                        "batch: relight batch's throughput on --count photos made from --photos x three of --maps, "
                        "with one worker, two and a local Ray cluster; video: clips (--clips) relit under --env maps: warping "
                        "error against the input's, frames a minute, stages, peak memory; clip-memory: the peak memory of "
                        "`relight render CLIP` on clips of 10 s and 60 s made from the bundled photo; plates: the light "
                        "estimated from plates made of each map of --maps at three yaws, the person relit by it against the "
                        "true map, a uniform light and spherical harmonics; colour: every photo of --set relit under a "
                        "uniform white map (its colours against the photo's: drift and cast in u'v'), a side key light "
                        "(the face skin's brightness, the backdrop kept) and two maps, contact sheets (out/bench-colour/); people: whom "
                        "each clip of --clips relights in every frame (the person chosen and followed), against CLIP.json "
                        "beside it when there is one: frames with the person missing, swapped or another beside them; spread: "
                        "each clip of --clips relit end to end (--end seconds, --repeats runs each way) inferred then relit, "
                        "by relight render CLIP (the relighting following the inference) and with --ray local: the time, "
                        "the warping error at the joins against elsewhere")
    p.add_argument("--last", help="timings: the run to compare with (default docs/results/bench_timings.json)")
    p.add_argument("--clips", nargs="+", help="video: clips, or folders of them (default $RELIGHT_DATA/videos)")
    p.add_argument("--ways", nargs="+", choices=("then", "one", "ray"),
                   help="spread: the ways each clip is relit: inferred then relit, one process (always), --ray local "
                        "(default all three)")
    p.add_argument("--procedural", type=int, help="plates: instead of --maps, this many procedural maps (two of a kind at "
                   "most, seeds from 9000), made into the output's folder: maps never looked at while the estimate was made")
    p.add_argument("--synthetic", action="store_true", help="video: also (or, without --clips, only) a clip made from the "
                   "bundled photo, and a strip of its frames (input, off, on) for the docs")
    p.add_argument("--truth", help="video: instead, the clips of a dataset made by `relight dataset make --split clip` "
                   "relit against the ray tracer's truth (relit RMSE as a clip and frame by frame)")
    p.add_argument("--env", nargs="+", help="video: maps to relight under (default potsdamer_platz and rooitou_park of --maps)")
    p.add_argument("--start", type=float, default=0.0, help="video: seconds into each clip to start at (default 0)")
    p.add_argument("--end", type=float, default=2.0, help="video: seconds into each clip to stop at (default 2)")
    p.add_argument("--max-size", type=int, default=2048, help="video: the frames' longer side at most (default 2048)")
    p.add_argument("--count", type=int, default=20, help="batch: distinct photos (default 20)")
    p.add_argument("--photos", help="photos, matte, upsample, plates: folder of .jpg photos, hand-made masks beside them "
                   "as <stem>.mask.png "
                   "(default $RELIGHT_DATA/photos)")
    p.add_argument("--set", nargs="+", metavar="DIR", help="plates: more folders of photos whose people are put back into "
                   "their own photo; matte --backdrops: more folders of photos with hand-made masks; "
                   "photos: every photo of these folders through the whole photo path (holes and speckle on "
                   "skin, bleed, kept, detail kept, light moved, infer time; contact sheets of "
                   "100 %% crops), split in a half to tune on and a half held back (issue 42; out/bench-photo-set/); "
                   "colour: the photos measured")
    p.add_argument("--before", help="photos --set, matte --backdrops: the JSON of an earlier run, shown beside "
                   "this one")
    p.add_argument("--backdrops", action="store_true", help="matte: instead, the people of --photos (and --set) "
                   "with hand-made masks composited on plain backdrops (flat and studio; pink, navy, white, grey), "
                   "through the automatic matte and relit: kept, spill, cut, the gaps the person encloses found, "
                   "bleed, the matte's time (out/bench_backdrops.json)")
    p.add_argument("--campaign-seed", type=int, default=17, help="robustness: the generators' seed (default 17; another seed "
                                                                  "makes held-back variants of every generated class)")
    p.add_argument("--quick", action="store_true", help="report: the small configuration CI runs (under 5 minutes)")
    p.add_argument("--sizes", type=int, nargs="+", default=[512, 1024])
    p.add_argument("--lights", type=int, nargs="+", default=[8, 16, 32])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--no-twin", action="store_true", help="skip timing the torch twin")
    p.add_argument("--twin-device", default="cpu", help="engine: the torch device the twin is timed on (cpu, cuda)")
    p.add_argument("--maps", help="lights, report, photos, viewer: folder of .hdr/.exr maps (default "
                   "$RELIGHT_DATA/hdri; viewer: its first .hdr or .exr is the new map opened)")
    p.add_argument("--counts", type=int, nargs="+", help="lights: numbers of lights (default 4 8 16 32)")
    p.add_argument("--methods", nargs="+", choices=("instant", "fast", "paper", "median-cut"),
                   help="lights: fitting methods (default all)")
    p.add_argument("--data", nargs="+", help="networks, report, photos, bodyfit: dataset directory (networks: or several)")
    p.add_argument("--networks", help="networks: folder of weights (default: the shipped ones)")
    p.add_argument("--no-face", action="store_true", help="networks: the networks' maps alone, without the face "
                   "fitted to the photo (viewer.photo.face) that relight infer blends in")
    p.add_argument("--limit", type=int, help="networks, photos: evaluate at most this many held-out (input, target) pairs; "
                   "bodyfit: people (default 12)")
    p.add_argument("-o", "--output", help="JSON path (default out/bench_<what>.json; figures go beside it); report, "
                   "photos: the folder (default out/report/, with --quick out/report-quick/; out/bench-photos/). "
                   "The committed figures are refreshed only when asked: -o docs/results/bench_<what>.json, or -o docs/results")
    p.set_defaults(func=cmd_bench)
    return commands


def run(command: str, argv) -> int:
    """Parse ``argv`` (the words after ``relight <command>``) and run the command."""
    args = build_parsers()[command].parse_args(argv)
    return args.func(args)


def dataset(argv) -> int:
    return run("dataset", argv)


def train(argv) -> int:
    return run("train", argv)


def bench(argv) -> int:
    return run("bench", argv)


if __name__ == "__main__":
    from viewer.cli.main import main

    sys.exit(main())
