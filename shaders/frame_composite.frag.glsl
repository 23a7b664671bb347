// The final composite at the output frame's resolution (docs/engine.md, "Frame"):
//   HDR = w_d A_frame D + w_s S,  alpha = the person's soft matte,
// with A_frame the detail albedo at the frame's resolution and D, S the diffuse and specular
// shading sums of the work-resolution composite (sum_l V_l I_l S_diff_l and sum_l V_l I_l S_spec_l),
// brought to the frame by filled_sample (bilinear, normalized by the mask, filled past it).
#include "filled_sample.glsl"
uniform sampler2D frame_albedo_alpha;  // detail albedo (rgb, linear) and matte (a), frame resolution
uniform sampler2D shading_diffuse;     // work resolution, premultiplied by the mask, mipmapped
uniform sampler2D shading_specular;
uniform vec2 frame_to_uv;              // 1 / frame size: the work images span the same field of view
uniform int max_lod;
uniform vec2 term_weights;             // (diffuse, specular): 1 shown, 0 left out
uniform bool unit_albedo;              // show shading: albedo replaced by 1
layout(location = 0) out vec4 hdr;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 aa = texelFetch(frame_albedo_alpha, px, 0);
    if (aa.a <= 0.0) { hdr = vec4(0.0); return; }
    vec2 uv = (vec2(px) + 0.5) * frame_to_uv;
    vec3 d = filled_sample(shading_diffuse, uv, max_lod);
    vec3 s = filled_sample(shading_specular, uv, max_lod);
    vec3 albedo = unit_albedo ? vec3(1.0) : aa.rgb;
    hdr = vec4(term_weights.x * albedo * d + term_weights.y * s, aa.a);
}
