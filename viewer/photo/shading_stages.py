"""The inference's stages after the networks (:data:`viewer.photo.inference.STAGE_LIST`): the face, a
clip's steady maps, the photo's own lights fitted and the shading they give, its sheen bounded and its
detail kept."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from viewer.photo import detail as detail_mod, gloss
from viewer.photo.face import find_faces, light_fit_weight, with_face
from viewer.photo.frames import person_box
from viewer.photo.network_frame import NETWORK_RES
from viewer.resize import mask_normalized_resize, resize


def face_stage(scene, frame_photo, alpha, sizes, skin, body, gloss_record, steady):
    faces = find_faces(frame_photo, alpha)
    if steady is not None:  # a clip's frame: the face's landmarks smoothed from frame to frame
        faces = steady[0].steady_faces(faces, steady[1])
    scene, face_record, face_surface = with_face(scene, faces, sizes.work_scale)
    if faces:  # where the face is: what the automatic exposure meters (viewer.output.render.photo_exposure)
        h, w = alpha.shape
        (x0, y0), (x1, y1) = np.clip(faces[0].points[:, :2].min(axis=0), 0, None), faces[0].points[:, :2].max(axis=0)
        x1, y1 = min(float(x1), w), min(float(y1), h)
        if x1 > x0 and y1 > y0:
            scene = replace(scene, frame=replace(scene.frame, face_box=(x0 / w, y0 / h, (x1 - x0) / w, (y1 - y0) / h)))
    if skin is not None:  # where light scatters under the skin, and how many millimetres a frame pixel is
        mm = gloss.skin_mm(faces[0].width if faces else None, person_box(body)[2])
        scene = replace(scene, frame=replace(scene.frame, skin=skin, skin_mm=mm))  # validated with the detail's
        gloss_record = {**gloss_record, "skin_mm_per_pixel": round(mm, 4)}
    return {"scene": scene, "face_record": face_record, "face_surface": face_surface, "gloss_record": gloss_record}


def steady_stage(scene, frame_photo, steady):
    """A clip's frame: its maps blended with the frame before's along the flow (``steady``: the
    clip's :class:`viewer.photo.steady.SteadyMaps` and the frame's shot; None for a photo)."""
    if steady is None:
        return {"scene": scene, "steady_share": None}
    maps, shot = steady
    steadied, share = maps.steady(scene, frame_photo, shot)
    if steadied is not scene:  # the maps blended: checked here, as the stages after check only the maps they replace
        steadied = steadied.validate(only=frozenset({"albedo", "specular", "roughness", "normal", "depth"}))
    return {"scene": steadied, "steady_share": round(share, 4)}


def fit_lights_stage(engine, scene, frame_linear, sizes, work_mask, side_work, face_surface, given_lights):
    from viewer.photo.own_lighting import fit_mask, fit_photo_lights

    # the photo at the maps' level of detail: one network pixel of low-pass
    target = detail_mod.masked_lowpass(resize(frame_linear, sizes.work), work_mask, side_work / NETWORK_RES)
    valid = fit_mask(scene, resize(frame_linear, sizes.work))
    if not valid.any():
        valid = work_mask
    if given_lights is not None:  # a clip's shot: the light its first frame was fitted to (viewer.photo.clip_inference)
        return {"lights": given_lights, "fit": {"lights": len(given_lights), "given": "the shot's, fitted on its first frame"},
                "target": target, "valid": valid}
    lights, fit = fit_photo_lights(engine, target, valid, weight=light_fit_weight(face_surface, valid))
    return {"lights": lights, "fit": fit, "target": target, "valid": valid}


def shading_stage(engine, lights, fit, target, valid):
    engine.set_lights(lights)
    explained = engine.render().output.read_work_hdr()
    diffuse, specular = engine.output.read_frame_shading(sheen_detail=False)  # the photo's sheen as its lights make it
    return {"explained": explained, "shading": (diffuse, specular), "fit": {**fit, "psnr_db": fit_psnr(explained, target, valid)}}


def sheen_stage(scene, shading, framing, matte, gloss_record):
    diffuse, specular = shading
    scene, specular, lessened = gloss.bounded_sheen(scene, specular, matte.foreground, framing.side / NETWORK_RES)
    return {"scene": scene, "shading": (diffuse, specular), "gloss_record": {**gloss_record, "sheen_lessened": round(lessened, 4)}}


def detail_stage(scene, frame_network_albedo, shading, framing, matte, detail):
    scene, detail_stats = with_detail(scene, frame_network_albedo, shading, framing.side, matte.foreground, detail)
    return {"scene": scene, "detail_stats": detail_stats}


def with_detail(scene, network_albedo_frame: np.ndarray, shading: tuple[np.ndarray, np.ndarray], framing_side: float,
                foreground: np.ndarray, method: str = detail_mod.DEFAULT, shared_scale: float | None = None):
    """(``scene`` with the detail albedo of ``method`` in its frame layer and, area-averaged over
    the person, in its maps; the detail step's statistics). ``shading`` = (D_old, S_old) at the
    frame, ``framing_side`` the networks' square in frame pixels, ``foreground`` the matte's
    foreground colours (linear, the frame's size): the photo's colour wherever it enters the person."""

    frame = scene.frame
    albedo, stats = detail_mod.detail_albedo(method, foreground, frame.alpha, network_albedo_frame, shading,
                                             lowpass_sigma=framing_side / NETWORK_RES, shared_scale=shared_scale)
    work = mask_normalized_resize(albedo, frame.alpha, (scene.width, scene.height))
    return replace(scene, albedo=np.where(scene.mask[..., None], np.clip(work, 0, 1), 0).astype(np.float32),
                   frame=replace(frame, albedo=albedo)).validate(only=frozenset({"albedo", "frame"})), stats


def fit_psnr(render: np.ndarray, target: np.ndarray, valid: np.ndarray) -> float:
    """PSNR (dB) of a render against the photo's low-pass over ``valid``, in display sRGB."""
    from viewer.files.imageio import linear_to_srgb

    a, b = linear_to_srgb(render[valid]), linear_to_srgb(target[valid])
    mse = float(np.mean((np.clip(a, 0, 1) - np.clip(b, 0, 1)) ** 2))
    return float(10 * np.log10(1.0 / max(mse, 1e-12)))
