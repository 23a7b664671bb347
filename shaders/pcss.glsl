// Contact-hardening soft shadows on the hard shadow map: percentage-closer soft shadows (Fernando
// 2005) with the area light's angular size. A blocker search over the light's footprint at a fixed
// distance finds the mean gap between the receiver and its blockers (normalised depth); the
// penumbra is then a Gaussian of alpha * gap metres (alpha: the light's angular sigma, radians),
// sampled by percentage-closer filtering. Both steps use the same PCSS_TAPS Gaussian-distributed
// offsets (a Vogel spiral of Gaussian radii, unit sigma) and compare each tap against the
// receiver's tangent plane, so a sloped lit surface does not shadow itself. No blocker: lit; a
// penumbra under half a texel: the hard test. Needs shadow_test.glsl. Mirrored by
// viewer/twin/pcss.py; the taps and constants are viewer.shadow_space's.
#define PCSS_TAPS 16

uniform vec2 pcss_taps[PCSS_TAPS];
uniform float pcss_search;  // blocker-receiver distance the search covers, in shadow-map windows
uniform float pcss_reach;   // the taps' largest |offset| along u or v (unit sigma)

// Normalised depth per unit of shadow-map uv along the receiver's tangent plane (n: its normal,
// l: the light direction); n.l is floored at 1 / max_slope, which bounds the slope as the hard
// test's bias is bounded.
vec2 receiver_gradient(mat4 frame, vec3 n, vec3 l, float max_slope) {
    vec3 r0 = vec3(frame[0][0], frame[1][0], frame[2][0]);  // right / (2 r)
    vec3 r1 = vec3(frame[0][1], frame[1][1], frame[2][1]);  // up / (2 r)
    vec3 r2 = vec3(frame[0][2], frame[1][2], frame[2][2]);  // -l / depth_scale
    float s = length(r0);
    return vec2(dot(n, r0), dot(n, r1)) * length(r2) / (s * s * max(dot(n, l), 1.0 / max_slope));
}

// Soft visibility of the receiver uvd (hard-test bias ``bias``, hard visibility ``hard``) for a
// light of angular sigma ``alpha`` whose shadow map spans ``window`` metres, ``depth_scale``
// metres per unit of normalised depth. ``min_depth``: the shadow map's minimum over blocks of
// ``block`` texels (viewer.shadow_space.pcss_search_block), read first: where even the nearest
// depth around is behind every tap's receiver plane, there is no blocker and no tap is taken.
float pcss_visibility(sampler2D shadow_map, sampler2D min_depth, int block, vec3 uvd, vec2 gradient, float bias,
                      float alpha, float window, float depth_scale, float hard) {
    float search = alpha * pcss_search;  // uv
    float reach = pcss_reach * search;
    ivec2 last = textureSize(shadow_map, 0) - 1;
    vec2 size = vec2(last + 1);
    ivec2 lo = clamp(ivec2(floor((uvd.xy - reach) * size)), ivec2(0), last) / block;
    ivec2 hi = clamp(ivec2(floor((uvd.xy + reach) * size)), ivec2(0), last) / block;
    float nearest = min(min(texelFetch(min_depth, lo, 0).r, texelFetch(min_depth, ivec2(hi.x, lo.y), 0).r),
                        min(texelFetch(min_depth, ivec2(lo.x, hi.y), 0).r, texelFetch(min_depth, hi, 0).r));
    if (nearest > uvd.z + (abs(gradient.x) + abs(gradient.y)) * reach - bias + 1e-6) return 1.0;
    float gap = 0.0;
    float blockers = 0.0;
    for (int i = 0; i < PCSS_TAPS; ++i) {
        vec2 o = pcss_taps[i] * search;
        float receiver = uvd.z + dot(gradient, o) - bias;
        float z = shadow_depth(shadow_map, uvd.xy + o);
        if (z < receiver) {
            gap += receiver - z;
            blockers += 1.0;
        }
    }
    if (blockers == 0.0) return 1.0;
    float width = alpha * (gap / blockers) * depth_scale / window;  // the penumbra's sigma, uv
    if (width * float(textureSize(shadow_map, 0).x) < 0.5) return hard;
    float lit = 0.0;
    for (int i = 0; i < PCSS_TAPS; ++i) {
        vec2 o = pcss_taps[i] * width;
        lit += (uvd.z + dot(gradient, o) - bias <= shadow_depth(shadow_map, uvd.xy + o)) ? 1.0 : 0.0;
    }
    return lit / float(PCSS_TAPS);
}
