"""4. The light pass (light_pass.frag.glsl): at every camera pixel of the mask's box, four lights at
once, each light's soft visibility (CSM, or contact-hardening soft shadows), hard visibility (shadow test), and Lambert and Disney
specular shading per unit intensity, into the light atlas. Also the refined visibility the
refinement network gives for the same lights (the 'refined' shadow mode), kept beside the atlas."""

from __future__ import annotations

import numpy as np

from viewer.errors import InputError
from viewer.gl.kit import PassKit, band_box
from viewer.gl.light import PASS_HARD, PASS_OFF, PASS_SOFT, Light
from viewer.gl.scene_resources import SceneResources
from viewer.gl.soft import soft_method
from viewer.gl.work_budget import draw_bands
from viewer.scene import shadow_space as ss

LIGHTS_PER_PASS = 4  # lights per light pass (one light-atlas plane each)
BANDS = 4  # a budgeted light pass's bands of rows (Engine.render with a budget)


class LightAtlas:
    """LIGHTS_PER_PASS RGBA32F planes holding every light's (V_soft, V_hard, S_diff, S_spec) over
    the mask's bounding box; light i is in plane i % 4, in the tile of its group i // 4 (a few
    textures to bind in the composite, four lights per light pass). Sized for the light count."""

    def __init__(self, kit: PassKit, mask_box, max_texture: int, source):
        self.kit, self.mask_box, self.max_texture, self.source = kit, mask_box, max_texture, source
        self.planes: list = []
        self.fbo = None

    def allocate(self, lights: list[Light]):
        _, _, bw, bh = self.mask_box
        n = max((len(lights) + LIGHTS_PER_PASS - 1) // LIGHTS_PER_PASS, 1)  # groups
        cols = min(max(int(np.ceil(np.sqrt(n * bh / bw))), 1), n)
        rows = int(np.ceil(n / cols))
        size = (cols * bw, rows * bh)
        if max(size) > self.max_texture:
            raise InputError(self.source, f"{len(lights)} lights over a {bw}x{bh} mask box need {size[0]}x{size[1]} "
                             f"light-atlas planes, above this GL's texture limit {self.max_texture}")
        self.release()
        self.planes = [self.kit.texture(size, 4) for _ in range(LIGHTS_PER_PASS)]
        self.fbo = self.kit.ctx.framebuffer(color_attachments=self.planes)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0)
        for i, l in enumerate(lights):
            g = i // LIGHTS_PER_PASS
            l.tile = ((g % cols) * bw, (g // cols) * bh)
            l.slot = i % LIGHTS_PER_PASS

    def read_tile(self, l: Light) -> np.ndarray:
        """(h, w, 4) of one light over the mask's box."""
        _, _, bw, bh = self.mask_box
        data = self.fbo.read(viewport=(l.tile[0], l.tile[1], bw, bh), components=4, dtype="f4", attachment=l.slot)
        return np.frombuffer(data, np.float32).reshape(bh, bw, 4)

    def release(self):
        for res in [self.fbo, *self.planes]:
            if res is not None:
                res.release()
        self.planes = []
        self.fbo = None


class RefinedVisibility:
    """The refinement network's visibility of the current lights, one plane per light-atlas plane
    at the same tiles (what the composite reads in the 'refined' mode). ``current`` is False
    once a light's direction or sigma changed."""

    def __init__(self, kit: PassKit, mask_box):
        self.kit, self.mask_box = kit, mask_box
        self.planes: list = []
        self.current = False

    def set(self, lights: list[Light], visibility: np.ndarray, shape: tuple[int, int], size):
        """The network's visibility (N, H, W) of ``lights`` over the maps' ``shape`` (H, W), written
        into planes of the light atlas's ``size``; values clipped to [0, 1], non-finite refused."""
        vis = np.asarray(visibility, np.float32)
        if vis.shape != (len(lights), *shape):
            raise ValueError(f"refined visibility must be ({len(lights)}, {shape[0]}, {shape[1]}), got {vis.shape}")
        if not np.all(np.isfinite(vis)):
            raise ValueError("refined visibility has NaN or Inf values")
        if not self.planes or self.planes[0].size != size:
            self.release()
            self.planes = [self.kit.texture(size, 1) for _ in range(LIGHTS_PER_PASS)]
        x, y, bw, bh = self.mask_box
        for l, v in zip(lights, vis):
            tile = np.ascontiguousarray(np.clip(v[y:y + bh, x:x + bw], 0.0, 1.0))
            self.planes[l.slot].write(tile.tobytes(), viewport=(l.tile[0], l.tile[1], bw, bh))
        self.current = True

    def release(self):
        for t in self.planes:
            t.release()
        self.planes = []


class LightShadingPass:
    """One light pass per group of four lights; a light's ``pass_mode`` says what its slot holds
    (PASS_OFF nothing, PASS_HARD hard visibility only, PASS_SOFT hard and soft, PASS_UNSHADOWED unit
    visibility: viewer.shader_modes)."""

    name = "light_pass"

    def __init__(self, kit: PassKit, scene: SceneResources, atlas: LightAtlas, resolution: int, terms: int, specular: bool,
                 soft: str = "csm", pcss_min_texels: float = ss.PCSS_MIN_TEXELS):
        self.kit, self.scene, self.atlas = kit, scene, atlas
        self.resolution, self.terms, self.specular, self.soft = resolution, terms, specular, soft_method(soft)
        self.pcss_min_texels = pcss_min_texels
        self._next = None  # (the group's state, band): a budgeted pass left part-way
        self.csm_offset, self.csm_clamp = ss.csm_constants(terms)
        # and the mode the shown visibility needs (Engine._needed_pass); sigma reaches it through
        # the CSM's pre-filtered basis, or directly: the contact-hardening penumbrae and, with
        # specular, the light's angular size widening its lobe (brdf.glsl's widened_alpha)
        self.inputs = ("direction", "shadow_map", *self.soft.reads)
        if specular and "sigma" not in self.inputs:
            self.inputs += ("sigma",)
        # the contact-hardening taps (unit Gaussian offsets), the same for every pass
        self.pcss_taps = ss.pcss_taps(ss.PCSS_TAPS).astype("f4").tobytes()
        self.pcss_search_taps = ss.pcss_taps(ss.PCSS_SEARCH_TAPS).astype("f4").tobytes()
        # what a slot with no shadow map (or no pre-filtered basis) binds: a texture llvmpipe samples
        # the way it samples the real ones (the same format, filter and power-of-two sides: its shader
        # variants are keyed on them). Any other texture there makes a new variant the first time a
        # light goes out mid-drag, 0.6-1.5 s of compiling (docs/viewer.md, "Stalls found").
        self.stand_in_shadow_map = kit.texture((1, 1), 1, np.ones(1, "f4").tobytes())
        n_tex = (terms + 1) // 2  # the pre-filtered atlas's width is n_tex tiles of a power of two
        self.stand_in_filtered = kit.texture((n_tex, 1), 4, np.zeros(4 * n_tex, "f4").tobytes(), linear=True)

    @property
    def defines(self) -> dict:
        """The shader defines of the soft-shadow method this engine uses (shared with the ground shadow pass)."""
        return self.soft.defines(self)

    @property
    def sources(self) -> dict:
        """The soft-shadow method's GLSL, as the ``soft_method.glsl`` light_visibility.glsl includes."""
        return {"soft_method.glsl": self.soft.glsl()}

    def bind_lights(self, prog, group: list[Light], modes: list[int]):
        """light_visibility.glsl's uniforms and textures for a group of up to four lights (shadow
        maps on units 2-5, CSM bases on 6-9; the stand-ins in slots that never read theirs)."""
        frames = np.zeros((LIGHTS_PER_PASS, 4, 4), "f4")
        dirs = np.zeros((LIGHTS_PER_PASS, 3), "f4")
        scales = np.ones(LIGHTS_PER_PASS, "f4")
        alphas = np.zeros(LIGHTS_PER_PASS, "f4")
        for j in range(LIGHTS_PER_PASS):
            l = group[j] if j < len(group) else None
            used = l is not None and modes[j] in (PASS_HARD, PASS_SOFT)
            (l.shadow_map if used else self.stand_in_shadow_map).use(2 + j)
            prog[f"shadow_map{j}"] = 2 + j
            soft = used and modes[j] == PASS_SOFT
            if self.soft.prefiltered:
                (l.filtered if soft else self.stand_in_filtered).use(6 + j)
                prog[f"filtered_basis{j}"] = 6 + j
            if used:
                frames[j] = l.frame.matrix.T
                scales[j] = l.frame.depth_scale()
            if l is not None:
                dirs[j] = l.frame.direction
                alphas[j] = l.sigma * ss.ANGULAR_SIGMA
        prog["light_frame"].write(frames.tobytes())
        prog["light_dir"].write(dirs.tobytes())
        prog["depth_scale"].write(scales.tobytes())
        prog["light_mode"].write(np.array(list(modes) + [PASS_OFF] * (LIGHTS_PER_PASS - len(modes)), "i4").tobytes())
        prog["texel_world"] = group[0].frame.texel_world(self.resolution)
        prog["hard_threshold"] = ss.HARD_SHADOW_THRESHOLD
        prog["normal_offset_texels"] = ss.NORMAL_OFFSET_TEXELS
        prog["slope_bias_texels"] = ss.SLOPE_BIAS_TEXELS
        prog["max_slope"] = ss.MAX_SLOPE
        prog["empty_depth"] = group[0].frame.empty_depth
        if "light_alpha" in prog:  # absent when neither PCSS nor the specular code reads it
            prog["light_alpha"].write(alphas.tobytes())
        self.soft.bind(self, prog, group)

    def run(self, group: list[Light], modes: list[int], work=None) -> bool:
        """Shade the group's lights into its atlas tile. With ``work`` (a budgeted render,
        :class:`viewer.gl.work_budget.WorkBudget`) in ``BANDS`` bands of the mask box's rows, one unit
        each (a group at 2048 pixels is ~75 ms idle and twice that beside a busy process, too long for
        one frame of a window opening a map): False when the budget ran out first (the bands drawn are
        kept; the next call goes on from the next band if it is for the same group in the same state:
        its lights, their directions, sizes and modes; anything else, an exposure say, keeps them)."""
        kit, sc = self.kit, self.scene
        tile = group[0].tile
        key = (tile, tuple(modes), tuple(id(l) for l in group), b"".join(l.direction.tobytes() for l in group),
               tuple(l.sigma for l in group))
        first = self._next[1] if work is not None and self._next is not None and self._next[0] == key else 0
        defines = self.defines
        if self.specular:
            defines["SPECULAR"] = None
        prog = kit.programs.get("fullscreen.vert.glsl", "light_pass.frag.glsl", self.sources, **defines)
        with kit.timed(self.name):
            sc.positions.use(0)
            sc.normals.use(1)
            prog["positions"] = 0
            prog["normals"] = 1
            self.bind_lights(prog, group, modes)
            x, y, bw, bh = sc.mask_box
            prog["tile_origin"] = tile
            prog["box_origin"] = (x, y)
            fbo = self.atlas.fbo
            fbo.viewport = (tile[0], tile[1], bw, bh)
            fbo.use()

            def draw(band):
                bx, by, bbw, bbh = band_box((bw, bh), band, BANDS) if band is not None else (0, 0, bw, bh)
                fbo.scissor = (tile[0] + bx, tile[1] + by, bbw, bbh)
                kit.fullscreen(prog)

            try:
                left = draw_bands(work, first, BANDS, "light_band", draw)
            finally:
                fbo.scissor = None  # the atlas's other users (its clear) see the whole of it
        self._next = None if left is None else (key, left)
        return left is None

    def release(self):
        self.stand_in_shadow_map.release()
        self.stand_in_filtered.release()
