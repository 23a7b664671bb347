// Per area light, at every camera pixel of the mask's bounding box: soft visibility (CSM), hard
// visibility (shadow map) and Lambert / Disney shading per unit intensity, written to the light's
// tile of the light atlas as (V_soft, V_hard, S_diff, S_spec). The composite multiplies by the
// light's RGB intensity and the albedo. Where the light is below the surface's horizon (n.l <= 0)
// both shading terms vanish, so the shadow tests are skipped and the visibility is 0 there.
#include "brdf.glsl"
#include "csm.glsl"
#include "shadow_test.glsl"

uniform sampler2D positions;   // camera-space points (xyz) and roughness (w)
uniform sampler2D normals;     // unit normals (xyz; zero outside the mask) and specular (w)
uniform sampler2D shadow_map;
uniform sampler2D filtered_basis;
uniform bool soft_from_hard;   // sigma ~ 0: soft visibility = hard visibility (filtering skipped)
uniform float csm_offset;
uniform float csm_clamp;
uniform ivec2 tile_origin;     // this light's tile in the light atlas
uniform ivec2 box_origin;      // the mask's bounding box in the image
layout(location = 0) out vec4 result;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy) - tile_origin + box_origin;
    vec4 ns = texelFetch(normals, px, 0);
    vec3 n = ns.xyz;
    if (dot(n, light_dir) <= 0.0) { result = vec4(0.0); return; }  // also every pixel outside the mask
    vec4 pm = texelFetch(positions, px, 0);
    vec3 uvd = receiver_uvd(pm.xyz, n);
    float v_hard = hard_visibility(shadow_map, uvd, receiver_bias(n));
    float v_soft = soft_from_hard ? v_hard : csm_visibility(filtered_basis, uvd.xy, uvd.z, csm_offset, csm_clamp);
    float s_diff = lambert_shading(n, light_dir);
#ifdef SPECULAR
    float s_spec = disney_specular_shading(n, light_dir, ns.w, pm.w);
#else
    float s_spec = 0.0;
#endif
    result = vec4(v_soft, v_hard, s_diff, s_spec);
}
