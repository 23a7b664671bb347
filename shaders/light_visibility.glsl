// The visibility of a point from each of the four lights of a pass: hard (shadow-map test) and
// soft (the engine's soft-shadow method, viewer/gl/soft/: its soft_visibility, included here as
// soft_method.glsl), and the per-light uniforms they read. Included by the light pass (the person's
// pixels) and the ground shadow pass (a ground plane at the feet). Needs shadow_test.glsl.

uniform mat4 light_frame[4];
uniform vec3 light_dir[4];
uniform float depth_scale[4];
uniform int light_mode[4];     // PASS_OFF: no light in this slot; PASS_HARD: hard only (sigma ~ 0, or
                               // soft not shown); PASS_SOFT: hard and soft; PASS_UNSHADOWED: visibility 1
uniform float light_alpha[4];  // each light's angular sigma (radians): contact-hardening penumbrae, specular widening
uniform float shadow_window;   // metres a shadow map spans (the same for every light)

#include "soft_method.glsl"

// (soft, hard) visibility of light j at p, a receiver with unit normal n facing the light
// (n.l > 0); 1 in mode 3.
vec2 light_visibility(int j, sampler2D shadow_map, sampler2D filtered_basis, vec3 p, vec3 n) {
    if (light_mode[j] == PASS_UNSHADOWED) return vec2(1.0);
    vec3 l = light_dir[j];
    vec3 uvd = receiver_uvd(light_frame[j], p, n);
    // a receiver past everything the map holds (the ground far behind the person) is as deep as
    // an empty texel, so it is shadowed by what covers it and lit elsewhere; a no-op on the person
    uvd.z = min(uvd.z, empty_depth);
    float bias = receiver_bias(n, l, depth_scale[j]);
    float v_hard = hard_visibility(shadow_map, uvd, bias);
    float v_soft = light_mode[j] == PASS_HARD ? v_hard : soft_visibility(j, shadow_map, filtered_basis, uvd, n, l, bias);
    return vec2(v_soft, v_hard);
}
