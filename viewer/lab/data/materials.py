"""Procedural materials of the synthetic people: regions (skin, hair, eyes, garments, shoes) from
rest-pose fields, colours and patterns (stripes, noise) and Disney specular / roughness per region.
Patterns are functions of the rest-pose position, so they follow the body through any pose."""

from __future__ import annotations

import colorsys
from dataclasses import dataclass

import numpy as np

from viewer.files.imageio import srgb_to_linear


def value_noise(p: np.ndarray, scale: float, seed: int) -> np.ndarray:
    """Smooth 3D value noise in [-1, 1] at points p (..., 3), lattice spacing ``scale`` metres."""
    rng = np.random.default_rng(seed)
    table = rng.uniform(-1.0, 1.0, size=(64, 64, 64))
    q = p / scale + 32.0
    i = np.floor(q).astype(np.int64)
    fr = q - i
    fr = fr * fr * (3.0 - 2.0 * fr)
    out = np.zeros(p.shape[:-1])
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                wgt = (fr[..., 0] if dx else 1 - fr[..., 0]) * (fr[..., 1] if dy else 1 - fr[..., 1]) * (fr[..., 2] if dz else 1 - fr[...,
                                                                                                                                      2])
                out += wgt * table[(i[..., 0] + dx) % 64, (i[..., 1] + dy) % 64, (i[..., 2] + dz) % 64]
    return out


def fbm(p: np.ndarray, scale: float, seed: int, octaves: int = 3) -> np.ndarray:
    total, amp, norm = np.zeros(p.shape[:-1]), 1.0, 0.0
    for o in range(octaves):
        total += amp * value_noise(p, scale / 2**o, seed + o)
        norm += amp
        amp *= 0.5
    return total / norm


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


@dataclass(frozen=True)
class Garment:
    """A garment's look: base ``color`` (linear RGB), Disney ``specular`` and ``roughness``, and a
    pattern: ``solid``, ``stripes`` (horizontal, ``period`` metres, ``width`` of a period in the
    second colour), ``dots`` (a lattice of ``period``, dots of ``width`` x period radius) or
    ``blotches`` (noise of scale ``period``); ``noise``: amplitude of a low-frequency colour noise."""
    color: tuple
    specular: float
    roughness: float
    pattern: str = "solid"
    pattern_color: tuple = (0.0, 0.0, 0.0)
    period: float = 0.07
    width: float = 0.24
    noise: float = 0.05


@dataclass(frozen=True)
class Accessories:
    """What a person wears or carries besides the outfit (:mod:`viewer.lab.data.accessories` draws
    them and builds the bag's mesh). Colours are linear RGB; None: not worn."""
    bag: str | None = None  # "crossbody" (on the hip, its strap over the other shoulder) or "backpack"
    bag_side: float = 1.0  # crossbody: the hip it hangs at (+1 the body's left, -1 its right)
    bag_color: tuple = (0.05, 0.035, 0.025)
    bag_specular: float = 0.5
    bag_roughness: float = 0.4
    watch: tuple | None = None  # the band, on the left wrist
    necklace: tuple | None = None  # a thin metal chain
    cap: tuple | None = None  # a knit cap


@dataclass(frozen=True)
class Outfit:
    """Everything a person's materials depend on besides the geometry."""
    skin: tuple = (0.52, 0.33, 0.25)
    skin_specular: float = 0.5
    skin_roughness: float = 0.45
    hair: tuple = (0.08, 0.05, 0.035)
    hair_specular: float = 0.4
    hair_roughness: float = 0.35
    iris: tuple = (0.12, 0.07, 0.04)
    top: Garment = Garment((0.40, 0.11, 0.07), 0.3, 0.7, "stripes", (0.50, 0.45, 0.36), 0.07, 0.24, 0.05)
    bottom: Garment = Garment((0.075, 0.10, 0.17), 0.2, 0.85, noise=0.18)
    shoes: Garment = Garment((0.04, 0.04, 0.045), 0.5, 0.3, noise=0.1)
    sole: tuple = (0.45, 0.44, 0.42)
    belt: tuple | None = (0.07, 0.04, 0.025)  # None: no belt
    sleeve: float = 0.40  # where sleeves end along the arm: 0 shoulder, 0.5 elbow, 1 wrist (> 1: long)
    leg: float = 1.0  # how far the bottom reaches from the waist to the ankle (1: full length)
    hair_volume: float = 0.007  # how far the hair stands off the scalp (metres)
    hair_length: float = 0.0  # how far long hair falls down the back below the neck (metres; 0: short)
    folds: float = 0.0  # amplitude of the cloth's folds and the hair's strands (metres; 0: smooth)
    accessories: Accessories = Accessories()


SAMPLE_OUTFIT = Outfit()  # the bundled sample's figure: striped brick-red T-shirt, jeans, dark shoes
EYE = ((0.50, 0.46, 0.42), 0.6, 0.15)  # sclera
PUPIL = ((0.02, 0.02, 0.02), 0.6, 0.15)
SOLE = (0.3, 0.6)  # specular, roughness
BELT = (0.45, 0.4)
STRAP = (0.45, 0.45)  # specular, roughness of bag straps (webbing or leather)
METAL = (1.0, 0.2)  # of a watch band and a necklace
KNIT = (0.25, 0.9)  # of a knit cap


def classify(fields: np.ndarray, heads: dict, rest_verts: np.ndarray, outfit: Outfit = SAMPLE_OUTFIT) -> dict:
    """Material regions (boolean arrays) from rest-pose fields (..., 8) as made by build_body;
    the outfit's sleeve and leg lengths and belt decide where skin shows."""
    p = fields[..., 0:3].astype(np.float64)  # rest position, anny axes (x left, -y front, z up)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    w_arm, t_arm, w_head, w_eye, w_foot = (fields[..., k] for k in range(3, 8))

    z_sole = rest_verts[:, 2].min()
    z_ankle = 0.5 * (heads["foot.L"][2] + heads["foot.R"][2])
    z_hip = 0.5 * (heads["upperleg01.L"][2] + heads["upperleg01.R"][2])
    z_spine = heads["spine01"][2]
    z_waist = z_hip + 0.22 * (z_spine - z_hip)
    head_c = heads["head"]
    eye_z = 0.5 * (heads["eye.L"][2] + heads["eye.R"][2])
    head_top = rest_verts[rest_verts[:, 2] > eye_z, 2].max()

    # hair: above a hairline that is high over the forehead and low at the nape, ears left bare
    ry = y - head_c[1]  # > 0 towards the back of the head
    hairline = (eye_z + 0.47 * (head_top - eye_z)) - 0.9 * np.clip(ry + 0.04, 0.0, None)
    hairline = np.maximum(hairline, eye_z - 0.55 * (head_top - eye_z))
    ear = (np.abs(x) > 0.062) & (ry > -0.045) & (ry < 0.025) & (z < eye_z + 0.035)
    hair_noise = value_noise(p * np.array([1.0, 1.0, 0.25]), 0.004, 11)
    is_head = w_head > 0.5
    is_eye = w_eye > 0.5
    is_hair = is_head & ~is_eye & (z > hairline + 0.005 * value_noise(p, 0.012, 13)) & ~ear
    if outfit.hair_length > 0.0:
        # long hair: the back of the neck and the ears covered, and a fall down the back whose hem
        # is a little ragged
        neck = heads["neck01"]
        is_hair |= is_head & ~is_eye & ((ry > -0.02) | ear) & (z > eye_z - 0.55 * (head_top - eye_z) - 0.05)
        hem = neck[2] - outfit.hair_length + 0.03 * value_noise(p, 0.03, 17)
        fall = (w_arm < 0.5) & (w_head <= 0.5) & (y > neck[1] + 0.01) & (z > hem) & (np.abs(x) < 0.11 + 0.02 * value_noise(p, 0.04, 19))
        is_hair |= fall
        is_head = is_head | fall  # the fall is not cloth

    is_arm = (w_arm > 0.5) & ~is_head
    sleeve_end = outfit.sleeve + 0.01 * np.sin(40.0 * np.arctan2(y, x))  # a slightly wavy hem
    is_arm_skin = is_arm & (t_arm > sleeve_end)
    body = ~is_head & ~is_arm
    is_sole = body & (z < z_sole + 0.022)
    is_shoe = body & ~is_sole & ((z < z_ankle + 0.035) | (w_foot > 0.5))
    legs = body & ~is_sole & ~is_shoe & (z < z_waist)
    z_hem = z_waist - outfit.leg * (z_waist - (z_ankle + 0.035))  # the bottom's hem
    is_leg_skin = legs & (z < z_hem) if outfit.leg < 1.0 else np.zeros_like(legs)
    is_belt = legs & (z > z_waist - 0.035) if outfit.belt is not None else np.zeros_like(legs)
    is_trousers = legs & ~is_belt & ~is_leg_skin
    is_shirt = ~(is_head | is_arm_skin | is_sole | is_shoe | is_belt | is_trousers | is_leg_skin)
    is_skin = (is_head & ~is_hair & ~is_eye) | is_arm_skin | is_leg_skin
    strap, watch, necklace, cap = _accessory_regions(p, w_arm, t_arm, is_head & ~is_eye, ear, ry, heads, eye_z, head_top, z_hip,
                                                     outfit.accessories)
    strap &= is_shirt
    watch &= ~strap
    is_shirt, is_skin, is_hair = is_shirt & ~strap & ~watch & ~necklace, is_skin & ~watch & ~necklace & ~cap, is_hair & ~cap
    cheeks = is_skin & is_head & (np.abs(z - (eye_z - 0.035)) < 0.025) & (ry < -0.06)
    # on the eyeballs: cosine of the angle from the eye's forward (-y) axis
    d_eye = np.stack([p - heads[f"eye.{side}"] for side in ("L", "R")])
    nearest = np.take_along_axis(d_eye, np.argmin(np.linalg.norm(d_eye, axis=-1), axis=0)[None, ..., None], axis=0)[0]
    gaze = -nearest[..., 1] / np.maximum(np.linalg.norm(nearest, axis=-1), 1e-12)
    iris = is_eye & (gaze > np.cos(np.radians(38.0)))
    pupil = is_eye & (gaze > np.cos(np.radians(16.0)))
    return dict(iris=iris, pupil=pupil, shirt=is_shirt, trousers=is_trousers, belt=is_belt, skin=is_skin, cheeks=cheeks,
                hair=is_hair, shoe=is_shoe, sole=is_sole, eye=is_eye, hair_noise=hair_noise,
                strap=strap, watch=watch, necklace=necklace, cap=cap)


def _accessory_regions(p, w_arm, t_arm, head, ear, ry, heads, eye_z, head_top, z_hip, a: Accessories):
    """Bands of the body's surface (rest positions ``p``) under the accessories that are not meshes
    of their own: bag straps, the watch, the necklace and the cap (``ear``: classify's ears, left bare)."""
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    none = np.zeros(p.shape[:-1], bool)
    strap, watch, necklace, cap = none, none, none, none
    shoulder_x, shoulder_z = abs(heads["upperarm01.L"][0]), heads["shoulder01.L"][2]
    if a.bag == "crossbody":
        # a sash from the top of the other shoulder to the bag's hip, seen alike from the front and
        # the back: 4 cm wide, within 2 cm of the segment in the (x, z) plane
        s = a.bag_side
        a0, a1 = np.array([-s * 0.6 * shoulder_x, shoulder_z + 0.04]), np.array([s * 0.85 * shoulder_x, z_hip + 0.07])
        d = a1 - a0
        q = np.stack([x, z], axis=-1) - a0
        t = np.clip((q @ d) / (d @ d), 0.0, 1.0)
        strap = (w_arm < 0.5) & (np.linalg.norm(q - t[..., None] * d, axis=-1) < 0.02)
    elif a.bag == "backpack":
        # a strap over each shoulder, down the chest to the armpit
        z_chest = heads["spine01"][2] - 0.08
        strap = (w_arm < 0.5) & (np.abs(np.abs(x) - 0.6 * shoulder_x) < 0.02) & (z > z_chest)
    if a.watch is not None:  # 2 cm above the left wrist
        watch = (w_arm > 0.5) & (x > 0.0) & (t_arm > 0.91) & (t_arm < 0.965)
    if a.necklace is not None:
        # a chain round the base of the neck that hangs lower in front
        neck = heads["neck01"]
        front = np.clip(-(y - neck[1]) / 0.07, 0.0, 1.0)
        chain_z = neck[2] - 0.035 - 0.06 * front**2
        radius = np.hypot(x - neck[0], y - neck[1])
        necklace = (w_arm < 0.5) & (np.abs(z - chain_z) < 0.005) & (radius < 0.075 + 0.04 * front)
    if a.cap is not None:  # over the top of the head, lower at the back, the ears bare
        line = np.maximum(eye_z + 0.40 * (head_top - eye_z) - 0.35 * np.clip(ry + 0.04, 0.0, None), eye_z + 0.1 * (head_top - eye_z))
        cap = head & (z > line) & ~ear
    return strap, watch, necklace, cap


def _pattern(g: Garment, p: np.ndarray, seed: int) -> np.ndarray:
    """Weight of the pattern colour (0..1) at rest positions ``p``."""
    if g.pattern == "stripes":
        phase = np.mod(p[..., 2] / g.period, 1.0)
        return smoothstep(0.0, 0.06, phase) * (1.0 - smoothstep(g.width, g.width + 0.06, phase))
    if g.pattern == "dots":
        q = p / g.period
        dist = np.linalg.norm(q - np.round(q), axis=-1)
        return 1.0 - smoothstep(g.width, g.width + 0.08, dist)
    if g.pattern == "blotches":
        return smoothstep(-0.08, 0.08, fbm(p, g.period, seed))
    if g.pattern == "solid":
        return np.zeros(p.shape[:-1])
    raise ValueError(f"unknown pattern {g.pattern!r}")


def make_materials(fields: np.ndarray, mask: np.ndarray, heads: dict, rest_verts: np.ndarray,
                   outfit: Outfit = SAMPLE_OUTFIT):
    """Per-pixel albedo, specular and roughness from the interpolated rest-pose fields."""
    p = fields[..., 0:3].astype(np.float64)
    r = {k: (v & mask if v.dtype == bool else v) for k, v in classify(fields, heads, rest_verts, outfit).items()}
    is_shirt, is_trousers, is_belt, is_skin = r["shirt"], r["trousers"], r["belt"], r["skin"]
    is_hair, is_shoe, is_sole, is_eye, hair_noise = r["hair"], r["shoe"], r["sole"], r["eye"], r["hair_noise"]

    h, w = mask.shape
    albedo = np.zeros((h, w, 3))
    spec = np.zeros((h, w))
    rough = np.zeros((h, w))

    def paint(sel, col, s, r, tint=None):
        col = np.broadcast_to(np.array(col), (h, w, 3))
        if tint is not None:
            col = col * tint[..., None]
        albedo[sel] = col[sel]
        spec[sel] = s
        rough[sel] = r

    def garment(sel, g: Garment, noise: np.ndarray, seed: int):
        k = _pattern(g, p, seed)[..., None]
        col = (1.0 - k) * np.array(g.color) + k * np.array(g.pattern_color)
        col *= (1.0 + g.noise * noise)[..., None]
        albedo[sel] = col[sel]
        spec[sel] = g.specular
        rough[sel] = g.roughness

    o = outfit
    # top: faint weave noise; bottom: low-frequency fading (worn denim); shoes: scuffs
    garment(is_shirt, o.top, fbm(p, 0.05, 3), 21)
    garment(is_trousers, o.bottom, fbm(p * np.array([2.0, 2.0, 0.5]), 0.12, 5), 22)
    if o.belt is not None:
        paint(is_belt, o.belt, *BELT)
    garment(is_shoe, o.shoes, fbm(p, 0.03, 7), 23)
    paint(is_sole, o.sole, *SOLE)
    paint(is_skin, o.skin, o.skin_specular, o.skin_roughness, 1.0 + 0.05 * fbm(p, 0.04, 9))
    albedo[r["cheeks"]] *= np.array([1.04, 0.96, 0.96])  # a little redness on the cheeks
    paint(is_hair, o.hair, o.hair_specular, o.hair_roughness, 1.0 + 0.2 * hair_noise)
    paint(is_eye, *EYE)
    paint(r["iris"], o.iris, EYE[1], EYE[2])
    paint(r["pupil"], *PUPIL)
    a = o.accessories
    if a.bag is not None:
        paint(r["strap"], a.bag_color, *STRAP, 1.0 + 0.1 * fbm(p, 0.02, 25))
    if a.watch is not None:
        paint(r["watch"], a.watch, *METAL)
    if a.necklace is not None:
        paint(r["necklace"], a.necklace, *METAL)
    if a.cap is not None:
        paint(r["cap"], a.cap, *KNIT, 1.0 + 0.15 * value_noise(p * np.array([1.0, 1.0, 0.3]), 0.004, 27))

    albedo = np.where(mask[..., None], np.clip(albedo, 0.0, 1.0), 0.0).astype(np.float32)
    spec = np.where(mask, spec, 0.0).astype(np.float32)
    rough = np.where(mask, rough, 0.0).astype(np.float32)
    regions = {
        "shirt": is_shirt, "trousers": is_trousers, "belt": is_belt, "skin": is_skin, "hair": is_hair,
        "shoes": is_shoe | is_sole, "eyes": is_eye, "accessories": r["strap"] | r["watch"] | r["necklace"] | r["cap"],
    }
    return albedo, spec, rough, regions


# ----------------------------------------------------------------------------------------------
# Random outfits
# ----------------------------------------------------------------------------------------------

# linear albedo of skin from very light to very dark (measured skin reflectances span roughly this
# range at 550 nm; the hue shifts from pink-beige to brown)
SKIN_LIGHT = np.array([0.62, 0.43, 0.35])
SKIN_DARK = np.array([0.10, 0.055, 0.035])
HAIR = {  # linear albedo
    "black": (0.02, 0.018, 0.016), "dark brown": (0.06, 0.035, 0.02), "brown": (0.14, 0.08, 0.045),
    "blond": (0.45, 0.32, 0.16), "red": (0.30, 0.10, 0.04), "grey": (0.35, 0.34, 0.33),
}
IRIS = ((0.12, 0.07, 0.04), (0.05, 0.03, 0.02), (0.10, 0.16, 0.22), (0.12, 0.14, 0.07))
# cloth kinds: (specular, roughness range)
CLOTH_KINDS = {"cotton": (0.3, (0.7, 0.9)), "denim": (0.2, (0.8, 0.9)), "satin": (0.6, (0.18, 0.35)),
               "leather": (0.5, (0.25, 0.45)), "synthetic": (0.45, (0.4, 0.6))}


def _color(rng: np.random.Generator) -> tuple:
    """A garment colour, as linear RGB: a third of them near-neutral (black, grey, white; saturation
    under 0.15), the rest of any hue and saturated (0.3 to 0.95, as dyed cloth is); display value
    0.12 to 0.9 (sRGB)."""
    saturation = rng.uniform(0.0, 0.15) if rng.uniform() < 0.33 else rng.uniform(0.3, 0.95)
    r, g, b = colorsys.hsv_to_rgb(rng.uniform(), saturation, rng.uniform(0.12, 0.9))
    return tuple(float(v) for v in srgb_to_linear([r, g, b]))


def _garment(rng: np.random.Generator, kinds: tuple, patterns: tuple) -> Garment:
    kind = kinds[int(rng.integers(len(kinds)))]
    specular, (r0, r1) = CLOTH_KINDS[kind]
    pattern = patterns[int(rng.integers(len(patterns)))]
    return Garment(_color(rng), specular, float(rng.uniform(r0, r1)), pattern, _color(rng),
                   period=float(rng.uniform(0.02, 0.12)), width=float(rng.uniform(0.15, 0.45)),
                   noise=float(rng.uniform(0.02, 0.2)))


def sample_outfit(rng: np.random.Generator) -> Outfit:
    """Skin over the human range, hair (short or long, flat or full), eyes, a top (solid, stripes, dots or blotches), a bottom
    (trousers or shorts) or a dress (the top's fabric down to the knee), shoes, sleeves from short
    to long, a belt or not; per-region specular and roughness (skin glossy, cotton and denim matte,
    satin and leather glossy)."""
    t = rng.uniform()
    skin = SKIN_LIGHT * (1 - t) + SKIN_DARK * t
    dress = rng.uniform() < 0.15  # one fabric from the shoulders to a hem near the knee (no skirt geometry)
    skin = tuple(float(v) for v in skin * rng.uniform(0.93, 1.07, 3))
    hair = HAIR[list(HAIR)[int(rng.integers(len(HAIR)))]]
    return Outfit(
        skin=skin, skin_specular=float(rng.uniform(0.4, 0.6)), skin_roughness=float(rng.uniform(0.35, 0.55)),
        hair=tuple(float(v) for v in np.array(hair) * rng.uniform(0.85, 1.15, 3)),
        hair_specular=float(rng.uniform(0.3, 0.5)), hair_roughness=float(rng.uniform(0.25, 0.45)),
        iris=IRIS[int(rng.integers(len(IRIS)))],
        top=(top := _garment(rng, ("cotton", "cotton", "satin", "synthetic"), ("solid", "solid", "stripes", "dots", "blotches"))),
        bottom=top if dress else _garment(rng, ("denim", "cotton", "synthetic", "leather"),
                                         ("solid", "solid", "solid", "blotches", "stripes")),
        shoes=_garment(rng, ("leather", "synthetic", "cotton"), ("solid",)),
        sole=tuple(float(v) for v in np.full(3, rng.uniform(0.05, 0.6))),
        belt=(_color(rng) if rng.uniform() < 0.5 and not dress else None),
        sleeve=float(rng.choice([0.15, 0.3, 0.45, 0.8, 1.1])),
        leg=float(rng.uniform(0.4, 0.6)) if dress else float(rng.choice([0.4, 0.55, 1.0, 1.0, 1.0])),
        hair_volume=float(rng.uniform(0.005, 0.03)),
        hair_length=float(rng.uniform(0.08, 0.35)) if rng.uniform() < 0.35 else 0.0,
        folds=float(rng.uniform(0.001, 0.006)),
    )
