// The person's shadow on a ground plane at the feet (a shadow catcher), four lights a pass, at a
// fraction of the work resolution (EngineOptions.ground_scale: half, a quarter in the drag preview). For the plane's point P seen through each pixel, the share of the plane's
// unshadowed irradiance E0 = sum_l I_l max(l.n, 0) that this pass's lights lose to the person
//   O = sum_l (I_l max(l.n, 0) / E0) (1 - V_l(P))  (n the plane's normal),
// added over the passes (additive blending); the display multiplies the background by 1 - O.
// The plane is ground_plane.glsl's: pixels at or above its horizon, and plane points outside a
// light's shadow map (the person's shadow cannot fall there), lose nothing. Near the feet each
// light's visibility is at most one minus the share of it the feet's contact points hide (the
// contact shadow, which the shadow map's bias and resolution miss): each point a small disk of
// its pixels' area, its solid angle weighted by a Gaussian lobe about the light's direction as wide
// as the light or the share of the sky it stands for (contact_spread), whichever is wider.
#include "ground_plane.glsl"
#include "shadow_test.glsl"
#include "light_visibility.glsl"

uniform sampler2D shadow_map0, shadow_map1, shadow_map2, shadow_map3;
uniform sampler2D filtered_basis0, filtered_basis1, filtered_basis2, filtered_basis3;  // CSM
#ifndef MAX_CONTACT_POINTS
#error MAX_CONTACT_POINTS is defined by the engine (viewer.scene.ground)
#endif
uniform vec4 contact_points[MAX_CONTACT_POINTS];  // camera space (xyz), area in m^2 (w)
uniform int contact_count;
uniform float contact_spread;  // radians: the sky each light stands for
uniform vec4 contact_bound;    // a sphere (centre, radius) outside which the contact points hide nothing
uniform vec3 light_share[4];   // I_l max(l.n, 0) / E0 per channel (0: below the horizon, or no light)
layout(location = 0) out vec4 occlusion;

// The share of light j (unit direction l, angular sigma alpha) that the contact points hide from p.
float contact_occlusion(vec3 p, vec3 l, float alpha) {
    if (distance(p, contact_bound.xyz) > contact_bound.w) return 0.0;
    float s2 = max(max(alpha, contact_spread), 1e-2);
    s2 *= s2;
    float hidden = 0.0;
    for (int i = 0; i < contact_count; ++i) {
        vec3 v = contact_points[i].xyz - p;
        float d2 = dot(v, v) + 1e-8;
        float c = dot(v, l) * inversesqrt(d2);
        if (c <= 0.0) continue;
        float solid = contact_points[i].w / (d2 + contact_points[i].w / PI);  // a disk's solid angle, at most pi
        hidden += solid * exp(-(1.0 - c) / s2) / (2.0 * PI * s2);  // 2 (1 - cos) ~ the angle squared
    }
    return min(hidden, 1.0);
}

vec3 light_occlusion(int j, sampler2D shadow_map, sampler2D filtered_basis, vec3 p) {
    if (light_mode[j] == PASS_OFF || light_mode[j] == PASS_UNSHADOWED || dot(light_dir[j], ground_normal) <= 0.0) return vec3(0.0);
    vec2 uv = (light_frame[j] * vec4(p, 1.0)).xy;
    float v = (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) ? 1.0
            : light_visibility(j, shadow_map, filtered_basis, p, ground_normal).x;
    v = min(v, 1.0 - contact_occlusion(p, light_dir[j], light_alpha[j]));
    return light_share[j] * (1.0 - v);
}

void main() {
    vec3 p;
    occlusion = vec4(0.0);
    if (!ground_point(gl_FragCoord.xy, p)) return;
    vec3 o = light_occlusion(0, shadow_map0, filtered_basis0, p) + light_occlusion(1, shadow_map1, filtered_basis1, p)
           + light_occlusion(2, shadow_map2, filtered_basis2, p) + light_occlusion(3, shadow_map3, filtered_basis3, p);
    occlusion = vec4(o, 0.0);
}
