// Four area lights per pass, at every camera pixel of the mask's bounding box: soft visibility
// (the engine's soft-shadow method, viewer/gl/soft/), hard visibility (shadow map) and Lambert / Disney shading per unit intensity, written as
// (V_soft, V_hard, S_diff, S_spec) to the four planes of the light atlas (light i: plane i % 4, in
// the tile of group i / 4). The composite multiplies by the light's RGB intensity and the albedo.
// Where a light is below the surface's horizon (n.l <= 0) both shading terms vanish, so the shadow
// tests are skipped and the visibility is 0 there. Mode 3 (no shadows shown) skips the shadow
// tests altogether (visibility 1, no shadow map needed). Sharing the pixel's fetches between four lights
// and drawing a quarter as often is what the batching buys.
#include "brdf.glsl"
#include "shadow_test.glsl"
#include "light_visibility.glsl"

uniform sampler2D positions;   // camera-space points (xyz) and roughness (w)
uniform sampler2D normals;     // unit normals (xyz; zero outside the mask) and specular (w)
uniform sampler2D shadow_map0, shadow_map1, shadow_map2, shadow_map3;
uniform sampler2D filtered_basis0, filtered_basis1, filtered_basis2, filtered_basis3;  // CSM
uniform ivec2 tile_origin;     // this group's tile in the light atlas
uniform ivec2 box_origin;      // the mask's bounding box in the image
layout(location = 0) out vec4 result0;
layout(location = 1) out vec4 result1;
layout(location = 2) out vec4 result2;
layout(location = 3) out vec4 result3;

vec4 light_result(int j, sampler2D shadow_map, sampler2D filtered_basis, vec3 p, vec3 n, float specular,
                  float roughness) {
    vec3 l = light_dir[j];
    if (light_mode[j] == PASS_OFF || dot(n, l) <= 0.0) return vec4(0.0);  // also every pixel outside the mask
    vec2 v = light_visibility(j, shadow_map, filtered_basis, p, n);
#ifdef SPECULAR
    float s_spec = disney_specular_shading(n, l, specular, roughness, light_alpha[j]);
#else
    float s_spec = 0.0;
#endif
    return vec4(v.x, v.y, lambert_shading(n, l), s_spec);
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy) - tile_origin + box_origin;
    vec4 ns = texelFetch(normals, px, 0);
    if (dot(ns.xyz, ns.xyz) < 0.5) {  // outside the mask
        result0 = result1 = result2 = result3 = vec4(0.0);
        return;
    }
    vec4 pm = texelFetch(positions, px, 0);
    result0 = light_result(0, shadow_map0, filtered_basis0, pm.xyz, ns.xyz, ns.w, pm.w);
    result1 = light_result(1, shadow_map1, filtered_basis1, pm.xyz, ns.xyz, ns.w, pm.w);
    result2 = light_result(2, shadow_map2, filtered_basis2, pm.xyz, ns.xyz, ns.w, pm.w);
    result3 = light_result(3, shadow_map3, filtered_basis3, pm.xyz, ns.xyz, ns.w, pm.w);
}
