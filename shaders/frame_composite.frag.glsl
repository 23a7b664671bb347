// The final composite and display at the output frame's resolution, in one pass
// (docs/engine.md, "Frame passes"):
//   HDR = w_d A_frame D + w_s S t,  alpha = the person's soft matte,
// with A_frame the detail albedo at the frame's resolution and D, S the diffuse and specular
// shading sums of the work-resolution composite (sum_l V_l I_l S_diff_l and sum_l V_l I_l S_spec_l),
// brought to the frame by filled_sample (bilinear, normalized by the mask, filled past it), and t the
// albedo's fine detail (a smooth sheen over the photo's texture flattened it: detail kept 0.74-0.79
// on the street photo, 0.99-1.05 with it, docs/photos.md); then,
// over the cached background, exposure, tone map and sRGB as the work display does; the photo's own
// background is shown as the photo is (no exposure, no tone curve: the photo's display values), and
// in the HDR outputs divided by the exposure, so that the HDR exposed is what the display shows.
// output_mode OUTPUT_DISPLAY writes the display image; OUTPUT_PERSON_HDR the person's HDR and matte; OUTPUT_COMPOSITED_HDR the HDR composited over
// the background before exposure (transparent: premultiplied), the EXR beside a display PNG;
// OUTPUT_BACKGROUND_DISPLAY the display image with no person and no shadow of theirs (a clip's
// frame where the person has left the picture), OUTPUT_BACKGROUND_HDR its HDR (as OUTPUT_COMPOSITED_HDR).
// Before / after (display only): left of compare_x pixels the original photo as it was, with a
// two-pixel white line at the split. With ground, the background is darkened by the person's
// shadow on the ground (ground_shadow.frag.glsl, work images' field of view, bilinear). On the skin,
// D is the light scattered under it (skin_scatter.frag.glsl) when that pass ran.
#include "filled_sample.glsl"
#include "tonemap.glsl"
uniform sampler2D frame_albedo_alpha;  // detail albedo (rgb, linear) and matte (a), frame resolution
uniform sampler2D albedo_mean;         // (the albedo's luminance where the person is, where the person is), mipmapped
uniform float sheen_lod;               // its mip level as coarse as the work frame's shading (the sheen's detail)
uniform bool sheen_detail;             // the sheen takes the albedo's fine detail (off: the smooth sum, as inference reads it)
uniform sampler2D shading_diffuse;     // work resolution, premultiplied by the mask, mipmapped
uniform sampler2D shading_specular;
uniform sampler2D background;          // linear, the frame's resolution or less (frame_background.frag.glsl), bilinear
uniform sampler2D photo;               // the original photo, linear, frame resolution
uniform float compare_x;               // display: pixels from the left showing the photo (0: none)
uniform vec2 frame_to_uv;              // 1 / frame size: the work images span the same field of view
uniform int max_lod;
uniform vec2 term_weights;             // (diffuse, specular): 1 shown, 0 left out
uniform bool unit_albedo;              // show shading: albedo replaced by 1
uniform bool transparent;
uniform bool photo_background;         // the background is the photo's own: shown as it is
uniform float exposure;                // stops
uniform int tonemap_op;
uniform int output_mode;
uniform sampler2D ground_occlusion;
uniform bool ground;
uniform bool skin_scatter;             // D replaced by its scattered self on the skin (skin_scatter.frag.glsl)
uniform sampler2D skin_scattered;      // (D scattered x skin, skin) over the skin's box, coarser, bilinear
uniform sampler2D skin;                // the share of skin per frame pixel
uniform ivec4 skin_box;                // (x, y, width, height) of that box in frame pixels
uniform vec2 skin_box_to_uv;           // 1 / the box's size in frame pixels, as the scattered image spans it
layout(location = 0) out vec4 color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    bool no_person = output_mode == OUTPUT_BACKGROUND_DISPLAY || output_mode == OUTPUT_BACKGROUND_HDR;
    vec4 aa = no_person ? vec4(0.0) : texelFetch(frame_albedo_alpha, px, 0);
    vec3 fg = vec3(0.0);
    if (aa.a > 0.0) {
        vec2 uv = (vec2(px) + 0.5) * frame_to_uv;
        vec3 d = filled_sample(shading_diffuse, uv, max_lod);
        ivec2 q = px - skin_box.xy;
        if (skin_scatter && all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, skin_box.zw))) {
            vec4 scattered = texture(skin_scattered, (vec2(q) + 0.5) * skin_box_to_uv);  // premultiplied by the skin
            float own = texelFetch(skin, px, 0).r;
            if (scattered.a > 1e-4) d = mix(d, scattered.rgb / scattered.a, own);
        }
        vec3 s = filled_sample(shading_specular, uv, max_lod);
        if (sheen_detail) {
            // the sheen takes the photo's fine detail as the albedo has it (weave, strands, pores): the albedo's
            // luminance over its mean over the person at the scale the work frame's shading resolves
            vec2 mean = textureLod(albedo_mean, uv, sheen_lod).rg;
            float y = dot(aa.rgb, vec3(0.2126, 0.7152, 0.0722));
            s *= clamp(y / max(mean.r / max(mean.g, 1e-3), 1e-4), SHEEN_DETAIL_MIN, SHEEN_DETAIL_MAX);
        }
        fg = term_weights.x * (unit_albedo ? vec3(1.0) : aa.rgb) * d + term_weights.y * s;
    }
    if (output_mode == OUTPUT_PERSON_HDR) { color = vec4(fg, aa.a); return; }
    vec3 bg = aa.a >= 1.0 ? vec3(0.0) : texture(background, (vec2(px) + 0.5) / vec2(textureSize(frame_albedo_alpha, 0))).rgb;
    if (ground && !no_person && aa.a < 1.0) {
        bg *= clamp(1.0 - texture(ground_occlusion, (vec2(px) + 0.5) * frame_to_uv).rgb, 0.0, 1.0);
    }
    if (output_mode == OUTPUT_COMPOSITED_HDR || output_mode == OUTPUT_BACKGROUND_HDR) {
        if (photo_background) bg *= exp2(-exposure);  // shown unexposed: the HDR times 2^exposure is the display's
        color = transparent ? vec4(fg * aa.a, aa.a) : vec4(mix(bg, fg, aa.a), 1.0);
        return;
    }
    float x = float(px.x) + 0.5;
    if (compare_x > 0.0 && abs(x - compare_x) < 1.0) { color = vec4(1.0); return; }
    if (x < compare_x) { color = vec4(linear_to_srgb(texelFetch(photo, px, 0).rgb), 1.0); return; }
    float scale = exp2(exposure);
    vec3 front = tonemap(fg * scale, tonemap_op);
    if (transparent) { color = vec4(linear_to_srgb(front), aa.a); return; }
    vec3 back = aa.a >= 1.0 ? vec3(0.0) : photo_background ? clamp(bg, 0.0, 1.0) : tonemap(bg * scale, tonemap_op);
    color = vec4(linear_to_srgb(mix(back, front, aa.a)), 1.0);
}
