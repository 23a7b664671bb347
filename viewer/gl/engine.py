"""The GL engine: renders a scene bundle under a set of area lights, redoing only what changed.

Passes (one shader file each in shaders/), per light l:
  1. shadow map       depth mesh (decimated) rendered orthographically from the light
  2. CSM basis        Fourier basis maps cos/sin(c_k z) of the shadow map
  3. prefilter        Gaussian of the light's sigma (resolution pyramid or exact, see prefilter.py)
  4. light pass       at every camera pixel: soft visibility (CSM), hard visibility (shadow test),
                      Lambert and Disney specular shading per unit intensity
then for all lights:
  5. composite        HDR = sum_l V_l I_l (A S_diff_l + S_spec_l)
  6. display          exposure, tone map, sRGB over a background

Cache rules: a new direction redoes 1-6 for that light; a new sigma redoes 2-6 for that light; a
new intensity redoes 5-6; exposure, tone map or background redo 6 only. Lights that cannot
contribute (zero intensity, facing no pixel, or below ``skip_threshold`` of the total) are skipped,
soft filtering is skipped where sigma ~ 0 (soft = hard visibility), and specular work is compiled
out for a scene without specular reflectance.
"""

from __future__ import annotations

import time
from collections import Counter, defaultdict
from contextlib import contextmanager
from dataclasses import dataclass, field

import moderngl
import numpy as np

from ..lights import AreaLights
from ..mesh import depth_mesh, masked_points
from ..scene import Scene
from .. import shadow_space as ss
from .prefilter import BlurPlan, blur_plan
from .programs import ProgramCache

VISIBILITY_MODES = {"soft": 0, "hard": 1, "none": 2}
TONEMAPS = {"aces": 0, "reinhard": 1, "clamp": 2}
BACKGROUNDS = {"color": 0, "photo": 1, "environment": 2}
COMPOSITE_CHUNK = 8


@dataclass(frozen=True)
class EngineOptions:
    shadow_resolution: int = 512  # texels of each light's shadow map
    shadow_step: int = 2  # depth-mesh decimation for shadow passes (1 = every pixel)
    terms: int = 4  # CSM Fourier terms M (2M basis maps)
    prefilter: str = "pyramid"  # "pyramid" (cost independent of sigma) or "exact"
    hard_sigma: float = 0.05  # sigma (256-px units) below which soft visibility = hard visibility
    skip_threshold: float = 1e-5  # lights whose bound is below this fraction of the total are skipped
    profile: bool = False  # finish GL work after every pass and record its wall time


@dataclass
class _Light:
    direction: np.ndarray
    sigma: float
    intensity: np.ndarray
    frame: ss.LightFrame | None = None
    bound: float = 0.0  # max intensity x max n.l over the mask
    active: bool = True
    shadow_map: moderngl.Texture | None = None
    filtered: list = field(default_factory=list)
    plan: BlurPlan | None = None
    buffer: moderngl.Texture | None = None
    buffer_fbo: moderngl.Framebuffer | None = None
    dirty_shadow: bool = True
    dirty_filter: bool = True
    dirty_shading: bool = True


class Engine:
    """Owns the GL resources of one scene; ``set_lights`` then ``render``; read outputs back."""

    def __init__(self, ctx: moderngl.Context, scene: Scene, options: EngineOptions | None = None):
        self.ctx = ctx
        self.scene = scene
        self.options = options or EngineOptions()
        o = self.options
        if o.terms < 2 or o.terms > 16:
            raise ValueError(f"CSM terms must be in [2, 16], got {o.terms}")
        max_size = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
        if max(scene.width, scene.height, o.shadow_resolution) > max_size:
            raise ValueError(f"image {scene.width}x{scene.height} or shadow map {o.shadow_resolution} exceeds the GL limit {max_size}")
        self.programs = ProgramCache(ctx)
        self.counters: Counter = Counter()
        self.timings: dict[str, list[float]] = defaultdict(list)
        self.csm_offset, self.csm_clamp = ss.csm_constants(o.terms)
        self._n_tex = (o.terms + 1) // 2
        self._specular = scene.has_specular
        self._lights: list[_Light] = []
        self._visibility = "soft"
        self._display_state: dict = {"exposure": 0.0, "tonemap": "aces", "background": "color", "color": (0.0, 0.0, 0.0), "rotation": np.eye(3)}
        self._dirty_composite = True
        self._dirty_display = True
        self._upload_scene()

    # ------------------------------------------------------------------ resources
    def _texture(self, size, components, data=None, dtype="f4", linear=False, repeat=False, levels=False):
        tex = self.ctx.texture(size, components, data=data, dtype=dtype)
        if levels:
            tex.build_mipmaps()
        flt = moderngl.LINEAR if linear else moderngl.NEAREST
        tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST if (linear and levels) else (moderngl.NEAREST_MIPMAP_NEAREST if levels else flt), flt)
        tex.repeat_x = repeat
        tex.repeat_y = False
        return tex

    def _upload_scene(self):
        s, o, ctx = self.scene, self.options, self.ctx
        w, h = s.width, s.height
        mask = s.mask.astype(np.float32)
        pts = s.points()
        self.tex_positions = self._texture((w, h), 4, np.dstack([pts, mask]).astype("f4").tobytes())
        self.tex_normals = self._texture((w, h), 4, np.dstack([s.normal, mask]).astype("f4").tobytes())
        self.tex_materials = self._texture((w, h), 2, np.dstack([s.specular, s.roughness]).astype("f4").tobytes())
        self.tex_albedo = self._texture((w, h), 4, np.dstack([s.albedo, mask]).astype("f4").tobytes())
        bg = s.background if s.background is not None else np.zeros((h, w, 3), np.float32)
        self.tex_background = self._texture((w, h), 4, np.dstack([bg, np.ones((h, w), np.float32)]).astype("f4").tobytes())
        self.tex_environment = self._texture((1, 1), 4, np.zeros(4, "f4").tobytes(), linear=True, repeat=True)
        self.hdr = self._texture((w, h), 4)
        self.hdr_fbo = ctx.framebuffer(color_attachments=[self.hdr])
        self.display = self._texture((w, h), 4, dtype="f1")
        self.display_fbo = ctx.framebuffer(color_attachments=[self.display])

        mesh = depth_mesh(s, step=o.shadow_step)
        self.mesh = mesh
        self._frame_points = masked_points(s).astype(np.float64)
        rows, cols = np.nonzero(s.mask)
        # camera-pixel passes only touch the mask's bounding box (the rest stays cleared to zero)
        self._mask_box = (int(cols.min()), int(rows.min()), int(cols.max() - cols.min() + 1), int(rows.max() - rows.min() + 1))
        self._normals_masked = s.normal[s.mask].astype(np.float64)
        prog = self.programs.get("shadow_map.vert.glsl", "shadow_map.frag.glsl")
        self._mesh_vbo = ctx.buffer(mesh.vertices.astype("f4").tobytes())
        self._mesh_ibo = ctx.buffer(mesh.triangles.astype("i4").tobytes()) if mesh.n_triangles else None
        self._shadow_vao = (
            ctx.vertex_array(prog, [(self._mesh_vbo, "3f", "position")], index_buffer=self._mesh_ibo, index_element_size=4)
            if self._mesh_ibo is not None
            else None
        )
        r = o.shadow_resolution
        self._shadow_depth = ctx.depth_renderbuffer((r, r))
        self._basis = [self._texture((r, r), 4, levels=True) for _ in range(self._n_tex)]
        self._basis_fbo = ctx.framebuffer(color_attachments=self._basis)
        self._scratch: dict = {}
        self._fullscreen_vaos: dict = {}

    def _fullscreen(self, program: moderngl.Program):
        vao = self._fullscreen_vaos.get(program.glo)
        if vao is None:
            vao = self._fullscreen_vaos[program.glo] = self.ctx.vertex_array(program, [])
        vao.render(moderngl.TRIANGLES, vertices=3)

    @contextmanager
    def _timed(self, name: str):
        self.counters[name] += 1
        if not self.options.profile:
            yield
            return
        self.ctx.finish()
        t0 = time.perf_counter()
        yield
        self.ctx.finish()
        self.timings[name].append(time.perf_counter() - t0)

    # ------------------------------------------------------------------ inputs
    @property
    def lights(self) -> AreaLights:
        return AreaLights(
            np.array([l.direction for l in self._lights]).reshape(-1, 3),
            np.array([l.sigma for l in self._lights]),
            np.array([l.intensity for l in self._lights]).reshape(-1, 3),
        )

    def set_lights(self, lights: AreaLights):
        """Replace the light set; only what changed is marked for recomputation."""
        lights.validate()
        if len(lights) != len(self._lights):
            for l in self._lights:
                self._release_light(l)
            self._lights = [_Light(d.copy(), float(s), i.copy()) for d, s, i in zip(lights.direction, lights.sigma, lights.intensity)]
            for l in self._lights:
                l.frame = ss.light_frames(self._frame_points, l.direction[None], self.options.terms)[0]
            self._dirty_composite = True
        else:
            for l, d, s, i in zip(self._lights, lights.direction, lights.sigma, lights.intensity):
                if not np.array_equal(l.direction, d):
                    l.direction = d.copy()
                    l.frame = ss.light_frames(self._frame_points, d[None], self.options.terms)[0]
                    l.dirty_shadow = True
                if l.sigma != float(s):
                    l.sigma = float(s)
                    l.dirty_filter = True
                if not np.array_equal(l.intensity, i):
                    l.intensity = i.copy()
                    self._dirty_composite = True
        self._update_activity()

    def _update_activity(self):
        for l in self._lights:
            facing = float(np.max(self._normals_masked @ l.direction.astype(np.float64), initial=0.0))
            l.bound = float(np.max(l.intensity)) * max(facing, 0.0)
        total = sum(l.bound for l in self._lights)
        for l in self._lights:
            active = l.bound > 0.0 and l.bound >= self.options.skip_threshold * total
            if active != l.active:
                l.active = active
                self._dirty_composite = True

    def set_visibility(self, mode: str):
        """Which visibility the composite uses: 'soft' (CSM), 'hard' (shadow map) or 'none'."""
        if mode not in VISIBILITY_MODES:
            raise ValueError(f"visibility must be one of {', '.join(VISIBILITY_MODES)}, got {mode!r}")
        if mode != self._visibility:
            self._visibility = mode
            self._dirty_composite = True

    def set_display(self, exposure: float | None = None, tonemap: str | None = None, background: str | None = None,
                    color=None, environment_rotation=None):
        """Display settings; only the display pass is redone."""
        st = self._display_state
        if tonemap is not None and tonemap not in TONEMAPS:
            raise ValueError(f"tone map must be one of {', '.join(TONEMAPS)}, got {tonemap!r}")
        if background is not None and background not in BACKGROUNDS:
            raise ValueError(f"background must be one of {', '.join(BACKGROUNDS)}, got {background!r}")
        if background == "photo" and self.scene.background is None:
            raise ValueError("this scene bundle has no background image (background.png)")
        for key, value in (("exposure", exposure), ("tonemap", tonemap), ("background", background), ("color", color),
                           ("rotation", environment_rotation)):
            if value is not None:
                if key == "exposure" and not np.isfinite(value):
                    raise ValueError("exposure must be finite")
                st[key] = value
        self._dirty_display = True

    def set_environment(self, pixels: np.ndarray):
        """Upload an equirectangular map (H, W, 3) linear RGB for the 'environment' background."""
        pixels = np.asarray(pixels, dtype=np.float32)
        h, w = pixels.shape[:2]
        self.tex_environment.release()
        data = np.dstack([pixels, np.ones((h, w), np.float32)]).astype("f4")
        self.tex_environment = self._texture((w, h), 4, data.tobytes(), linear=True, repeat=True)
        self._dirty_display = True

    # ------------------------------------------------------------------ passes
    def _release_light(self, l: _Light):
        for res in [l.shadow_map, l.buffer, l.buffer_fbo, *l.filtered]:
            if res is not None:
                res.release()

    def _ensure_light_resources(self, l: _Light):
        if l.shadow_map is None:
            r = self.options.shadow_resolution
            l.shadow_map = self._texture((r, r), 1)
            l.buffer = self._texture((self.scene.width, self.scene.height), 4)
            l.buffer_fbo = self.ctx.framebuffer(color_attachments=[l.buffer])
            l.buffer_fbo.clear(0.0, 0.0, 0.0, 0.0)

    def _render_shadow_map(self, l: _Light):
        with self._timed("shadow_map"):
            fbo = self.ctx.framebuffer(color_attachments=[l.shadow_map], depth_attachment=self._shadow_depth)
            fbo.use()
            fbo.clear(l.frame.empty_depth, 0.0, 0.0, 0.0, depth=1.0)
            if self._shadow_vao is not None:
                prog = self._shadow_vao.program
                prog["light_frame"].write(l.frame.matrix().T.astype("f4").tobytes())
                self.ctx.enable(moderngl.DEPTH_TEST)
                self.ctx.disable(moderngl.CULL_FACE)
                self._shadow_vao.render(moderngl.TRIANGLES)
                self.ctx.disable(moderngl.DEPTH_TEST)
            fbo.release()

    def _scratch_textures(self, size):
        key = tuple(size)
        if key not in self._scratch:
            texs = [self._texture(size, 4) for _ in range(self._n_tex)]
            self._scratch[key] = (texs, self.ctx.framebuffer(color_attachments=texs))
        return self._scratch[key]

    def _prefilter(self, l: _Light):
        o = self.options
        r = o.shadow_resolution
        plan = blur_plan(ss.sigma_in_pixels(l.sigma, r), r, o.prefilter)
        l.plan = plan
        with self._timed("csm_basis"):
            prog = self.programs.get("fullscreen.vert.glsl", "csm_basis.frag.glsl", TERMS=o.terms)
            l.shadow_map.use(0)
            prog["shadow_map"] = 0
            self._basis_fbo.use()
            self._fullscreen(prog)
            if plan.level > 0:
                for tex in self._basis:
                    tex.build_mipmaps(0, plan.level)
        size = (max(r >> plan.level, 1), max(r >> plan.level, 1))
        if not l.filtered or l.filtered[0].size != size:
            for tex in l.filtered:
                tex.release()
            l.filtered = [self._texture(size, 4, linear=True) for _ in range(self._n_tex)]
        temp, temp_fbo = self._scratch_textures(size)
        prog = self.programs.get("fullscreen.vert.glsl", "gaussian_blur.frag.glsl", TERMS=o.terms)
        prog["radius"] = plan.radius
        prog["sigma"] = plan.sigma
        prog["norm"] = plan.norm
        with self._timed("prefilter"):
            for axis, sources, level, target in (((1, 0), self._basis, plan.level, temp_fbo), ((0, 1), temp, 0, None)):
                for t, tex in enumerate(sources):
                    tex.use(1 + t)
                prog["source"] = list(range(1, 1 + self._n_tex)) if self._n_tex > 1 else 1
                prog["level"] = level
                prog["axis"] = axis
                if target is None:
                    target = self.ctx.framebuffer(color_attachments=l.filtered)
                    target.use()
                    self._fullscreen(prog)
                    target.release()
                else:
                    target.use()
                    self._fullscreen(prog)

    def _light_pass(self, l: _Light, soft_from_hard: bool):
        o = self.options
        defines = {"TERMS": o.terms}
        if self._specular:
            defines["SPECULAR"] = None
        prog = self.programs.get("fullscreen.vert.glsl", "light_pass.frag.glsl", **defines)
        with self._timed("light_pass"):
            r = o.shadow_resolution
            f = l.frame
            units = {"positions": self.tex_positions, "normals": self.tex_normals, "materials": self.tex_materials, "shadow_map": l.shadow_map}
            for unit, (name, tex) in enumerate(units.items()):
                tex.use(unit)
                if prog.get(name, None) is not None:
                    prog[name] = unit
            if not soft_from_hard:
                for t, tex in enumerate(l.filtered):
                    tex.use(len(units) + t)
                prog["filtered_basis"] = list(range(len(units), len(units) + self._n_tex)) if self._n_tex > 1 else len(units)
            prog["soft_from_hard"] = soft_from_hard
            prog["light_frame"].write(f.matrix().T.astype("f4").tobytes())
            prog["light_dir"] = tuple(float(v) for v in f.direction)
            prog["texel_world"] = f.texel_world(r)
            prog["depth_scale"] = f.depth_scale()
            prog["hard_threshold"] = ss.HARD_SHADOW_THRESHOLD
            prog["normal_offset_texels"] = ss.NORMAL_OFFSET_TEXELS
            prog["slope_bias_texels"] = ss.SLOPE_BIAS_TEXELS
            prog["max_slope"] = ss.MAX_SLOPE
            prog["csm_offset"] = self.csm_offset
            prog["csm_clamp"] = self.csm_clamp
            l.buffer_fbo.use()
            l.buffer_fbo.scissor = self._mask_box
            self._fullscreen(prog)

    def _composite(self):
        active = [l for l in self._lights if l.active]
        prog = self.programs.get("fullscreen.vert.glsl", "composite.frag.glsl", CHUNK=COMPOSITE_CHUNK)
        with self._timed("composite"):
            self.hdr_fbo.use()
            self.hdr_fbo.scissor = None
            self.hdr_fbo.clear(0.0, 0.0, 0.0, 0.0)
            self.hdr_fbo.scissor = self._mask_box
            self.tex_albedo.use(0)
            prog["albedo_mask"] = 0
            prog["light_buffers"] = list(range(1, 1 + COMPOSITE_CHUNK))
            prog["visibility_channel"] = VISIBILITY_MODES[self._visibility]
            chunks = [active[i:i + COMPOSITE_CHUNK] for i in range(0, len(active), COMPOSITE_CHUNK)] or [[]]
            for c, chunk in enumerate(chunks):
                for i, l in enumerate(chunk):
                    l.buffer.use(1 + i)
                for i in range(len(chunk), COMPOSITE_CHUNK):
                    self.tex_albedo.use(1 + i)  # unused slots still need a bound texture
                inten = np.zeros((COMPOSITE_CHUNK, 3), "f4")
                for i, l in enumerate(chunk):
                    inten[i] = l.intensity
                prog["intensity"].write(inten.tobytes())
                prog["count"] = len(chunk)
                prog["write_alpha"] = c == 0
                if c == 0:
                    self.ctx.disable(moderngl.BLEND)
                else:
                    self.ctx.enable(moderngl.BLEND)
                    self.ctx.blend_func = moderngl.ONE, moderngl.ONE
                self._fullscreen(prog)
            self.ctx.disable(moderngl.BLEND)

    def _display(self):
        st = self._display_state
        prog = self.programs.get("fullscreen.vert.glsl", "display.frag.glsl")
        cam = self.scene.camera
        with self._timed("display"):
            self.display_fbo.use()
            self.hdr.use(0)
            self.tex_background.use(1)
            self.tex_environment.use(2)
            prog["hdr"] = 0
            prog["background_image"] = 1
            prog["environment"] = 2
            prog["background_mode"] = BACKGROUNDS[st["background"]]
            prog["background_color"] = tuple(float(c) for c in st["color"])
            prog["environment_rotation"].write(np.asarray(st["rotation"], dtype="f4").T.tobytes())
            prog["focal_center_px"] = cam.center
            prog["focal_px"] = cam.focal_px
            prog["exposure"] = float(st["exposure"])
            prog["tonemap_op"] = TONEMAPS[st["tonemap"]]
            prog["flip_y"] = False
            self._fullscreen(prog)

    def render(self) -> "Engine":
        """Bring every output up to date, redoing only the passes whose inputs changed."""
        if not self._lights:
            raise ValueError("no lights: call set_lights first")
        o = self.options
        hard_px = ss.sigma_in_pixels(o.hard_sigma, o.shadow_resolution)
        for l in self._lights:
            if not l.active:
                continue  # stays dirty, so it is computed once it contributes
            self._ensure_light_resources(l)
            if l.dirty_shadow:
                self._render_shadow_map(l)
                l.dirty_shadow, l.dirty_filter = False, True
            soft_from_hard = ss.sigma_in_pixels(l.sigma, o.shadow_resolution) < hard_px
            if l.dirty_filter:
                if not soft_from_hard:
                    self._prefilter(l)
                l.dirty_filter, l.dirty_shading = False, True
            if l.dirty_shading:
                self._light_pass(l, soft_from_hard)
                l.dirty_shading = False
                self._dirty_composite = True
        if self._dirty_composite:
            self._composite()
            self._dirty_composite = False
            self._dirty_display = True
        if self._dirty_display:
            self._display()
            self._dirty_display = False
        return self

    # ------------------------------------------------------------------ outputs
    def _read(self, tex: moderngl.Texture, components: int, dtype="f4") -> np.ndarray:
        w, h = tex.size
        arr = np.frombuffer(tex.read(), dtype=np.float32 if dtype == "f4" else np.uint8)
        return arr.reshape(h, w, components).copy()

    def read_hdr(self) -> np.ndarray:
        """(H, W, 3) float32 linear HDR, row 0 at the top."""
        return self._read(self.hdr, 4)[..., :3]

    def read_display(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB display image."""
        return self._read(self.display, 4, dtype="f1")[..., :3]

    def read_light(self, index: int) -> dict:
        """Per-light intermediate outputs (H, W) each: soft and hard visibility, diffuse and
        specular shading per unit intensity. All zero for a skipped light."""
        l = self._lights[index]
        if not l.active or l.buffer is None:
            z = np.zeros((self.scene.height, self.scene.width), np.float32)
            return {"visibility_soft": z, "visibility_hard": z, "diffuse": z, "specular": z}
        b = self._read(l.buffer, 4)
        return {"visibility_soft": b[..., 0], "visibility_hard": b[..., 1], "diffuse": b[..., 2], "specular": b[..., 3]}

    def read_shadow_map(self, index: int) -> np.ndarray:
        """(R, R) normalised depth of a light's shadow map, row 0 at v = 0."""
        l = self._lights[index]
        if l.shadow_map is None:
            raise ValueError(f"light {index} has no shadow map (it contributes nothing)")
        return self._read(l.shadow_map, 1)[..., 0]

    def light_active(self, index: int) -> bool:
        return self._lights[index].active

    def release(self):
        for l in self._lights:
            self._release_light(l)
        self._lights = []
        for vao in self._fullscreen_vaos.values():
            vao.release()
        for texs, fbo in self._scratch.values():
            fbo.release()
            for t in texs:
                t.release()
        self.programs.release()
