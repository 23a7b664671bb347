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
For a scene with a frame layer (a photo's bundle: frame_pass.py), 5 also writes the shading sums,
and at the output frame's resolution the frame composite with its display (5f) runs in place of 6,
over a frame background (6b) kept until the background, the map or its rotation changes.

Cache rules: a new direction redoes 1-6 for that light; a new sigma redoes 2-6 for that light; a
new intensity, the diffuse / specular switches or a shading view redo 5-6 (5f); exposure,
tone map, background or an inspection view redo 6 (5f, over the whole frame) only; the background,
the map or its rotation also 6b. Lights that cannot contribute (zero intensity,
facing no pixel, or an upper bound below ``skip_threshold`` of the scene's diffuse level) are
skipped, soft filtering is skipped where sigma ~ 0 (soft = hard visibility) and whenever the soft
visibility is not shown (hard or no shadows), shadow maps are skipped when no shadows are shown,
and specular work is compiled out for a scene without specular reflectance.
"""

from __future__ import annotations

import functools
import time
from collections import Counter, defaultdict
from contextlib import contextmanager
from dataclasses import dataclass, field

import moderngl
import numpy as np

from ..errors import InputError
from ..lights import AreaLights
from ..mesh import caster_points, depth_mesh, resolve_step
from ..scene import Scene
from .. import shadow_space as ss
from .context import make_current
from .frame_pass import MAX_FILL_LOD, OUTPUT_COMPOSITED_HDR, OUTPUT_PERSON_HDR, FramePass
from .prefilter import METHODS, BlurPlan, blur_plan
from .programs import shared_programs


def _in_context(method):
    """Runs an engine method with the engine's GL context current (see :func:`make_current`)."""

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        make_current(self.ctx)
        return method(self, *args, **kwargs)

    return run


VISIBILITY_MODES = {"soft": 0, "hard": 1, "none": 2, "refined": 3}
# What the display image shows: the relit frame, the diffuse or specular shading alone (composited
# from the same light atlas), or an inspection view of the bundle's maps or of one light's shadow.
VIEWS = ("final", "diffuse_shading", "specular_shading", "albedo", "normal", "depth", "specular", "roughness", "shadow")
_INSPECT_VIEWS = {"albedo": 1, "normal": 2, "depth": 3, "specular": 4, "roughness": 5, "shadow": 6}
# light-pass modes per light (shaders/light_pass.frag.glsl)
_PASS_OFF, _PASS_HARD, _PASS_SOFT, _PASS_UNSHADOWED = 0, 1, 2, 3
TONEMAPS = {"aces": 0, "reinhard": 1, "clamp": 2}
BACKGROUNDS = {"color": 0, "photo": 1, "environment": 2, "transparent": 3}
MAX_LIGHTS_PER_COMPOSITE = 64
LIGHTS_PER_PASS = 4  # lights per light pass (one light-atlas plane each, shaders/light_pass.frag.glsl)
SMALL_ATLAS_TILE = 64  # tiles up to this size are drawn whole, in one draw
BASIS_MAX_BLOCK_LEVEL = 3  # deeper pyramid levels come from a box_reduce pass (keeps the basis pass parallel)


@dataclass(frozen=True)
class EngineOptions:
    shadow_resolution: int = 512  # texels of each light's shadow map
    shadow_step: int = 0  # depth-mesh decimation for shadow passes (1 = every pixel; 0 = auto,
    # 3 per 512 image pixels: ~1.5 cm triangles on the sample, 1.8 % error, see docs/engine.md)
    terms: int = 4  # CSM Fourier terms M (2M basis maps)
    prefilter: str = "pyramid"  # "pyramid" (cost independent of sigma) or "exact"
    hard_sigma: float = 0.05  # sigma (256-px units) below which soft visibility = hard visibility
    skip_threshold: float = 1e-5  # lights whose upper bound is below this fraction of the diffuse level are skipped
    leave_out: bool = True  # skip what the scene does not need (dark lights, soft filtering at sigma ~ 0, specular
    # work on a matte scene); False does all of it, for measuring what the policy saves (relight bench report)
    profile: bool = False  # finish GL work after every pass and record its wall time

    def __post_init__(self):
        r = self.shadow_resolution
        if not (isinstance(r, int) and 16 <= r <= 8192 and r & (r - 1) == 0):
            raise InputError(None, f"shadow resolution must be a power of two in [16, 8192], got {r}")
        if not 2 <= self.terms <= 16:
            raise InputError(None, f"CSM terms must be in [2, 16], got {self.terms}")
        if self.shadow_step < 0:
            raise InputError(None, f"shadow step must be >= 0 (0 = auto), got {self.shadow_step}")
        if self.prefilter not in METHODS:
            raise InputError(None, f"prefilter must be one of {', '.join(METHODS)}, got {self.prefilter!r}")
        if not (self.hard_sigma >= 0 and 0 <= self.skip_threshold < 1):
            raise InputError(None, "hard_sigma must be >= 0 and skip_threshold in [0, 1)")


@dataclass
class _Light:
    direction: np.ndarray
    sigma: float
    intensity: np.ndarray
    frame: ss.LightFrame | None = None
    facing: float = 0.0  # max n.l over the mask's normals
    bound: float = 0.0  # max intensity x facing x the scene's response bound: >= any pixel's value
    active: bool = True
    shadow_map: moderngl.Texture | None = None
    shadow_fbo: moderngl.Framebuffer | None = None
    filtered: moderngl.Texture | None = None  # pre-filtered basis atlas (one of ``work``)
    work: dict = field(default_factory=dict)  # intermediate atlases: slot -> (texture, framebuffer)
    plan: BlurPlan | None = None
    tile: tuple = (0, 0)  # origin of this light's group tile in the light atlas
    slot: int = 0  # plane of the light atlas (light index % LIGHTS_PER_PASS)
    dirty_shadow: bool = True
    dirty_filter: bool = True
    dirty_shading: bool = True
    pass_mode: int = _PASS_OFF  # light-pass mode the light atlas currently holds for this light


class Engine:
    """Owns the GL resources of one scene; ``set_lights`` then ``render``; read outputs back."""

    def __init__(self, ctx: moderngl.Context, scene: Scene, options: EngineOptions | None = None):
        self.ctx = ctx
        make_current(ctx)
        self.scene = scene
        self.options = options or EngineOptions()
        o = self.options
        max_size = self._max_texture = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
        if max(scene.width, scene.height, o.shadow_resolution, *scene.output_size) > max_size:
            raise InputError(scene.source, f"image {scene.width}x{scene.height} (output {scene.output_size[0]}x{scene.output_size[1]}) "
                             f"or shadow map {o.shadow_resolution} exceeds this GL's texture limit {max_size}")
        self.programs = shared_programs(ctx)  # compiled once per context, not released with the engine
        self.counters: Counter = Counter()
        self.profile = self.options.profile  # may be toggled: profiling syncs after every pass
        self.timings: dict[str, list[float]] = defaultdict(list)
        self.csm_offset, self.csm_clamp = ss.csm_constants(o.terms)
        self._n_tex = (o.terms + 1) // 2
        self._specular = scene.has_specular or not o.leave_out
        self._lights: list[_Light] = []
        self._visibility = "soft"
        self._refined = False  # the refined planes hold the refinement of the current lights
        self.refined_planes: list = []
        self._components = (True, True)  # diffuse, specular shown in the final image
        self._view = ("final", 0)  # (view, inspected light)
        self._display_state: dict = {"exposure": 0.0, "tonemap": "aces", "background": "color", "color": np.zeros(3), "rotation": np.eye(3)}
        self._dirty_composite = True
        self._dirty_frame = True  # the shading sums' mipmaps (scenes with a frame layer)
        self._dirty_frame_background = True
        self._dirty_display = True
        self._dirty_background = True  # display pixels outside the mask's box need redrawing
        self.frame_pass: FramePass | None = None
        self._upload_scene()

    # ------------------------------------------------------------------ resources
    def _texture(self, size, components, data=None, dtype="f4", linear=False, repeat=False):
        tex = self.ctx.texture(size, components, data=data, dtype=dtype)
        flt = moderngl.LINEAR if linear else moderngl.NEAREST
        tex.filter = (flt, flt)
        tex.repeat_x = repeat
        tex.repeat_y = False
        return tex

    def _upload_scene(self):
        s, o, ctx = self.scene, self.options, self.ctx
        w, h = s.width, s.height
        mask = s.mask.astype(np.float32)
        pts = s.points()
        # two fetches per pixel and light: (position, roughness) and (normal, specular); normals are
        # zero outside the mask, so n.l <= 0 there
        self.tex_positions = self._texture((w, h), 4, np.dstack([pts, s.roughness]).astype("f4").tobytes())
        self.tex_normals = self._texture((w, h), 4, np.dstack([s.normal, s.specular]).astype("f4").tobytes())
        self.tex_albedo = self._texture((w, h), 4, np.dstack([s.albedo, mask]).astype("f4").tobytes())
        bg = s.background if s.background is not None else np.zeros((h, w, 3), np.float32)
        self.tex_background = self._texture((w, h), 4, np.dstack([bg, np.ones((h, w), np.float32)]).astype("f4").tobytes())
        self.tex_environment = self._texture((1, 1), 4, np.zeros(4, "f4").tobytes(), linear=True, repeat=True)
        self.hdr = self._texture((w, h), 4)
        targets = [self.hdr]
        self.shading_targets = []
        if s.frame is not None:  # the work composite also writes the shading sums the frame composite reads
            self.shading_targets = [self._texture((w, h), 4, linear=True) for _ in range(2)]
            for tex in self.shading_targets:  # filled_sample reads coarser mip levels past the mask
                tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            targets += self.shading_targets
            self.frame_pass = FramePass(ctx, self.programs, self._fullscreen, s.frame, s.camera, self._texture)
        self.hdr_fbo = ctx.framebuffer(color_attachments=targets)
        self.hdr_fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.work_display = self._texture((w, h), 4, dtype="f1")
        self.display_fbo = ctx.framebuffer(color_attachments=[self.work_display])

        self.shadow_step = resolve_step(o.shadow_step, s)
        mesh = depth_mesh(s, step=self.shadow_step)
        self.mesh = mesh
        self._frame_points = caster_points(s, mesh).astype(np.float32)
        self._sphere = ss.bounding_sphere(self._frame_points.astype(np.float64))
        rows, cols = np.nonzero(s.mask)
        self._depth_range = (float(s.depth[s.mask].min()), float(s.depth[s.mask].max()))
        # camera-pixel passes only touch the mask's bounding box (the rest stays cleared to zero)
        self._mask_box = (int(cols.min()), int(rows.min()), int(cols.max() - cols.min() + 1), int(rows.max() - rows.min() + 1))
        self._normals_masked = np.ascontiguousarray(s.normal[s.mask], dtype=np.float32)
        # Upper bound of (A S_diff + S_spec) per unit intensity and unit n.l over the scene:
        # S_spec = n.l F D G <= n.l * 1 * 1 / (pi alpha^2) * 1 / (n.l alpha) (G1(n.l) n.l <= 1,
        # G1(n.v) <= 1 / alpha), i.e. <= 1 / (pi alpha^3) with the smallest alpha of a specular pixel.
        glossy = s.mask & (s.specular > 0)
        alpha = max(float(s.roughness[glossy].min()) ** 2, 1e-3) if glossy.any() else None
        self._diffuse_bound = float(s.albedo[s.mask].max()) / np.pi
        self._response_bound = self._diffuse_bound + (1.0 / (np.pi * alpha**3) if alpha else 0.0)
        prog = self.programs.get("shadow_map.vert.glsl", "shadow_map.frag.glsl")
        self._shadow_vao = None  # a mesh without triangles casts no shadow
        if mesh.n_triangles:
            self._mesh_vbo = ctx.buffer(mesh.vertices.astype("f4").tobytes())
            self._mesh_ibo = ctx.buffer(mesh.triangles.astype("i4").tobytes())
            self._shadow_vao = ctx.vertex_array(prog, [(self._mesh_vbo, "3f", "position")], index_buffer=self._mesh_ibo,
                                                index_element_size=4)
        r = o.shadow_resolution
        self._shadow_depth = ctx.depth_renderbuffer((r, r))
        self._fullscreen_vaos: dict = {}

    def _fullscreen(self, program: moderngl.Program):
        vao = self._fullscreen_vaos.get(program.glo)
        if vao is None:
            vao = self._fullscreen_vaos[program.glo] = self.ctx.vertex_array(program, [])
        vao.render(moderngl.TRIANGLES, vertices=3)

    @contextmanager
    def _timed(self, name: str, count: bool = True):
        if count:
            self.counters[name] += 1
        if not self.profile:
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

    @_in_context
    def set_lights(self, lights: AreaLights):
        """Replace the light set; only what changed is marked for recomputation."""
        lights.validate()
        if len(lights) != len(self._lights):
            for l in self._lights:
                self._release_light(l)
            self._lights = [_Light(d.copy(), float(s), i.copy()) for d, s, i in zip(lights.direction, lights.sigma, lights.intensity)]
            self._allocate_light_atlas()
            moved = list(range(len(self._lights)))
            self._dirty_composite = True
            if self._view[0] == "shadow" and self._view[1] >= len(self._lights):
                self._view = ("final", 0)  # the inspected light is gone
                self._dirty_display = self._dirty_background = True
        else:
            moved = []
            for k, (l, d, s, i) in enumerate(zip(self._lights, lights.direction, lights.sigma, lights.intensity)):
                if not np.array_equal(l.direction, d):
                    l.direction = d.copy()
                    l.dirty_shadow = l.dirty_shading = True
                    moved.append(k)
                if l.sigma != float(s):
                    l.sigma = float(s)
                    l.dirty_filter = True
                    self._drop_refined()
                if not np.array_equal(l.intensity, i):
                    l.intensity = i.copy()
                    self._dirty_composite = True
        if moved:
            self._drop_refined()
            dirs = np.array([self._lights[k].direction for k in moved])
            frames = ss.light_frames(self._frame_points, dirs, self.options.shadow_resolution, self.options.terms, sphere=self._sphere)
            facing = (self._normals_masked @ dirs.T.astype(np.float32)).max(axis=0, initial=0.0)
            for k, frame, f in zip(moved, frames, facing):
                self._lights[k].frame = frame
                self._lights[k].facing = max(float(f), 0.0)
        self._update_activity()

    def _update_activity(self):
        """A light is skipped when even its upper bound (diffuse + specular peak) stays below
        ``skip_threshold`` of the scene's diffuse level (the sum of the lights' diffuse bounds)."""
        peaks = [float(np.max(l.intensity)) * l.facing for l in self._lights]  # max I x max n.l
        for l, peak in zip(self._lights, peaks):
            l.bound = peak * self._response_bound
        level = sum(peaks) * self._diffuse_bound
        level = level if level > 0 else sum(l.bound for l in self._lights)
        for l in self._lights:
            active = not self.options.leave_out or (l.bound > 0.0 and l.bound >= self.options.skip_threshold * level)
            if active != l.active:
                l.active = active
                self._dirty_composite = True

    def set_visibility(self, mode: str):
        """Which visibility the composite uses: 'soft' (CSM), 'hard' (shadow map), 'none', or
        'refined' (the refinement network's, see ``set_refined_visibility``; soft until it is set)."""
        if mode not in VISIBILITY_MODES:
            raise ValueError(f"visibility must be one of {', '.join(VISIBILITY_MODES)}, got {mode!r}")
        if mode != self._visibility:
            self._visibility = mode
            self._dirty_composite = True  # lights whose light pass lacks what the mode needs redo it in render()

    def _drop_refined(self):
        """The lights' shadows changed: the refined visibility no longer applies (the composite
        uses the soft visibility until ``set_refined_visibility`` is called again)."""
        if self._refined:
            self._refined = False
            if self._visibility == "refined":
                self._dirty_composite = True

    @property
    def refined_current(self) -> bool:
        """Whether the refined visibility of the current lights has been set."""
        return self._refined

    @_in_context
    def set_refined_visibility(self, visibility: np.ndarray):
        """The shadow refinement network's visibility (N, H, W) of the current lights, shown in the
        'refined' mode until a light's direction or sigma changes (then the soft visibility is
        shown until it is set again). Values are clipped to [0, 1]; non-finite values refused."""
        vis = np.asarray(visibility, np.float32)
        h, w = self.scene.height, self.scene.width
        if vis.shape != (len(self._lights), h, w):
            raise ValueError(f"refined visibility must be ({len(self._lights)}, {h}, {w}), got {vis.shape}")
        if not np.all(np.isfinite(vis)):
            raise ValueError("refined visibility has NaN or Inf values")
        size = self.light_planes[0].size
        if not self.refined_planes or self.refined_planes[0].size != size:
            for t in self.refined_planes:
                t.release()
            self.refined_planes = [self._texture(size, 1) for _ in range(LIGHTS_PER_PASS)]
        x, y, bw, bh = self._mask_box
        for l, v in zip(self._lights, vis):
            tile = np.ascontiguousarray(np.clip(v[y:y + bh, x:x + bw], 0.0, 1.0))
            self.refined_planes[l.slot].write(tile.tobytes(), viewport=(l.tile[0], l.tile[1], bw, bh))
        self._refined = True
        if self._visibility == "refined":
            self._dirty_composite = True

    def set_components(self, diffuse: bool = True, specular: bool = True):
        """Show or leave out the diffuse and specular terms of the final image (composite only)."""
        components = (bool(diffuse), bool(specular))
        if components != self._components:
            self._components = components
            self._dirty_composite = True

    def set_view(self, view: str = "final", light: int = 0):
        """What the display image shows (``VIEWS``): the relit frame; the diffuse or specular shading
        alone; the albedo, normal, depth, specular or roughness map; or light ``light``'s shadow
        (its visibility under the current shadow mode, soft when no shadows are shown)."""
        if view not in VIEWS:
            raise ValueError(f"view must be one of {', '.join(VIEWS)}, got {view!r}")
        if view == "shadow" and not 0 <= light < len(self._lights):
            raise ValueError(f"no light {light}: there are {len(self._lights)}")
        new = (view, int(light) if view == "shadow" else 0)
        if new != self._view:
            terms = self._composite_terms()
            self._view = new
            if self._composite_terms() != terms:
                self._dirty_composite = True
            self._dirty_frame = self._dirty_display = self._dirty_background = True

    def _composite_terms(self) -> tuple[float, float, bool]:
        """(diffuse weight, specular weight, unit albedo) of the composite: the shading views show
        one term; every other view keeps the relit image (the HDR output) as the switches say."""
        view = self._view[0]
        if view == "diffuse_shading":
            return 1.0, 0.0, True
        if view == "specular_shading":
            return 0.0, 1.0, False
        return float(self._components[0]), float(self._components[1]), False

    def set_display(self, exposure: float | None = None, tonemap: str | None = None, background: str | None = None,
                    color=None, environment_rotation=None):
        """Display settings; only the display pass is redone."""
        st = self._display_state
        if tonemap is not None and tonemap not in TONEMAPS:
            raise ValueError(f"tone map must be one of {', '.join(TONEMAPS)}, got {tonemap!r}")
        if background is not None and background not in BACKGROUNDS:
            raise ValueError(f"background must be one of {', '.join(BACKGROUNDS)}, got {background!r}")
        if background == "photo" and self.scene.background is None and self.frame_pass is None:
            raise ValueError("this scene bundle has no background image (background.png)")
        for key, value in (("exposure", exposure), ("tonemap", tonemap), ("background", background), ("color", color),
                           ("rotation", environment_rotation)):
            if value is not None:
                if key == "exposure" and not (np.isfinite(value) and abs(value) <= 40):
                    raise InputError(None, f"exposure must be within [-40, 40] stops, got {value}")
                if key in ("color", "rotation"):
                    value = np.array(value, dtype=np.float64)
                    if np.array_equal(value, st[key]):
                        continue
                elif value == st[key]:
                    continue
                st[key] = value
                self._dirty_display = True
                self._dirty_background = True
                if key in ("background", "color", "rotation"):
                    self._dirty_frame_background = True

    @_in_context
    def set_environment(self, pixels: np.ndarray):
        """Upload an equirectangular map (H, W, 3) linear RGB for the 'environment' background."""
        pixels = np.asarray(pixels, dtype=np.float32)
        h, w = pixels.shape[:2]
        self.tex_environment.release()
        data = np.dstack([pixels, np.ones((h, w), np.float32)]).astype("f4")
        self.tex_environment = self._texture((w, h), 4, data.tobytes(), linear=True, repeat=True)
        self._dirty_display = True
        self._dirty_background = True
        self._dirty_frame_background = True

    # ------------------------------------------------------------------ passes
    def _release_light(self, l: _Light):
        for res in [l.shadow_fbo, l.shadow_map] + [r for entry in l.work.values() for r in reversed(entry)]:
            if res is not None:
                res.release()
        l.work.clear()

    def _allocate_light_atlas(self):
        """The light atlas: LIGHTS_PER_PASS RGBA32F planes holding every light's (V_soft, V_hard,
        S_diff, S_spec) over the mask's bounding box; light i is in plane i % 4, in the tile of its
        group i // 4 (a few textures to bind in the composite, four lights per light pass)."""
        _, _, bw, bh = self._mask_box
        n = max((len(self._lights) + LIGHTS_PER_PASS - 1) // LIGHTS_PER_PASS, 1)  # groups
        cols = min(max(int(np.ceil(np.sqrt(n * bh / bw))), 1), n)
        rows = int(np.ceil(n / cols))
        size = (cols * bw, rows * bh)
        if max(size) > self._max_texture:
            raise InputError(self.scene.source, f"{len(self._lights)} lights over a {bw}x{bh} mask box need {size[0]}x{size[1]} "
                             f"light-atlas planes, above this GL's texture limit {self._max_texture}")
        self._release_light_atlas()
        self._drop_refined()
        self.light_planes = [self._texture(size, 4) for _ in range(LIGHTS_PER_PASS)]
        self.light_atlas_fbo = self.ctx.framebuffer(color_attachments=self.light_planes)
        self.light_atlas_fbo.clear(0.0, 0.0, 0.0, 0.0)
        for i, l in enumerate(self._lights):
            g = i // LIGHTS_PER_PASS
            l.tile = ((g % cols) * bw, (g // cols) * bh)
            l.slot = i % LIGHTS_PER_PASS

    def _release_light_atlas(self):
        for res in [getattr(self, "light_atlas_fbo", None), *getattr(self, "light_planes", [])]:
            if res is not None:
                res.release()
        self.light_planes = []
        self.light_atlas_fbo = None

    def _needed_pass(self, l: _Light) -> int:
        """The light-pass mode the current visibility and view need for this light: no shadow map
        when no shadows are shown, no filtering unless the soft visibility is shown."""
        if not l.active:
            return _PASS_OFF
        visibility = self._visibility
        if visibility == "none" and self._view[0] == "shadow" and self._lights[self._view[1]] is l:
            visibility = "soft"  # the shadow view shows the inspected light's soft visibility then
        if visibility == "none":
            return _PASS_UNSHADOWED
        if visibility == "hard" or self._soft_is_hard(l):
            return _PASS_HARD
        return _PASS_SOFT  # soft, and refined (whose network reads the hard and soft visibility)

    def _soft_is_hard(self, l: _Light) -> bool:
        """sigma ~ 0: the light's soft visibility is its hard one and its filtering is skipped."""
        return self.options.leave_out and l.sigma < self.options.hard_sigma

    def _ensure_light_resources(self, l: _Light):
        if l.shadow_map is None:
            r = self.options.shadow_resolution
            l.shadow_map = self._texture((r, r), 1)
            l.shadow_fbo = self.ctx.framebuffer(color_attachments=[l.shadow_map], depth_attachment=self._shadow_depth)

    def _render_shadow_map(self, l: _Light):
        with self._timed("shadow_map"):
            fbo = l.shadow_fbo
            fbo.use()
            fbo.clear(l.frame.empty_depth, 0.0, 0.0, 0.0, depth=1.0)
            if self._shadow_vao is not None:
                prog = self._shadow_vao.program
                prog["light_frame"].write(l.frame.matrix().T.astype("f4").tobytes())
                self.ctx.enable(moderngl.DEPTH_TEST)
                self.ctx.disable(moderngl.CULL_FACE)
                self._shadow_vao.render(moderngl.TRIANGLES)
                self.ctx.disable(moderngl.DEPTH_TEST)

    def _work_atlas(self, l: _Light, size, slot: str):
        """A light's own intermediate atlas (kept per light so that every stage can run for all
        lights before the next stage starts: llvmpipe then waits once per stage, not per pass)."""
        entry = l.work.get(slot)
        if entry is None or entry[0].size != tuple(size):
            if entry is not None:
                entry[1].release()
                entry[0].release()
            tex = self._texture(size, 4, linear=(slot == "filtered"))
            entry = l.work[slot] = (tex, self.ctx.framebuffer(color_attachments=[tex]))
        return entry

    def _csm_basis(self, l: _Light):
        """Basis atlas of the light's shadow map at its blur plan's mip level L (box averages of
        2^L x 2^L texel blocks: computed directly up to level 3, deeper levels by a box_reduce pass)."""
        o = self.options
        r = o.shadow_resolution
        plan = l.plan = blur_plan(ss.sigma_in_pixels(l.sigma, r), r, o.prefilter)
        n = max(r >> plan.level, 1)
        staged = min(plan.level, BASIS_MAX_BLOCK_LEVEL)
        n_staged = max(r >> staged, 1)
        tex, fbo = self._work_atlas(l, (n_staged * self._n_tex, n_staged), "basis")
        with self._timed("csm_basis"):
            prog = self.programs.get("fullscreen.vert.glsl", "csm_basis.frag.glsl", TERMS=o.terms)
            l.shadow_map.use(0)
            prog["shadow_map"] = 0
            prog["block"] = 1 << staged
            prog["tile_size"] = n_staged
            prog["empty_depth"] = l.frame.empty_depth
            self._footprint_pass(l, fbo, n_staged, 1, prog, cheap_texels=False)  # block x block reads each
            if staged < plan.level:
                _, reduced_fbo = self._work_atlas(l, (n * self._n_tex, n), "reduced")
                reduce = self.programs.get("fullscreen.vert.glsl", "box_reduce.frag.glsl")
                tex.use(0)
                reduce["source"] = 0
                reduce["factor"] = 1 << (plan.level - staged)
                self._footprint_pass(l, reduced_fbo, n, 1, reduce)

    def _blur(self, l: _Light, axis):
        """One separable Gaussian pass: basis -> "temp" (horizontal) or "temp" -> "filtered"."""
        plan = l.plan
        n = max(self.options.shadow_resolution >> plan.level, 1)
        size = (n * self._n_tex, n)
        if axis == (1, 0):
            source = l.work["reduced" if plan.level > BASIS_MAX_BLOCK_LEVEL else "basis"][0]
            _, target = self._work_atlas(l, size, "temp")
        else:
            source = l.work["temp"][0]
            l.filtered, target = self._work_atlas(l, size, "filtered")
        prog = self.programs.get("fullscreen.vert.glsl", "gaussian_blur.frag.glsl")
        with self._timed("prefilter", count=axis == (1, 0)):  # counted once per light
            prog["radius"] = plan.radius
            prog["sigma"] = plan.sigma
            prog["norm"] = plan.norm
            prog["tile_size"] = n
            prog["source"] = 0
            prog["axis"] = axis
            source.use(0)
            self._footprint_pass(l, target, n, plan.radius + 1, prog)

    def _footprint_pass(self, l: _Light, fbo: moderngl.Framebuffer, n: int, margin: int, prog: moderngl.Program,
                        cheap_texels: bool = True):
        """Run a basis-atlas pass only over the mesh's footprint in the shadow map (plus ``margin``
        texels) in each tile; the rest of the tile holds the basis of an empty texel, a constant,
        which every later pass (box average, Gaussian) leaves unchanged. Small atlases of cheap
        texels are drawn whole in one draw instead (per-draw overhead dominates there)."""
        if cheap_texels and n <= SMALL_ATLAS_TILE:
            fbo.scissor = None
            fbo.use()
            self._fullscreen(prog)
            return
        u0, v0, u1, v1 = l.frame.footprint
        x0, y0 = max(int(np.floor(u0 * n)) - margin, 0), max(int(np.floor(v0 * n)) - margin, 0)
        x1, y1 = min(int(np.ceil(u1 * n)) + margin, n), min(int(np.ceil(v1 * n)) + margin, n)
        empty = ss.csm_empty_basis(l.frame.empty_depth, self.options.terms)
        fbo.scissor = None
        fbo.use()
        for t in range(self._n_tex):
            fbo.clear(*empty[t], viewport=(t * n, 0, n, n))
        if x1 > x0 and y1 > y0:
            for t in range(self._n_tex):
                fbo.scissor = (t * n + x0, y0, x1 - x0, y1 - y0)
                fbo.use()
                self._fullscreen(prog)
        fbo.scissor = None

    def _light_pass(self, group: list, modes: list):
        """One light pass for up to four lights of a group; ``modes`` per slot: 0 no light (or a
        skipped one), 1 hard visibility only (sigma ~ 0), 2 hard and CSM."""
        o = self.options
        defines = {"TERMS": o.terms}
        if self._specular:
            defines["SPECULAR"] = None
        prog = self.programs.get("fullscreen.vert.glsl", "light_pass.frag.glsl", **defines)
        with self._timed("light_pass"):
            self.tex_positions.use(0)
            self.tex_normals.use(1)
            prog["positions"] = 0
            prog["normals"] = 1
            frames = np.zeros((LIGHTS_PER_PASS, 4, 4), "f4")
            dirs = np.zeros((LIGHTS_PER_PASS, 3), "f4")
            scales = np.ones(LIGHTS_PER_PASS, "f4")
            fallback = self.tex_positions  # any texture: slots without a light never read it
            for j in range(LIGHTS_PER_PASS):
                l = group[j] if j < len(group) else None
                used = l is not None and modes[j] in (_PASS_HARD, _PASS_SOFT)
                (l.shadow_map if used else fallback).use(2 + j)
                (l.filtered if used and modes[j] == _PASS_SOFT else fallback).use(6 + j)
                prog[f"shadow_map{j}"] = 2 + j
                prog[f"filtered_basis{j}"] = 6 + j
                if used:
                    frames[j] = l.frame.matrix().T
                    scales[j] = l.frame.depth_scale()
                if l is not None:
                    dirs[j] = l.frame.direction
            prog["light_frame"].write(frames.tobytes())
            prog["light_dir"].write(dirs.tobytes())
            prog["depth_scale"].write(scales.tobytes())
            prog["light_mode"].write(np.array(list(modes) + [0] * (LIGHTS_PER_PASS - len(modes)), "i4").tobytes())
            prog["texel_world"] = group[0].frame.texel_world(o.shadow_resolution)
            prog["hard_threshold"] = ss.HARD_SHADOW_THRESHOLD
            prog["normal_offset_texels"] = ss.NORMAL_OFFSET_TEXELS
            prog["slope_bias_texels"] = ss.SLOPE_BIAS_TEXELS
            prog["max_slope"] = ss.MAX_SLOPE
            prog["csm_offset"] = self.csm_offset
            prog["csm_clamp"] = self.csm_clamp
            x, y, bw, bh = self._mask_box
            prog["tile_origin"] = group[0].tile
            prog["box_origin"] = (x, y)
            fbo = self.light_atlas_fbo
            fbo.viewport = fbo.scissor = (group[0].tile[0], group[0].tile[1], bw, bh)
            fbo.use()
            self._fullscreen(prog)

    def _composite(self):
        defines = {"MAX_LIGHTS": MAX_LIGHTS_PER_COMPOSITE}
        if self.frame_pass is not None:
            defines["FRAME_SHADING"] = None
        prog = self.programs.get("fullscreen.vert.glsl", "composite.frag.glsl", **defines)
        with self._timed("composite"):
            x, y, _, _ = self._mask_box
            self.hdr_fbo.scissor = self._mask_box  # outside the box the HDR stays cleared to zero
            self.hdr_fbo.use()
            self.tex_albedo.use(0)
            prog["albedo_mask"] = 0
            for j, plane in enumerate(self.light_planes):
                plane.use(1 + j)
                prog[f"light_plane{j}"] = 1 + j
            prog["box_origin"] = (x, y)
            mode = self._visibility
            if mode == "refined":
                if self._refined:
                    for j, plane in enumerate(self.refined_planes):
                        plane.use(1 + LIGHTS_PER_PASS + j)
                        prog[f"refined_plane{j}"] = 1 + LIGHTS_PER_PASS + j
                else:
                    mode = "soft"  # until the refinement of these lights arrives
            prog["visibility_channel"] = VISIBILITY_MODES[mode]
            diffuse, specular, unit_albedo = self._composite_terms()
            prog["term_weights"] = (diffuse, specular)
            prog["unit_albedo"] = unit_albedo
            k = MAX_LIGHTS_PER_COMPOSITE
            chunks = [self._lights[i:i + k] for i in range(0, len(self._lights), k)]
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
                    self.ctx.disable(moderngl.BLEND)
                else:
                    self.ctx.enable(moderngl.BLEND)
                    self.ctx.blend_func = moderngl.ONE, moderngl.ONE
                self._fullscreen(prog)
            self.ctx.disable(moderngl.BLEND)

    def _display(self):
        if self._view[0] in _INSPECT_VIEWS:
            self._inspect()
            return
        fp = self.frame_pass
        if fp is None:
            with self._timed("display"):
                box = None if self._dirty_background else self._mask_box  # only the foreground changed
                self._draw_display(self.display_fbo, self.hdr, self.tex_background, self.scene.camera, box)
            return
        self._frame_ready()
        with self._timed("frame_composite"):
            box = None if self._dirty_background else fp.box  # only the foreground changed
            fp.draw(fp.display_fbo, self.shading_targets, self._composite_terms(), self._display_state, TONEMAPS, box=box)

    def _draw_display(self, fbo, hdr, background_image, cam, box, hdr_output: bool = False):
        """The display shader over ``fbo`` (``box`` = (x, y, w, h) to redraw only that part)."""
        st = self._display_state
        prog = self.programs.get("fullscreen.vert.glsl", "display.frag.glsl", **({"HDR_OUTPUT": None} if hdr_output else {}))
        fbo.scissor = box
        fbo.use()
        hdr.use(0)
        background_image.use(1)
        self.tex_environment.use(2)
        prog["hdr"] = 0
        prog["background_image"] = 1
        prog["environment"] = 2
        prog["background_mode"] = BACKGROUNDS[st["background"]]
        prog["background_color"] = tuple(float(c) for c in st["color"])
        prog["environment_rotation"].write(np.asarray(st["rotation"], dtype="f4").T.tobytes())
        prog["focal_center_px"] = cam.center
        prog["focal_px"] = cam.focal_px
        if not hdr_output:
            prog["exposure"] = float(st["exposure"])
            prog["tonemap_op"] = TONEMAPS[st["tonemap"]]
        self._fullscreen(prog)
        fbo.scissor = None

    def _inspect(self):
        view, index = self._view
        prog = self.programs.get("fullscreen.vert.glsl", "inspect.frag.glsl")
        fbo = self.display_fbo if self.frame_pass is None else self.frame_pass.display_fbo  # the display's size stays
        with self._timed("display"):
            fbo.scissor = None
            fbo.use()
            prog["display_to_work"] = (self.scene.width / fbo.size[0], self.scene.height / fbo.size[1])
            for unit, (name, tex) in enumerate((("positions", self.tex_positions), ("normals", self.tex_normals),
                                                ("albedo_mask", self.tex_albedo))):
                tex.use(unit)
                prog[name] = unit
            light = self._lights[index] if view == "shadow" else None
            (self.light_planes[light.slot] if light is not None else self.tex_albedo).use(3)
            prog["light_plane"] = 3
            prog["light_valid"] = light is not None and light.active and light.pass_mode != _PASS_OFF
            prog["tile_origin"] = light.tile if light is not None else (0, 0)
            prog["box_origin"] = self._mask_box[:2]
            prog["visibility_channel"] = 1 if self._visibility == "hard" else 0
            prog["view"] = _INSPECT_VIEWS[view]
            prog["depth_range"] = self._depth_range
            prog["background_color"] = (0.1, 0.1, 0.1)
            self._fullscreen(prog)

    @_in_context
    def render(self) -> "Engine":
        """Bring every output up to date, redoing only the passes whose inputs changed."""
        if not self._lights:
            raise ValueError("no lights: call set_lights first")
        active = [l for l in self._lights if l.active]  # inactive lights stay dirty until they count
        need = {id(l): self._needed_pass(l) for l in self._lights}
        if self._visibility == "none":  # the composite ignores visibility: any computed pass will do
            for l in self._lights:
                if need[id(l)] == _PASS_UNSHADOWED and l.pass_mode != _PASS_OFF and not l.dirty_shading:
                    need[id(l)] = l.pass_mode
        # Stage by stage over all lights: each stage only waits for the previous one once.
        for l in active:
            if l.dirty_shadow and need[id(l)] in (_PASS_HARD, _PASS_SOFT):
                self._ensure_light_resources(l)
                self._render_shadow_map(l)
                l.dirty_shadow = False
                l.dirty_filter = l.dirty_shading = True
        to_filter = [l for l in active if l.dirty_filter and need[id(l)] == _PASS_SOFT]
        for l in to_filter:
            self._csm_basis(l)
        for axis in ((1, 0), (0, 1)):
            for l in to_filter:
                self._blur(l, axis)
        for l in to_filter:
            l.dirty_filter, l.dirty_shading = False, True
        for g in range(0, len(self._lights), LIGHTS_PER_PASS):
            group = self._lights[g:g + LIGHTS_PER_PASS]
            if not any(l.active and (l.dirty_shading or l.pass_mode != need[id(l)]) for l in group):
                continue
            # the whole group is redone; a skipped light's slot is zeroed, so it is redone when it counts again
            self._light_pass(group, [need[id(l)] for l in group])
            for l in group:
                l.dirty_shading = not l.active
                l.pass_mode = need[id(l)]
            self._dirty_composite = True
        if self._dirty_composite:
            self._composite()
            self._dirty_composite = False
            self._dirty_display = self._dirty_frame = True
        if self._dirty_display:
            self._display()
            self._dirty_display = False
            self._dirty_background = False
        return self

    # ------------------------------------------------------------------ outputs
    def _read(self, tex: moderngl.Texture, components: int, dtype="f4") -> np.ndarray:
        w, h = tex.size
        arr = np.frombuffer(tex.read(), dtype=np.float32 if dtype == "f4" else np.uint8)
        return arr.reshape(h, w, components).copy()

    @property
    def display(self) -> moderngl.Texture:
        """The display image shown and saved: at the output frame's resolution for a scene with a
        frame layer (the inspection views too), else at the maps'."""
        if self.frame_pass is not None:
            return self.frame_pass.display
        return self.work_display

    @property
    def output_size(self) -> tuple[int, int]:
        """(width, height) of :attr:`display` and :meth:`read_hdr`."""
        return self.display.size

    @_in_context
    def read_hdr(self) -> np.ndarray:
        """(H, W, 3) float32 linear HDR of the person (zero outside), at the output size, row 0 at
        the top."""
        return self.read_hdr_rgba()[..., :3]

    @_in_context
    def read_hdr_rgba(self) -> np.ndarray:
        """(H, W, 4): the person's linear HDR and its coverage (the mask, or the frame's matte)."""
        if self.frame_pass is None:
            return self._read(self.hdr, 4)
        self._frame_ready()
        return self.frame_pass.read(self.shading_targets, self._composite_terms(), self._display_state, TONEMAPS, OUTPUT_PERSON_HDR)

    @_in_context
    def read_frame_shading(self) -> tuple[np.ndarray, np.ndarray]:
        """The diffuse and specular shading sums (sum_l V_l I_l S_diff_l and sum_l V_l I_l S_spec_l),
        (H, W, 3) each at the output frame's resolution, upsampled exactly as the frame composite
        upsamples them (a scene with a frame layer; after render())."""
        if self.frame_pass is None:
            raise ValueError("the scene has no frame layer")
        self._frame_ready()
        fp, st = self.frame_pass, self._display_state
        diffuse = fp.read(self.shading_targets, (1.0, 0.0, True), st, TONEMAPS, OUTPUT_PERSON_HDR)[..., :3]
        specular = fp.read(self.shading_targets, (0.0, 1.0, False), st, TONEMAPS, OUTPUT_PERSON_HDR)[..., :3]
        return diffuse, specular

    def _frame_ready(self):
        """The frame composite's inputs up to date: the shading sums' mipmaps and the background."""
        if self._dirty_frame_background:
            with self._timed("frame_background"):
                self.frame_pass.draw_background(self._display_state, BACKGROUNDS, self.tex_environment)
            self._dirty_frame_background = False
        if self._dirty_frame:
            with self._timed("frame_mipmaps"):
                for tex in self.shading_targets:
                    tex.build_mipmaps(0, MAX_FILL_LOD)
            self._dirty_frame = False

    @_in_context
    def read_work_hdr(self) -> np.ndarray:
        """(H, W, 3) linear HDR at the maps' (work) resolution."""
        return self._read(self.hdr, 4)[..., :3]

    @_in_context
    def read_display(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB display image."""
        return self._read(self.display, 4, dtype="f1")[..., :3]

    @_in_context
    def read_display_rgba(self) -> np.ndarray:
        """(H, W, 4) uint8: the display image and its alpha (the coverage for the transparent
        background, 255 otherwise)."""
        return self._read(self.display, 4, dtype="f1")

    @_in_context
    def read_output_hdr(self) -> np.ndarray:
        """(H, W, 4) float32: the display image's linear HDR before exposure and tone map, over
        the same background (alpha 1), or premultiplied with its coverage for the transparent
        background: the EXR that goes with the display PNG."""
        fp = self.frame_pass
        if fp is not None:
            self._frame_ready()
            return fp.read(self.shading_targets, self._composite_terms(), self._display_state, TONEMAPS, OUTPUT_COMPOSITED_HDR)
        tex = self._texture(self.hdr.size, 4)
        fbo = self.ctx.framebuffer(color_attachments=[tex])
        try:
            self._draw_display(fbo, self.hdr, self.tex_background, self.scene.camera, None, hdr_output=True)
            return self._read(tex, 4)
        finally:
            fbo.release()
            tex.release()

    @_in_context
    def read_light(self, index: int) -> dict:
        """Per-light intermediate outputs (H, W) each: soft and hard visibility, diffuse and
        specular shading per unit intensity. All zero for a skipped light and outside the mask."""
        l = self._lights[index]
        h, w = self.scene.height, self.scene.width
        full = np.zeros((h, w, 4), np.float32)
        if l.active and l.pass_mode != _PASS_OFF:
            x, y, bw, bh = self._mask_box
            data = self.light_atlas_fbo.read(viewport=(l.tile[0], l.tile[1], bw, bh), components=4, dtype="f4",
                                             attachment=l.slot)
            full[y:y + bh, x:x + bw] = np.frombuffer(data, np.float32).reshape(bh, bw, 4)
        return {"visibility_soft": full[..., 0], "visibility_hard": full[..., 1], "diffuse": full[..., 2], "specular": full[..., 3]}

    @_in_context
    def read_shadow_map(self, index: int) -> np.ndarray:
        """(R, R) normalised depth of a light's shadow map, row 0 at v = 0."""
        l = self._lights[index]
        if not l.active or l.shadow_map is None or l.dirty_shadow:
            raise ValueError(f"light {index} contributes nothing, so it has no current shadow map")
        return self._read(l.shadow_map, 1)[..., 0]

    @_in_context
    def read_filtered_basis(self, index: int) -> np.ndarray:
        """A light's pre-filtered CSM basis, (2 M, n, n): cos and sin of c_k z for k = 0 .. M-1, at
        the blur plan's mip level (n = shadow resolution / 2^L). Raises for a light whose soft
        visibility is its hard one (sigma ~ 0) or that contributes nothing."""
        l = self._lights[index]
        if not l.active or l.filtered is None or l.dirty_filter or l.dirty_shadow or l.plan is None or self._soft_is_hard(l):
            raise ValueError(f"light {index} has no current filtered basis (skipped, or sigma ~ 0)")
        atlas = self._read(l.filtered, 4)  # (n, tiles * n, 4)
        n = atlas.shape[0]
        tiles = [atlas[:, t * n:(t + 1) * n] for t in range(self._n_tex)]
        maps = [tile[..., c] for tile in tiles for c in range(4)]
        return np.stack(maps[:2 * self.options.terms])

    def light_active(self, index: int) -> bool:
        return self._lights[index].active

    @_in_context
    def release(self):
        """Free every GL object the engine created (the context stays)."""
        for l in self._lights:
            self._release_light(l)
        self._lights = []
        self._release_light_atlas()
        for t in self.refined_planes:
            t.release()
        self.refined_planes = []
        if self.frame_pass is not None:
            self.frame_pass.release()
            self.frame_pass = None
        objects = [getattr(self, name, None) for name in (
            "hdr_fbo", "hdr", "display_fbo", "work_display", "tex_positions",
            "tex_normals", "tex_albedo", "tex_background", "tex_environment", "_shadow_vao", "_mesh_vbo",
            "_mesh_ibo", "_shadow_depth")]
        objects += list(getattr(self, "shading_targets", [])) + list(self._fullscreen_vaos.values())
        self._fullscreen_vaos.clear()
        for obj in objects:
            if obj is not None:
                obj.release()
