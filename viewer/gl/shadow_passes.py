"""The per-light shadow passes (paper section 4): the shadow map, its convolutional-shadow-map
basis, and the basis pre-filtered by the light's Gaussian. Each runs for one light at a time and
keeps its results in the light's own resources (:class:`viewer.gl.light.Light`); ``inputs`` names
what makes a light's result stale (the engine's change tracking reads it)."""

from __future__ import annotations

import moderngl
import numpy as np

from viewer.gl.kit import PassKit
from viewer.gl.light import Light
from viewer.gl.prefilter import blur_plan
from viewer.gl.scene_resources import SceneResources
from viewer.scene import shadow_space as ss

SMALL_ATLAS_TILE = 64  # tiles up to this size are drawn whole, in one draw
BASIS_MAX_BLOCK_LEVEL = 3  # deeper pyramid levels come from a box_reduce pass (keeps the basis pass parallel)


class ShadowMapPass:
    """1. The depth mesh rendered orthographically from the light into an R32F shadow map
    (shadow_map.{vert,frag}.glsl). Owns the mesh's buffers and the shared depth buffer."""

    name = "shadow_map"
    inputs = ("direction",)

    def __init__(self, kit: PassKit, scene: SceneResources, resolution: int):
        self.kit = kit
        self.resolution = resolution
        mesh = scene.mesh
        prog = kit.programs.get("shadow_map.vert.glsl", "shadow_map.frag.glsl")
        self.vao = self.vbo = self.ibo = None  # a mesh without triangles casts no shadow
        if mesh.n_triangles:
            self.vbo = kit.ctx.buffer(mesh.vertices.astype("f4").tobytes())
            self.ibo = kit.ctx.buffer(mesh.triangles.astype("i4").tobytes())
            self.vao = kit.ctx.vertex_array(prog, [(self.vbo, "3f", "position")], index_buffer=self.ibo, index_element_size=4)
        self.depth = kit.ctx.depth_renderbuffer((resolution, resolution))

    def run(self, l: Light):
        l.ensure_shadow_map(self.kit, self.resolution, self.depth)
        ctx = self.kit.ctx
        with self.kit.timed(self.name):
            fbo = l.shadow_fbo
            fbo.use()
            fbo.clear(l.frame.empty_depth, 0.0, 0.0, 0.0, depth=1.0)
            if self.vao is not None:
                prog = self.vao.program
                prog["light_frame"].write(l.frame.matrix.T.astype("f4").tobytes())
                ctx.enable(moderngl.DEPTH_TEST)
                ctx.disable(moderngl.CULL_FACE)
                self.vao.render(moderngl.TRIANGLES)
                ctx.disable(moderngl.DEPTH_TEST)

    def release(self):
        for obj in (self.vao, self.vbo, self.ibo, self.depth):
            if obj is not None:
                obj.release()


def footprint_pass(kit: PassKit, l: Light, fbo: moderngl.Framebuffer, n: int, n_tex: int, terms: int, margin: int,
                   prog: moderngl.Program, cheap_texels: bool = True):
    """Run a basis-atlas pass only over the mesh's footprint in the shadow map (plus ``margin``
    texels) in each tile; the rest of the tile holds the basis of an empty texel, a constant,
    which every later pass (box average, Gaussian) leaves unchanged. Small atlases of cheap
    texels are drawn whole in one draw instead (per-draw overhead dominates there)."""
    if cheap_texels and n <= SMALL_ATLAS_TILE:
        fbo.scissor = None
        fbo.use()
        kit.fullscreen(prog)
        return
    u0, v0, u1, v1 = l.frame.footprint
    x0, y0 = max(int(np.floor(u0 * n)) - margin, 0), max(int(np.floor(v0 * n)) - margin, 0)
    x1, y1 = min(int(np.ceil(u1 * n)) + margin, n), min(int(np.ceil(v1 * n)) + margin, n)
    empty = ss.csm_empty_basis(l.frame.empty_depth, terms)
    fbo.scissor = None
    fbo.use()
    for t in range(n_tex):
        fbo.clear(*empty[t], viewport=(t * n, 0, n, n))
    if x1 > x0 and y1 > y0:
        for t in range(n_tex):
            fbo.scissor = (t * n + x0, y0, x1 - x0, y1 - y0)
            fbo.use()
            kit.fullscreen(prog)
    fbo.scissor = None


class CsmBasisPass:
    """2. The basis atlas (cos, sin)(c_k z) of the light's shadow map at its blur plan's mip level L
    (csm_basis.frag.glsl: box averages of 2^L x 2^L texel blocks, directly up to level 3; deeper
    levels by box_reduce.frag.glsl). The plan follows from sigma (prefilter.py)."""

    name = "csm_basis"
    inputs = ("shadow_map", "sigma")

    def __init__(self, kit: PassKit, resolution: int, terms: int, method: str):
        self.kit, self.resolution, self.terms, self.method = kit, resolution, terms, method
        self.n_tex = (terms + 1) // 2  # RGBA tiles per atlas

    def run(self, l: Light):
        kit, r = self.kit, self.resolution
        plan = l.plan = blur_plan(ss.sigma_in_pixels(l.sigma, r), r, self.method)
        n = max(r >> plan.level, 1)
        staged = min(plan.level, BASIS_MAX_BLOCK_LEVEL)
        n_staged = max(r >> staged, 1)
        tex, fbo = l.work_atlas(kit, (n_staged * self.n_tex, n_staged), "basis")
        with kit.timed(self.name):
            prog = kit.programs.get("fullscreen.vert.glsl", "csm_basis.frag.glsl", TERMS=self.terms)
            l.shadow_map.use(0)
            prog["shadow_map"] = 0
            prog["block"] = 1 << staged
            prog["tile_size"] = n_staged
            prog["empty_depth"] = l.frame.empty_depth
            footprint_pass(kit, l, fbo, n_staged, self.n_tex, self.terms, 1, prog, cheap_texels=False)  # block x block reads each
            if staged < plan.level:
                _, reduced_fbo = l.work_atlas(kit, (n * self.n_tex, n), "reduced")
                reduce = kit.programs.get("fullscreen.vert.glsl", "box_reduce.frag.glsl")
                tex.use(0)
                reduce["source"] = 0
                reduce["factor"] = 1 << (plan.level - staged)
                footprint_pass(kit, l, reduced_fbo, n, self.n_tex, self.terms, 1, reduce)


class PrefilterPass:
    """3. The separable Gaussian of the residual sigma over the basis atlas (gaussian_blur.frag.glsl,
    horizontal into the light's "temp" atlas, vertical into its "filtered" one)."""

    name = "prefilter"
    inputs = ("csm_basis",)

    def __init__(self, kit: PassKit, resolution: int, terms: int):
        self.kit, self.resolution, self.terms = kit, resolution, terms
        self.n_tex = (terms + 1) // 2

    def run_axis(self, l: Light, axis):
        """One direction of the blur: basis -> "temp" (horizontal, axis (1, 0)) or "temp" -> "filtered"."""
        kit, plan = self.kit, l.plan
        n = max(self.resolution >> plan.level, 1)
        size = (n * self.n_tex, n)
        if axis == (1, 0):
            source = l.work["reduced" if plan.level > BASIS_MAX_BLOCK_LEVEL else "basis"][0]
            _, target = l.work_atlas(kit, size, "temp")
        else:
            source = l.work["temp"][0]
            l.filtered, target = l.work_atlas(kit, size, "filtered")
        prog = kit.programs.get("fullscreen.vert.glsl", "gaussian_blur.frag.glsl")
        with kit.timed(self.name, count=axis == (1, 0)):  # counted once per light
            prog["radius"] = plan.radius
            prog["sigma"] = plan.sigma
            prog["norm"] = plan.norm
            prog["tile_size"] = n
            prog["source"] = 0
            prog["axis"] = axis
            source.use(0)
            footprint_pass(kit, l, target, n, self.n_tex, self.terms, plan.radius + 1, prog)
