// Composite of a chunk of lights (additively blended over chunks):
// HDR += sum_l V_l * I_l * (A * S_diff_l + S_spec_l). Alpha carries the mask.
#ifndef CHUNK
#define CHUNK 8
#endif
uniform sampler2D albedo_mask;           // linear albedo (rgb) and mask (a)
uniform sampler2D light_buffers[CHUNK];  // (V_soft, V_hard, S_diff, S_spec) per light
uniform vec3 intensity[CHUNK];
uniform int count;
uniform int visibility_channel;          // 0: soft (CSM), 1: hard (shadow map), 2: none
uniform bool write_alpha;
layout(location = 0) out vec4 hdr;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 am = texelFetch(albedo_mask, px, 0);
    if (am.a < 0.5) { hdr = vec4(0.0); return; }
    vec3 sum = vec3(0.0);
    for (int i = 0; i < count; ++i) {
        vec4 b = texelFetch(light_buffers[i], px, 0);
        float v = visibility_channel == 0 ? b.x : (visibility_channel == 1 ? b.y : 1.0);
        sum += v * intensity[i] * (am.rgb * b.z + b.w);
    }
    hdr = vec4(sum * am.a, write_alpha ? am.a : 0.0);
}
