// Light scattered under the skin: one axis of a separable screen-space diffusion of the diffuse
// shading sum D over the photo's skin (the separable subsurface scattering of Jimenez et al. 2015,
// with d'Eon and Luebke's six-Gaussian skin profile; viewer/gl/skin_pass.py makes the kernel).
// Drawn over the skin's bounding box on a grid of `grid` frame pixels a cell (D, upsampled from the
// work frame, holds nothing finer than a work pixel, several frame pixels wide); gl_FragCoord is
// the cell's, relative to the box. Each tap is millimetres along the axis, turned into frame pixels
// by px_per_mm, and weighs its kernel weight (per channel: red reaches furthest) times how much
// skin it falls on, normalized per channel: light moves only between skin pixels, so nothing off
// the skin changes, and a uniform irradiance stays as it is. Both axes write (D' * skin, skin),
// premultiplied so that bilinear lookups of the result stay normalized at the skin's edge.
//   FIRST_AXIS: reads D at the work resolution (filled_sample over its mip levels);
//   else:       reads the first axis's image.
#include "filled_sample.glsl"
#ifndef SCATTER_TAPS
#error SCATTER_TAPS is defined by the engine (viewer/gl/skin_pass.py)
#endif
uniform sampler2D source;              // FIRST_AXIS: D (work resolution, premultiplied by the mask, mipmapped)
uniform sampler2D skin;                // the share of skin per frame pixel, bilinear
uniform ivec2 box_origin;              // the box's corner in frame pixels
uniform float grid;                    // frame pixels a cell of this pass spans
uniform vec2 frame_to_uv;              // 1 / frame size
uniform vec2 box_to_uv;                // 1 / the box's size in frame pixels (the first axis's image spans the box)
uniform vec2 axis;                     // (1, 0) or (0, 1)
uniform float px_per_mm;
uniform float offsets_mm[SCATTER_TAPS];
uniform vec3 weights[SCATTER_TAPS];    // each channel's kernel, summing to 1
uniform int max_lod;
layout(location = 0) out vec4 color;

// (the irradiance at frame point q, how much skin is there)
vec4 tap(vec2 q) {
#ifdef FIRST_AXIS
    return vec4(filled_sample(source, q * frame_to_uv, max_lod), texture(skin, q * frame_to_uv).r);
#else
    vec4 t = texture(source, (q - vec2(box_origin)) * box_to_uv);
    return vec4(t.a > 1e-6 ? t.rgb / t.a : vec3(0.0), t.a);
#endif
}

void main() {
    vec2 centre = vec2(box_origin) + gl_FragCoord.xy * grid;  // the cell's centre in frame pixels
    float own = texture(skin, centre * frame_to_uv).r;
    if (own <= 0.0) {
        color = vec4(0.0);
        return;
    }
    vec3 sum = vec3(0.0);
    vec3 norm = vec3(0.0);
    for (int i = 0; i < SCATTER_TAPS; ++i) {
        vec4 t = tap(centre + axis * (offsets_mm[i] * px_per_mm));
        vec3 w = weights[i] * t.a;
        sum += w * t.rgb;
        norm += w;
    }
    color = vec4(sum / max(norm, vec3(1e-12)) * own, own);
}
