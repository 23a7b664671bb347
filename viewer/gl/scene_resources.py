"""The scene on the GPU: the maps as textures, the background image and environment map, and the
figures every pass reads off the scene (the mask's box, the depth range, the shadow casters'
bounding sphere, the bounds that decide which lights can contribute). Made once per engine: the
scene never changes in an engine's life; only the environment map is replaced."""

from __future__ import annotations

import moderngl
import numpy as np

from viewer.gl.kit import PassKit
from viewer.scene import shadow_space as ss
from viewer.scene.bundle import Scene, bounding_box
from viewer.scene.depth_mesh import caster_points, depth_mesh, resolve_step

MAX_ENVIRONMENT_WIDTH = 8192  # texels of the background's map: a bigger map is box-averaged down to it


def fit_environment(pixels: np.ndarray, max_width: int) -> np.ndarray:
    """The equirectangular map (H, W, 3) box-averaged by the smallest integer factor that brings its
    width to ``max_width`` or below (a map wider than the GL's textures would otherwise show black)."""
    h, w = pixels.shape[:2]
    factor = -(-w // max_width)
    if factor <= 1:
        return pixels
    h2, w2 = h // factor, w // factor
    cropped = pixels[:h2 * factor, :w2 * factor].astype(np.float64)
    return cropped.reshape(h2, factor, w2, factor, 3).mean(axis=(1, 3)).astype(np.float32)


class SceneResources:
    def __init__(self, kit: PassKit, scene: Scene, shadow_step: int):
        s = scene
        w, h = s.width, s.height
        self.kit = kit
        mask = s.mask.astype(np.float32)
        pts = s.points()
        # two fetches per pixel and light: (position, roughness) and (normal, specular); normals are
        # zero outside the mask, so n.l <= 0 there
        self.positions = kit.texture((w, h), 4, np.dstack([pts, s.roughness]).astype("f4").tobytes())
        self.normals = kit.texture((w, h), 4, np.dstack([s.normal, s.specular]).astype("f4").tobytes())
        self.albedo = kit.texture((w, h), 4, np.dstack([s.albedo, mask]).astype("f4").tobytes())
        bg = s.background if s.background is not None else np.zeros((h, w, 3), np.float32)
        self.background = kit.texture((w, h), 4, np.dstack([bg, np.ones((h, w), np.float32)]).astype("f4").tobytes())
        self.environment = kit.texture((1, 1), 4, np.zeros(4, "f4").tobytes(), linear=True, repeat=True)

        self.shadow_step = resolve_step(shadow_step, s)
        self.mesh = depth_mesh(s, step=self.shadow_step)  # the shadow casters (decimated depth mesh)
        self.caster_points = caster_points(s, self.mesh).astype(np.float32)
        self.sphere = ss.bounding_sphere(self.caster_points.astype(np.float64))
        self.depth_range = (float(s.depth[s.mask].min()), float(s.depth[s.mask].max()))
        # camera-pixel passes only touch the mask's bounding box (the rest stays cleared to zero)
        self.mask_box = bounding_box(s.mask)
        self.normals_by_axis = np.ascontiguousarray(s.normal[s.mask].T, dtype=np.float32)  # (3, P): see facing
        # Upper bound of (A S_diff + S_spec) per unit intensity and unit n.l over the scene:
        # S_spec = n.l F D G <= n.l * 1 * 1 / (pi alpha^2) * 1 / (n.l alpha) (G1(n.l) n.l <= 1,
        # G1(n.v) <= 1 / alpha), i.e. <= 1 / (pi alpha^3) with the smallest alpha of a specular pixel.
        glossy = s.mask & (s.specular > 0)
        alpha = max(float(s.roughness[glossy].min()) ** 2, 1e-3) if glossy.any() else None
        self.diffuse_bound = float(s.albedo[s.mask].max()) / np.pi
        self.response_bound = self.diffuse_bound + (1.0 / (np.pi * alpha**3) if alpha else 0.0)

    def facing(self, directions: np.ndarray) -> np.ndarray:
        """Each direction's best n.l over the person's pixels (0 when none faces it): the bound that
        leaves out lights facing away. It runs for every moved light in every dragged frame
        (:func:`viewer.scene.shadow_space.projections`: 2048^2, 64 lights: 18 -> 5 ms; 1024^2, 16
        lights: 4.2 -> 0.3 ms)."""
        best = np.zeros(len(directions), np.float32)
        for proj in ss.projections(directions, self.normals_by_axis):
            np.maximum(best, proj.max(axis=1), out=best)
        return best

    def set_environment(self, pixels: np.ndarray):
        """Replace the equirectangular map (H, W, 3) linear RGB of the 'environment' background."""
        limit = min(MAX_ENVIRONMENT_WIDTH, int(self.kit.ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384)))
        pixels = fit_environment(np.asarray(pixels, dtype=np.float32), limit)
        h, w = pixels.shape[:2]
        self.environment.release()
        data = np.dstack([pixels, np.ones((h, w), np.float32)]).astype("f4")
        self.environment = self.kit.texture((w, h), 4, data.tobytes(), linear=True, repeat=True)
        self.environment.build_mipmaps()  # environment_seen reads a minified map's level
        self.environment.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)

    def release(self):
        for tex in (self.positions, self.normals, self.albedo, self.background, self.environment):
            tex.release()
