"""``relight bench networks``: the shipped networks on the held-out split (people and maps never
trained on), as tables like the paper's.

For every held-out person and each of its two lightings as the *input* photo (the other is the
*target*; a person with one lighting is relit under that same lighting):

- **materials and geometry**: the inverse-rendering and depth networks' maps against the truth
  (RMSE and SSIM over the mask; depth after removing each map's median, in centimetres; the mean
  normal angle);
- **shading with shadows** under the target's fitted area lights, from the true geometry and from
  the predicted one, with the shadow map (SM), the convolutional shadow map (CSM) and the
  refinement network (refined): the paper's ablation, against the ray-traced shadowed diffuse
  shading (albedo 1);
- **specular shading** (predicted maps, refined shadows) against the ray-traced specular lobe;
- **relit image**: the predicted scene relit under the target's lights by the GL engine (refined,
  CSM and SM shadows), the same with the true maps (what the renderer alone loses), and the
  baseline: second-order spherical-harmonics lighting of the target map without shadows
  (:mod:`viewer.lighting.sh`) on the same predicted albedo and normals, against the ray-traced relit image.

Every image is scaled by the target photo's exposure (its 99th percentile of luminance -> 0.9, the
networks' own convention, so maps of any brightness weigh alike) before RMSE; SSIM uses the same
scaled images clipped to [0, 1]; FLIP (NVIDIA's, LDR) compares them tone mapped to sRGB. LPIPS
needs pretrained ImageNet weights, which cannot be fetched here, so it is not reported.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import atomic_path, read_exr, write_text
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.gl.context import describe
from viewer.lab.bench.metrics import chroma, metrics, srgb
from viewer.lighting.envmap import load_envmap
from viewer.scene.area_lights import AreaLights, load_lights
from viewer.scene.bundle import Scene, load_scene
from viewer.scene.camera import Camera

# label: (the engine's shadow mode, its soft-shadow method); refined reads the hard and soft visibility
SHADOW_MODES = {"SM": ("hard", "csm"), "CSM": ("soft", "csm"), "PCSS": ("soft", "pcss"),
                "refined_CSM": ("refined", "csm"), "refined": ("refined", "pcss")}  # refined: the product's default


def _engine_images(ctx, scene: Scene, lights, wanted, refiner) -> dict:
    """{(shadow-mode label, view): HDR (H, W, 3)} for the scene, ``wanted`` a list of (label of
    :data:`SHADOW_MODES`, view); one engine per soft-shadow method (refined: the refinement network
    on that engine's own visibility)."""
    from viewer.output.render import render_frame
    from viewer.scene.look import Look

    out = {}
    for soft in dict.fromkeys(SHADOW_MODES[label][1] for label, _ in wanted):
        eng = Engine(ctx, scene, EngineOptions(soft=soft))
        try:
            eng.set_lights(lights)
            for label, view in wanted:
                mode, method = SHADOW_MODES[label]
                if method != soft:
                    continue
                eng.set_visibility(mode)
                eng.set_view(view)
                render_frame(eng, Look(shadows=mode), refiner)
                out[label, view] = eng.output.read_hdr()[..., :3].copy()
        finally:
            eng.release()
    return out


def _predict(nets, photo, mask, face: bool = True) -> tuple[Scene, dict]:
    """The predicted scene of a linear photo (3, H, W) with its background and its mask (1, H, W),
    made much as ``relight infer`` makes it: the networks run at inference's resolution
    (``NETWORK_RES``; the photo area-averaged down to it in linear light, where inference resizes
    the 8-bit photo), and their maps, extended past the mask, are resampled (bilinear) back to the
    photo's; with ``face``, the face fitted to the photo (exposed and in 8-bit sRGB, as a photo
    is) is blended in (:mod:`viewer.photo.face`). ``raw["face_region"]``: the fitted face's pixels
    (None without one), found in both cases so that both are measured over the same pixels."""
    import torch
    from torch.nn import functional as F

    from viewer.files.imageio import linear_to_srgb
    from viewer.nets import depth as depth_net, inverse as inverse_net
    from viewer.nets.photo import exposure_scale
    from viewer.photo import face as face_mod
    from viewer.photo.network_frame import NETWORK_RES, extend, map_stack, scene_maps

    h, w = mask.shape[-2:]
    cam = Camera(w, h)
    with torch.no_grad():
        photo, mask = photo[None], mask[None]
        small, small_mask = photo, mask
        if (h, w) != (NETWORK_RES, NETWORK_RES):
            small = F.interpolate(photo, size=(NETWORK_RES, NETWORK_RES), mode="area")
            small_mask = (F.interpolate(mask, size=(NETWORK_RES, NETWORK_RES), mode="area") > 0.5).to(mask.dtype)
        maps, (direction, sigma, intensity), _ = inverse_net.predict(nets["inverse"], small, small_mask)
        depth = depth_net.predict(nets["depth"], small, small_mask, cam.distance)
        stack = map_stack(maps, depth)
        if (h, w) != (NETWORK_RES, NETWORK_RES):
            stack = F.interpolate(extend(stack, small_mask), size=(h, w), mode="bilinear", align_corners=False)
    m = mask[0, 0].numpy() > 0.5
    scene = Scene(**scene_maps(stack[0].permute(1, 2, 0).numpy().astype(np.float32), m, cam.distance), mask=m, camera=cam)
    lights = AreaLights(direction[0].numpy(), sigma[0].numpy(), intensity[0].numpy())
    exposed = float(exposure_scale(photo, mask)) * photo[0].permute(1, 2, 0).numpy()
    faces = face_mod.find_faces((np.clip(linear_to_srgb(np.clip(exposed, 0, 1)), 0, 1) * 255).round().astype(np.uint8),
                                mask[0, 0].numpy())
    if face:
        scene, _, surface = face_mod.with_face(scene, faces, 1.0)
    else:
        surface = face_mod.face_surface(faces[0], 1.0, m.shape, m) if faces else None
    return scene.validate(), {"albedo": scene.albedo, "normal": scene.normal, "lights": lights,
                              "face_surface": surface if face else None,
                              "face_region": surface.region if surface is not None else None}


def _degrees(normal: np.ndarray, truth: np.ndarray, region: np.ndarray) -> float:
    """The mean angle (degrees) between two normal maps over ``region``."""
    return float(np.degrees(np.arccos(np.clip((normal * truth).sum(-1)[region], -1, 1))).mean())


def _terminator(normal: np.ndarray, truth: np.ndarray, region: np.ndarray, lights) -> dict:
    """Where the target's strongest light's attached shadow falls over ``region``: the share of its
    pixels on the wrong side of the terminator (n . l > 0 with one normal map, <= 0 with the
    other), and the share the truth has in attached shadow."""
    l = lights.direction[int(np.argmax(lights.intensity.sum(axis=-1)))]
    lit, lit_true = (normal[region] @ l) > 0, (truth[region] @ l) > 0
    return {"wrong_side": float((lit != lit_true).mean()), "dark_true": float((~lit_true).mean())}


def _depth_l1(depth: np.ndarray, truth: np.ndarray, region: np.ndarray) -> dict:
    """Depth error over ``region`` after removing each map's median there, centimetres, and a flat
    figure's (the truth's own spread about its median)."""
    dp, dt = depth[region] - np.median(depth[region]), truth[region] - np.median(truth[region])
    return {"rmse_cm": float(np.sqrt(np.mean((dp - dt) ** 2)) * 100), "l1_cm": float(np.abs(dp - dt).mean() * 100),
            "flat_l1_cm": float(np.abs(dt).mean() * 100)}


def _relative_rmse(pred: np.ndarray, truth: np.ndarray, m: np.ndarray) -> dict:
    """RMSE over the mask relative to the truth's mean, as it is and after the best single scale
    (which separates the shading's shape from its overall brightness)."""
    p, t = pred[m].astype(np.float64), truth[m].astype(np.float64)
    level = max(float(np.abs(t).mean()), 1e-12)
    k = float((p * t).sum() / max((p * p).sum(), 1e-30))
    return {"rmse_rel": float(np.sqrt(((p - t) ** 2).mean())) / level,
            "rmse_rel_scaled": float(np.sqrt(((k * p - t) ** 2).mean())) / level}


def _own_lights_error(ctx, pred: Scene, truth: Scene, photo: np.ndarray, shading: np.ndarray, network_lights,
                      surface=None) -> dict:
    """How well the input photo's own lights are known (what relighting divides out): its shadowed
    diffuse shading rebuilt on the TRUE geometry under the lights the product fits to the photo on
    the predicted maps (viewer.photo.own_lighting, as ``relight infer`` does), under the inverse
    network's own guess, and under the same fit made on the true maps (the fit's own floor: what
    is left when the networks are perfect), against the ray-traced shading of the photo's lighting.
    ``surface``: the face blended into ``pred`` (weighted in its fit as inference weighs it)."""
    from viewer.photo.face import light_fit_weight
    from viewer.photo.own_lighting import fit_mask, fit_photo_lights

    def fit(scene, face=None):
        eng = Engine(ctx, scene, EngineOptions())
        try:
            valid = fit_mask(scene, photo)
            valid = valid if valid.any() else scene.mask
            return fit_photo_lights(eng, photo, valid, weight=light_fit_weight(face, valid))[0]
        finally:
            eng.release()

    out = {}
    for name, lights in (("fitted", fit(pred, surface)), ("network", network_lights), ("fitted_true_maps", fit(truth))):
        img = _engine_images(ctx, truth, lights, [("CSM", "diffuse_shading")], None)["CSM", "diffuse_shading"]
        for k, v in _relative_rmse(img, shading, truth.mask).items():
            out[f"{name}_{k}"] = v
    return out


def run_networks_benchmark(data, networks_dir=None, output="out/bench_networks.json", figure=None,
                           limit: int | None = None, progress=None, face: bool = True) -> dict:
    from viewer.lab.data.loader import RelightDataset
    from viewer.lighting.sh import relight as sh_relight
    from viewer.nets.photo import exposure_scale
    from viewer.photo.inference import load_networks
    from viewer.photo.network_frame import NETWORK_RES
    from viewer.photo.refinement import Refiner
    from viewer.resources import network_dir

    networks_dir = Path(networks_dir) if networks_dir is not None else network_dir()
    nets = load_networks("cpu", networks_dir)
    refiner = Refiner(networks_dir / "refine.safetensors")
    ds = RelightDataset(data)
    ctx = create_headless_context()
    by_sample: dict[Path, list[int]] = {}
    for i, (s, _) in enumerate(ds.items):
        by_sample.setdefault(s, []).append(i)
    # each lighting as the input, the next one as the target (a person with one lighting: itself)
    pairs = [(idx[k], idx[(k + 1) % len(idx)]) for idx in by_sample.values() for k in range(min(len(idx), 2))]
    if limit:
        pairs = pairs[:limit]
    rows: dict[str, list[dict]] = {}
    per_pair: list[dict] = []  # the relit RMSE of each pair, ours (refined) and SH's
    examples = []
    start = time.perf_counter()

    def add(name, value):
        rows.setdefault(name, []).append(value)

    for n, (src, tgt) in enumerate(pairs):
        sample, k_tgt = ds.items[tgt]
        item, target = ds[src], ds[tgt]
        truth = load_scene(sample)
        m = truth.mask
        photo = item["image"] + (1 - item["mask"]) * item["background"]
        t0 = time.perf_counter()
        pred, raw = _predict(nets, photo, item["mask"], face)
        add("seconds_networks", time.perf_counter() - t0)
        # materials and geometry
        add("albedo", metrics(pred.albedo, truth.albedo, m))
        add("albedo_chroma", chroma(pred.albedo, truth.albedo, m))
        add("specular", metrics(pred.specular[..., None], truth.specular[..., None], m))
        add("roughness", metrics(pred.roughness[..., None], truth.roughness[..., None], m))
        add("normal", {**metrics(pred.normal, truth.normal, m, data_range=2.0), "degrees": _degrees(pred.normal, truth.normal, m)})
        if raw["face_region"] is not None:
            region = raw["face_region"] & m
            add("normal_face", {"degrees": _degrees(pred.normal, truth.normal, region), "pixels": float(region.sum())})
            add("depth_face", _depth_l1(pred.depth, truth.depth, region))
        add("depth", _depth_l1(pred.depth, truth.depth, m))
        # the photo's own lighting, as the product estimates it
        add("own_lights", _own_lights_error(ctx, pred, truth, photo.permute(1, 2, 0).numpy(),
                                            item["diffuse_shadowed"].permute(1, 2, 0).numpy(), raw["lights"],
                                            raw["face_surface"]))
        # the target lighting
        d = sample / f"lighting_{k_tgt}"
        lights = load_lights(d / "lights.json")
        if raw["face_region"] is not None:
            add("terminator_face", _terminator(pred.normal, truth.normal, raw["face_region"] & m, lights))
        full_t = target["image"].permute(1, 2, 0).numpy()
        s = float(exposure_scale(target["image"][None], target["mask"][None]))
        y_diff = target["diffuse_shadowed"].permute(1, 2, 0).numpy() * s
        true_img = _engine_images(ctx, truth, lights, [(label, "diffuse_shading") for label in SHADOW_MODES]
                                  + [("refined", "final")], refiner)
        pred_img = _engine_images(ctx, pred, lights, [(label, v) for label in SHADOW_MODES for v in ("diffuse_shading", "final")]
                                  + [("refined", "specular_shading")], refiner)
        for label in SHADOW_MODES:
            add(f"shading_true_geometry_{label}", metrics(s * true_img[label, "diffuse_shading"], y_diff, m))
            add(f"shading_{label}", metrics(s * pred_img[label, "diffuse_shading"], y_diff, m))
        spec_t = s * read_exr(d / "specular_shadowed.exr")
        add("specular_shading", metrics(s * pred_img["refined", "specular_shading"], spec_t, m))
        relit = {}
        for label in SHADOW_MODES:
            relit[label] = s * pred_img[label, "final"]
            add(f"relit_{label}", metrics(relit[label], s * full_t, m, flip=True))
        add("relit_true_maps_refined", metrics(s * true_img["refined", "final"], s * full_t, m, flip=True))
        lighting = json.loads((d / "lighting.json").read_text())
        env = load_envmap(sample.parents[1] / "maps" / f"{lighting['map']}.hdr").rotated(lighting["yaw"])
        relit["SH"] = s * sh_relight(pred.albedo, pred.normal, m, env)
        add("relit_SH_baseline", metrics(relit["SH"], s * full_t, m, flip=True))
        per_pair.append({"input": f"{ds.items[src][0].name}/{ds.items[src][1]}", "target": f"{sample.name}/{k_tgt}",
                         "lighting": lighting.get("kind"),
                         "relit_refined": rows["relit_refined"][-1]["rmse"], "relit_SH": rows["relit_SH_baseline"][-1]["rmse"]})
        if len(examples) < 4 and n % 2 == 0:
            exposed = float(exposure_scale(photo[None], item["mask"][None])) * photo.permute(1, 2, 0).numpy()
            examples.append({"photo": exposed, "truth": s * full_t, "ours": relit["refined"], "sh": relit["SH"],
                             "albedo": (truth.albedo, raw["albedo"]), "normal": (truth.normal, raw["normal"]), "mask": m})
        if progress is not None:
            progress("held-out pairs", n + 1, len(pairs))
    summary = {name: _summarize(values) for name, values in rows.items()}
    result = {"machine": describe(ctx), "data": [str(d) for d in (data if isinstance(data, (list, tuple)) else [data])],
              "networks": str(networks_dir), "face": face, "pairs": len(pairs), "people": len({ds.items[a][0] for a, _ in pairs}),
              "resolution": int(ds[0]["image"].shape[-1]), "network_resolution": NETWORK_RES, "seconds": round(time.perf_counter() - start,
                                                                                                               1), "metrics": summary,
              "per_pair": per_pair}
    if output:
        write_text(output, json.dumps(result, indent=1) + "\n")
    figure = figure or (Path(output).with_name("networks_heldout.png") if output else None)
    if figure and examples:
        _figure(examples, figure)
    return result


def _summarize(values: list) -> dict:
    """Mean, standard deviation and median over the pairs (the median: a few pairs with a sun's
    highlight dominate a mean of RMSEs)."""
    if isinstance(values[0], dict):
        return {k: _summarize([v[k] for v in values]) for k in values[0]} | {"count": len(values)}
    return {"mean": float(np.mean(values)), "std": float(np.std(values)), "median": float(np.median(values))}


def _figure(examples, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = ["input photo", "target (ray traced)", "ours (refined)", "SH baseline", "albedo: truth", "albedo: ours",
            "normal: truth", "normal: ours"]
    fig, axes = plt.subplots(len(examples), len(cols), figsize=(2.0 * len(cols), 2.2 * len(examples)), dpi=90, squeeze=False)
    for r, ex in enumerate(examples):
        m = ex["mask"][..., None]
        pics = [ex["photo"], ex["truth"], ex["ours"], ex["sh"], ex["albedo"][0], ex["albedo"][1] * m,
                (ex["normal"][0] * 0.5 + 0.5) * m, (ex["normal"][1] * 0.5 + 0.5) * m]
        for c, pic in enumerate(pics):
            ax = axes[r, c]
            ax.imshow(srgb(pic) if c < 6 else np.clip(pic, 0, 1))
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(cols[c], fontsize=8)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)


TABLES = (
    ("Materials and geometry", (("albedo", "albedo"), ("specular", "specular"), ("roughness", "roughness"), ("normal", "normal")),
     ("rmse", "ssim")),
    ("Shading with shadows, true geometry (the SM / CSM / refined ablation)",
     tuple((f"shading_true_geometry_{k}", k) for k in SHADOW_MODES), ("rmse", "ssim")),
    ("Shading with shadows, predicted geometry", tuple((f"shading_{k}", k) for k in SHADOW_MODES), ("rmse", "ssim")),
    ("Specular shading (predicted maps, refined shadows)", (("specular_shading", "specular shading"),), ("rmse", "ssim")),
    ("Relit image", (("relit_refined", "ours, refined (from PCSS)"), ("relit_refined_CSM", "ours, refined from CSM (the paper's)"),
                     ("relit_PCSS", "ours, PCSS"), ("relit_CSM", "ours, CSM"), ("relit_SM", "ours, SM"),
                     ("relit_SH_baseline", "SH order 2, no shadows (baseline)"),
                     ("relit_true_maps_refined", "true maps, refined (renderer alone)")), ("rmse", "ssim", "flip")),
)


def table(result: dict) -> str:
    """Markdown tables of a :func:`run_networks_benchmark` result (mean +- std over the pairs)."""
    m = result["metrics"]
    lines = [f"{result['pairs']} (input, target) pairs of {result['people']} held-out people at {result['resolution']}^2; "
             f"{result['machine']}"]
    for title, entries, keys in TABLES:
        lines += ["", f"**{title}**", "", "| | " + " | ".join(k.upper() for k in keys) + " |", "|---" * (len(keys) + 1) + "|"]
        for name, label in entries:
            if name in m:
                lines.append(f"| {label} | " + " | ".join(f"{m[name][k]['mean']:.4f} +- {m[name][k]['std']:.4f}" for k in keys) + " |")
    relit = [(label, m[name]["rmse"]) for name, label in TABLES[-1][1] if name in m and "median" in m[name]["rmse"]]
    if relit:
        lines += ["", "Relit RMSE, median over the pairs (a few pairs with a sun's highlight weigh heavily in the mean): "
                      + "; ".join(f"{label} {r['median']:.4f}" for label, r in relit)]
    if result.get("per_pair"):
        better = sum(p["relit_refined"] < p["relit_SH"] for p in result["per_pair"])
        lines += ["", f"Ours (refined) below the SH baseline in relit RMSE on {better} of {len(result['per_pair'])} pairs"]
    if "own_lights" in m:
        o = m["own_lights"]
        lines += ["", "The photo's own lights (its shadowed diffuse shading rebuilt on the true geometry; RMSE relative "
                      "to the mean, as is / after the best single scale): fitted to the photo "
                      f"{o['fitted_rmse_rel']['mean']:.3f} / {o['fitted_rmse_rel_scaled']['mean']:.3f}; the network's guess "
                      f"{o['network_rmse_rel']['mean']:.3f} / {o['network_rmse_rel_scaled']['mean']:.3f}"
                      + (f"; fitted on the true maps (the fit's floor) {o['fitted_true_maps_rmse_rel']['mean']:.3f} / "
                         f"{o['fitted_true_maps_rmse_rel_scaled']['mean']:.3f}" if "fitted_true_maps_rmse_rel" in o else "")]
    if "albedo_chroma" in m:
        c = m["albedo_chroma"]
        lines += ["", f"Albedo colour (brightness aside): chromaticity L1 {c['chroma_l1']['mean']:.4f}; saturation "
                      f"{c['saturation_pred']['mean']:.4f} predicted against {c['saturation_true']['mean']:.4f} true"]
    d = m["depth"]
    lines += ["", f"Depth (median-aligned): RMSE {d['rmse_cm']['mean']:.2f} cm, L1 {d['l1_cm']['mean']:.2f} cm "
              f"(a flat figure: {d['flat_l1_cm']['mean']:.2f} cm); normal angle {m['normal']['degrees']['mean']:.1f} deg; "
              f"networks {m['seconds_networks']['mean'] * 1000:.0f} ms per photo"]
    if "normal_face" in m:
        f, fd = m["normal_face"], m["depth_face"]
        lines += ["",
                  f"In the face region ({'the face fitted to the photo blended in' if result.get('face', True) else 'the networks alone'}; "
                      f"{f['count']} of {result['pairs']} inputs with a face found, "
                      f"{f['pixels']['mean']:.0f} pixels): normal angle {f['degrees']['mean']:.1f} deg (median "
                      f"{f['degrees']['median']:.1f}); depth L1 {fd['l1_cm']['mean']:.2f} cm "
                      f"(a flat face: {fd['flat_l1_cm']['mean']:.2f} cm)"]
    if "terminator_face" in m:
        t = m["terminator_face"]
        lines += [f"The strongest target light's terminator in the face region: {100 * t['wrong_side']['mean']:.1f} % of "
                  f"its pixels on the wrong side ({100 * t['dark_true']['mean']:.1f} % in attached shadow in the truth)"]
    return "\n".join(lines)
