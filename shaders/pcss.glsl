// Contact-hardening soft shadows on the hard shadow map: percentage-closer soft shadows (Fernando
// 2005) with the area light's angular size. A blocker search over the light's footprint at a fixed
// distance finds the mean gap between the receiver and its blockers (normalised depth); the
// penumbra is then a Gaussian of alpha * gap metres (alpha: the light's angular sigma, radians),
// sampled by percentage-closer filtering, at least pcss_min_texels texels wide (a sharp shadow's
// edge is filtered, not a staircase of texels). Both steps use Gaussian-distributed offsets (Vogel
// spirals of Gaussian radii, unit sigma: PCSS_SEARCH_TAPS for the search, PCSS_TAPS for the
// filter) and compare each tap against the receiver's tangent plane, so a sloped lit surface does
// not shadow itself; a texel no triangle covers (empty_depth) is never a blocker, however far the
// tangent plane of a grazing receiver (the ground under a low sun) reaches. No blocker: lit. Needs
// shadow_test.glsl. Mirrored by viewer/twin/pcss.py; the taps and constants are viewer.scene.shadow_space's.
#if !defined(PCSS_TAPS) || !defined(PCSS_SEARCH_TAPS)
#error PCSS_TAPS and PCSS_SEARCH_TAPS are defined by the engine (viewer.scene.shadow_space)
#endif

uniform vec2 pcss_taps[PCSS_TAPS];
uniform vec2 pcss_search_taps[PCSS_SEARCH_TAPS];
uniform float pcss_search;  // blocker-receiver distance the search covers, in shadow-map windows
uniform float pcss_min_texels;  // the penumbra's smallest sigma, shadow-map texels

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

// Soft visibility of the receiver uvd (hard-test bias ``bias``) for a light of angular sigma
// ``alpha`` whose shadow map spans ``window`` metres, ``depth_scale`` metres per unit of
// normalised depth.
float pcss_visibility(sampler2D shadow_map, vec3 uvd, vec2 gradient, float bias, float alpha, float window,
                      float depth_scale) {
    float search = alpha * pcss_search;  // uv
    float gap = 0.0;
    float blockers = 0.0;
    for (int i = 0; i < PCSS_SEARCH_TAPS; ++i) {
        vec2 o = pcss_search_taps[i] * search;
        float receiver = uvd.z + dot(gradient, o) - bias;
        float z = shadow_depth(shadow_map, uvd.xy + o);
        if (z < receiver && z < empty_depth) {
            gap += receiver - z;
            blockers += 1.0;
        }
    }
    if (blockers == 0.0) return 1.0;
    float width = max(alpha * (gap / blockers) * depth_scale / window,  // the penumbra's sigma, uv
                      pcss_min_texels / float(textureSize(shadow_map, 0).x));
    float lit = 0.0;
    for (int i = 0; i < PCSS_TAPS; ++i) {
        vec2 o = pcss_taps[i] * width;
        float z = shadow_depth(shadow_map, uvd.xy + o);
        lit += (uvd.z + dot(gradient, o) - bias <= z || z >= empty_depth) ? 1.0 : 0.0;
    }
    return lit / float(PCSS_TAPS);
}
