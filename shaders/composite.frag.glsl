// Composite over the mask's bounding box of up to MAX_LIGHTS lights (additively blended when
// there are more): HDR += sum_l V_l * I_l * (A * S_diff_l + S_spec_l). Alpha carries the mask.
#ifndef MAX_LIGHTS
#define MAX_LIGHTS 64
#endif
uniform sampler2D albedo_mask;           // linear albedo (rgb) and mask (a)
uniform sampler2D light_atlas;           // per light tile: (V_soft, V_hard, S_diff, S_spec)
uniform ivec2 tile_origin[MAX_LIGHTS];
uniform vec3 intensity[MAX_LIGHTS];
uniform int count;
uniform ivec2 box_origin;
uniform int visibility_channel;          // 0: soft (CSM), 1: hard (shadow map), 2: none
uniform bool write_alpha;
layout(location = 0) out vec4 hdr;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 am = texelFetch(albedo_mask, px, 0);
    if (am.a < 0.5) { hdr = vec4(0.0); return; }
    ivec2 local = px - box_origin;
    vec3 sum = vec3(0.0);
    for (int i = 0; i < count; ++i) {
        vec4 b = texelFetch(light_atlas, tile_origin[i] + local, 0);
        float v = visibility_channel == 0 ? b.x : (visibility_channel == 1 ? b.y : 1.0);
        sum += v * intensity[i] * (am.rgb * b.z + b.w);
    }
    hdr = vec4(sum, write_alpha ? am.a : 0.0);
}
