// The person's shadow on a ground plane at the feet (a shadow catcher), four lights a pass, at half
// the work resolution. For the plane's point P seen through each pixel, the share of the plane's
// unshadowed irradiance E0 = sum_l I_l max(l.y, 0) that this pass's lights lose to the person:
//   O = sum_l (I_l max(l.y, 0) / E0) (1 - V_l(P)),
// added over the passes (additive blending); the display multiplies the background by 1 - O.
// The plane is y = ground_y in camera space (a level camera): pixels at or above the horizon, and
// plane points outside a light's shadow map (the person's shadow cannot fall there), lose nothing.
#include "shadow_test.glsl"
#ifdef SOFT_PCSS
#include "pcss.glsl"
#else
#include "csm.glsl"
#endif
#include "light_visibility.glsl"

uniform sampler2D shadow_map0, shadow_map1, shadow_map2, shadow_map3;
uniform sampler2D filtered_basis0, filtered_basis1, filtered_basis2, filtered_basis3;  // CSM
uniform vec3 light_share[4];   // I_l max(l.y, 0) / E0 per channel (0: below the horizon, or no light)
uniform float ground_y;        // the plane's height (camera space, metres; below the camera: < 0)
uniform vec2 focal_center_px;  // this pass's camera (pixels, rows from the top)
uniform float focal_px;
layout(location = 0) out vec4 occlusion;

vec3 light_occlusion(int j, sampler2D shadow_map, sampler2D filtered_basis, vec3 p) {
    if (light_mode[j] == 0 || light_mode[j] == 3 || light_dir[j].y <= 0.0) return vec3(0.0);
    vec2 uv = (light_frame[j] * vec4(p, 1.0)).xy;
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) return vec3(0.0);
    return light_share[j] * (1.0 - light_visibility(j, shadow_map, filtered_basis, p, vec3(0.0, 1.0, 0.0)).x);
}

void main() {
    vec2 q = gl_FragCoord.xy;
    vec3 view = vec3((q.x - focal_center_px.x) / focal_px, -(q.y - focal_center_px.y) / focal_px, -1.0);
    occlusion = vec4(0.0);
    if (view.y >= -1e-6) return;  // at or above the horizon: no ground
    vec3 p = view * (ground_y / view.y);
    vec3 o = light_occlusion(0, shadow_map0, filtered_basis0, p) + light_occlusion(1, shadow_map1, filtered_basis1, p)
           + light_occlusion(2, shadow_map2, filtered_basis2, p) + light_occlusion(3, shadow_map3, filtered_basis3, p);
    occlusion = vec4(o, 0.0);
}
