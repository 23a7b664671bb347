// Per area light, at every camera pixel: soft visibility (CSM), hard visibility (shadow map) and
// Lambert / Disney shading per unit intensity. Output (V_soft, V_hard, S_diff, S_spec); the
// composite multiplies by the light's RGB intensity and the albedo.
#include "brdf.glsl"
#include "csm.glsl"
#include "shadow_test.glsl"

uniform sampler2D positions;   // camera-space points (xyz) and mask (w)
uniform sampler2D normals;
uniform sampler2D materials;   // (specular, roughness)
uniform sampler2D shadow_map;
uniform sampler2D filtered_basis[BASIS_TEXTURES];
uniform bool soft_from_hard;   // sigma ~ 0: soft visibility = hard visibility (filtering skipped)
uniform float csm_offset;
uniform float csm_clamp;
layout(location = 0) out vec4 result;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 pm = texelFetch(positions, px, 0);
    if (pm.w < 0.5) { result = vec4(0.0); return; }
    vec3 n = texelFetch(normals, px, 0).xyz;
    vec2 mat = texelFetch(materials, px, 0).xy;
    vec3 uvd = receiver_uvd(pm.xyz, n);
    float v_hard = hard_visibility(shadow_map, uvd, receiver_bias(n));
    float v_soft = v_hard;
    if (!soft_from_hard) {
        vec4 b[BASIS_TEXTURES];
        for (int t = 0; t < BASIS_TEXTURES; ++t) b[t] = texture(filtered_basis[t], uvd.xy);
        v_soft = csm_visibility(b, uvd.z, csm_offset, csm_clamp);
    }
    float s_diff = lambert_shading(n, light_dir);
#ifdef SPECULAR
    float s_spec = disney_specular_shading(n, light_dir, mat.x, mat.y);
#else
    float s_spec = 0.0;
#endif
    result = vec4(v_soft, v_hard, s_diff, s_spec);
}
