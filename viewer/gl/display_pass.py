"""6. The display (display.frag.glsl) of a scene without a frame layer: exposure, neutral / ACES / Reinhard /
clamp, sRGB over the environment map, the background image or a colour, at the maps' resolution;
and the inspection views (inspect.frag.glsl) of any scene: its maps, or one light's shadow."""

from __future__ import annotations

import moderngl
import numpy as np

from viewer.gl.kit import PassKit
from viewer.gl.light import PASS_OFF, Light
from viewer.gl.light_pass import LightAtlas
from viewer.gl.scene_resources import SceneResources
from viewer.scene.camera import Camera
from viewer.scene.look import Look
from viewer.shader_modes import MODES, code

INSPECT_VIEWS = MODES["INSPECT"]


def set_background(prog, look: Look, background: str, camera: Camera):
    """The background's uniforms (shaders/envmap.glsl and the background modes) for ``look``: its
    mode, colour, the map's turn, the camera the map is seen through and its height above the ground."""
    prog["background_mode"] = code("BACKGROUND", background)
    prog["background_color"] = look.background_color
    prog["environment_rotation"].write(np.asarray(look.environment_rotation, dtype="f4").T.tobytes())
    prog["ground_squash"] = look.ground_squash
    prog["focal_center_px"] = camera.center
    prog["focal_px"] = camera.focal_px


class DisplayPass:
    """Owns the work-resolution display image (uint8 sRGB + alpha)."""

    name = "display"
    inputs = ("composite",)  # redrawn over the mask's box only
    whole_inputs = ("display", "view", "environment", "ground", "ground_shadow")  # redrawn over the whole image

    def __init__(self, kit: PassKit, scene: SceneResources, size, camera: Camera, ground: moderngl.Texture):
        self.kit, self.scene, self.camera, self.ground = kit, scene, camera, ground  # ground: GroundShadowPass's
        self.image = kit.texture(size, 4, dtype="f1")
        self.fbo = kit.ctx.framebuffer(color_attachments=[self.image])

    def run(self, hdr: moderngl.Texture, look: Look, background: str, box=None):
        with self.kit.timed(self.name):
            self.draw(self.fbo, hdr, look, background, box)

    def draw(self, fbo, hdr, look: Look, background: str, box=None, hdr_output: bool = False):
        """The display shader over ``fbo`` (``box`` = (x, y, w, h) to redraw only that part; ``hdr_output``:
        the linear HDR over the background, before exposure and tone map)."""
        kit, sc = self.kit, self.scene
        prog = kit.programs.get("fullscreen.vert.glsl", "display.frag.glsl", **({"HDR_OUTPUT": None} if hdr_output else {}))
        fbo.scissor = box
        fbo.use()
        hdr.use(0)
        sc.background.use(1)
        sc.environment.use(2)
        self.ground.use(3)
        prog["hdr"] = 0
        prog["background_image"] = 1
        prog["environment"] = 2
        prog["ground_occlusion"] = 3
        prog["ground"] = look.ground
        set_background(prog, look, background, self.camera)
        if not hdr_output:
            prog["exposure"] = look.exposure_stops
            prog["tonemap_op"] = code("TONEMAP", look.tonemap)
        kit.fullscreen(prog)
        fbo.scissor = None

    def read_hdr_output(self, hdr, look: Look, background: str) -> np.ndarray:
        with self.kit.scratch_target(hdr.size) as (tex, fbo):
            self.draw(fbo, hdr, look, background, None, hdr_output=True)
            return self.kit.read(tex, 4)

    def release(self):
        self.fbo.release()
        self.image.release()


class InspectPass:
    """An inspection view into the display image (the display's size stays): the albedo, normal,
    depth, specular or roughness map, or one light's shadow under the current shadow mode."""

    name = "display"  # counted as a display run; drawn in place of the display when the view is an inspection
    # view, so it is redrawn whenever the display is (the engine tracks the display's inputs)

    def __init__(self, kit: PassKit, scene: SceneResources, work_size):
        self.kit, self.scene, self.work_size = kit, scene, work_size

    def run(self, fbo, view: str, light: Light | None, atlas: LightAtlas, visibility: str):
        kit, sc = self.kit, self.scene
        prog = kit.programs.get("fullscreen.vert.glsl", "inspect.frag.glsl")
        with kit.timed(self.name):
            fbo.scissor = None
            fbo.use()
            prog["display_to_work"] = (self.work_size[0] / fbo.size[0], self.work_size[1] / fbo.size[1])
            for unit, (name, tex) in enumerate((("positions", sc.positions), ("normals", sc.normals), ("albedo_mask", sc.albedo))):
                tex.use(unit)
                prog[name] = unit
            (atlas.planes[light.slot] if light is not None else sc.albedo).use(3)
            prog["light_plane"] = 3
            prog["light_valid"] = light is not None and light.active and light.pass_mode != PASS_OFF
            prog["tile_origin"] = light.tile if light is not None else (0, 0)
            prog["box_origin"] = sc.mask_box[:2]
            prog["visibility_channel"] = code("VISIBILITY", "hard" if visibility == "hard" else "soft")
            prog["view"] = code("INSPECT", view)
            prog["depth_range"] = sc.depth_range
            prog["background_color"] = (0.1, 0.1, 0.1)
            kit.fullscreen(prog)
