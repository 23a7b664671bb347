// Composite over the mask's bounding box of up to MAX_LIGHTS lights (additively blended when
// there are more): HDR += sum_l V_l * I_l * (w_d A' * S_diff_l + w_s S_spec_l). Alpha carries the
// mask. (w_d, w_s) switch the diffuse and specular terms; A' is the albedo, or 1 to show the
// diffuse shading itself. With FRAME_SHADING the two shading sums sum_l V_l I_l S_diff_l and
// sum_l V_l I_l S_spec_l are also written (alpha = mask), for the frame composite.
// Light 4g + j of a chunk sits in plane j of the light atlas, in the tile of group g.
#ifndef MAX_LIGHTS
#error MAX_LIGHTS is defined by the engine (MAX_LIGHTS_PER_COMPOSITE in viewer/gl/engine.py)
#endif
uniform sampler2D albedo_mask;           // linear albedo (rgb) and mask (a)
uniform sampler2D light_plane0, light_plane1, light_plane2, light_plane3;  // (V_soft, V_hard, S_diff, S_spec)
uniform ivec2 group_origin[MAX_LIGHTS / 4];
uniform vec3 intensity[MAX_LIGHTS];      // zero for lights that are skipped
uniform int groups;
uniform ivec2 box_origin;
uniform sampler2D refined_plane0, refined_plane1, refined_plane2, refined_plane3;  // refined V (r), same tiles
uniform int visibility_channel;          // VISIBILITY_*: soft (CSM), hard (shadow map), none, refined
uniform bool write_alpha;
uniform vec2 term_weights;            // (diffuse, specular): 1 shown, 0 left out
uniform bool unit_albedo;             // show shading: albedo replaced by 1
layout(location = 0) out vec4 hdr;
#ifdef FRAME_SHADING
layout(location = 1) out vec4 shading_diffuse;
layout(location = 2) out vec4 shading_specular;
#endif

vec3 sum_diffuse = vec3(0.0);
vec3 sum_specular = vec3(0.0);

void contribution(vec4 b, float refined, vec3 i) {
    float v = visibility_channel == VISIBILITY_SOFT ? b.x : (visibility_channel == VISIBILITY_HARD ? b.y
                                                                  : (visibility_channel == VISIBILITY_REFINED ? refined : 1.0));
    sum_diffuse += v * i * b.z;
    sum_specular += v * i * b.w;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 am = texelFetch(albedo_mask, px, 0);
    if (am.a < 0.5) {
        hdr = vec4(0.0);
#ifdef FRAME_SHADING
        shading_diffuse = shading_specular = vec4(0.0);
#endif
        return;
    }
    vec3 albedo = unit_albedo ? vec3(1.0) : am.rgb;
    ivec2 local = px - box_origin;
    for (int g = 0; g < groups; ++g) {
        ivec2 q = group_origin[g] + local;
        bool r = visibility_channel == VISIBILITY_REFINED;
        contribution(texelFetch(light_plane0, q, 0), r ? texelFetch(refined_plane0, q, 0).r : 0.0, intensity[4 * g]);
        contribution(texelFetch(light_plane1, q, 0), r ? texelFetch(refined_plane1, q, 0).r : 0.0, intensity[4 * g + 1]);
        contribution(texelFetch(light_plane2, q, 0), r ? texelFetch(refined_plane2, q, 0).r : 0.0, intensity[4 * g + 2]);
        contribution(texelFetch(light_plane3, q, 0), r ? texelFetch(refined_plane3, q, 0).r : 0.0, intensity[4 * g + 3]);
    }
    float a = write_alpha ? am.a : 0.0;
    hdr = vec4(term_weights.x * albedo * sum_diffuse + term_weights.y * sum_specular, a);
#ifdef FRAME_SHADING
    shading_diffuse = vec4(sum_diffuse, a);
    shading_specular = vec4(sum_specular, a);
#endif
}
