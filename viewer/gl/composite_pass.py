"""5. The composite (composite.frag.glsl): HDR = sum_l V_l I_l (A S_diff_l + S_spec_l) over the mask's
box, with the mask in alpha; for a scene with a frame layer it also writes the shading sums
D = sum_l V_l I_l S_diff_l and S = sum_l V_l I_l S_spec_l that the frame composite upsamples."""

from __future__ import annotations

import moderngl
import numpy as np

from viewer.gl.kit import PassKit
from viewer.gl.light import Light
from viewer.gl.light_pass import LIGHTS_PER_PASS, LightAtlas, RefinedVisibility
from viewer.gl.scene_resources import SceneResources
from viewer.shader_modes import code

MAX_LIGHTS_PER_COMPOSITE = 64


class CompositePass:
    """Owns the work-resolution HDR target (and the two shading targets of a frame scene)."""

    name = "composite"
    # the light atlas, the intensities and which lights count, the shadow mode shown, the refined
    # visibility (in the refined mode), and the terms shown (diffuse / specular switches, shading views)
    inputs = ("light_pass", "intensity", "activity", "visibility", "refined_visibility", "terms")

    def __init__(self, kit: PassKit, scene: SceneResources, size, frame_shading: bool):
        self.kit, self.scene = kit, scene
        self.hdr = kit.texture(size, 4)
        targets = [self.hdr]
        self.shading = []  # (D, S) at the work resolution, mipmapped by the frame composite
        if frame_shading:
            self.shading = [kit.texture(size, 4, linear=True) for _ in range(2)]
            for tex in self.shading:  # filled_sample reads coarser mip levels past the mask
                tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            targets += self.shading
        self.fbo = kit.ctx.framebuffer(color_attachments=targets)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0)

    def run(self, lights: list[Light], atlas: LightAtlas, refined: RefinedVisibility, visibility: str, terms):
        kit, sc = self.kit, self.scene
        ctx = kit.ctx
        defines = {"MAX_LIGHTS": MAX_LIGHTS_PER_COMPOSITE}
        if self.shading:
            defines["FRAME_SHADING"] = None
        prog = kit.programs.get("fullscreen.vert.glsl", "composite.frag.glsl", **defines)
        with kit.timed(self.name):
            x, y, _, _ = sc.mask_box
            self.fbo.scissor = sc.mask_box  # outside the box the HDR stays cleared to zero
            self.fbo.use()
            sc.albedo.use(0)
            prog["albedo_mask"] = 0
            for j, plane in enumerate(atlas.planes):
                plane.use(1 + j)
                prog[f"light_plane{j}"] = 1 + j
            prog["box_origin"] = (x, y)
            mode = visibility
            if mode == "refined":
                if refined.current:
                    for j, plane in enumerate(refined.planes):
                        plane.use(1 + LIGHTS_PER_PASS + j)
                        prog[f"refined_plane{j}"] = 1 + LIGHTS_PER_PASS + j
                else:
                    mode = "soft"  # until the refinement of these lights arrives
            prog["visibility_channel"] = code("VISIBILITY", mode)
            diffuse, specular, unit_albedo = terms
            prog["term_weights"] = (diffuse, specular)
            prog["unit_albedo"] = unit_albedo
            k = MAX_LIGHTS_PER_COMPOSITE
            chunks = [lights[i:i + k] for i in range(0, len(lights), k)]
            for c, chunk in enumerate(chunks):
                groups = (len(chunk) + LIGHTS_PER_PASS - 1) // LIGHTS_PER_PASS
                origins = np.zeros((k // LIGHTS_PER_PASS, 2), "i4")
                inten = np.zeros((k, 3), "f4")
                for i, l in enumerate(chunk):
                    origins[i // LIGHTS_PER_PASS] = l.tile
                    if l.active:
                        inten[i] = l.intensity
                prog["group_origin"].write(origins.tobytes())
                prog["intensity"].write(inten.tobytes())
                prog["groups"] = groups
                prog["write_alpha"] = c == 0
                if c == 0:
                    ctx.disable(moderngl.BLEND)
                else:
                    ctx.enable(moderngl.BLEND)
                    ctx.blend_func = moderngl.ONE, moderngl.ONE
                kit.fullscreen(prog)
            ctx.disable(moderngl.BLEND)

    def release(self):
        for obj in [self.fbo, self.hdr, *self.shading]:
            obj.release()
