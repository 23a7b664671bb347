// Display image: exposure, tone map and sRGB of the HDR composite over a background
// (the rotated environment map seen through the camera, the photo's own background, a colour, or
// none: transparent, the composite's alpha kept). With HDR_OUTPUT the same composite is written in
// linear HDR instead (before exposure and tone map; transparent: premultiplied RGB and alpha), the
// EXR that goes with a display PNG. With ground, the background is darkened by the person's shadow
// on the ground (ground_shadow.frag.glsl: the share of the ground's light the person takes away).
#include "tonemap.glsl"
#include "envmap.glsl"
uniform sampler2D hdr;
uniform sampler2D background_image;   // linear RGB, image rows top first
uniform sampler2D environment;        // equirectangular, linear RGB
uniform int background_mode;          // BACKGROUND_*
uniform vec3 background_color;        // linear
uniform mat3 environment_rotation;    // camera-space view direction -> map direction
uniform float ground_squash;          // the map\'s ground seen from the camera\'s height (envmap.glsl: 1, as taken)
uniform vec2 focal_center_px;         // principal point (pixels)
uniform float focal_px;
uniform float exposure;               // stops
uniform int tonemap_op;
uniform sampler2D ground_occlusion;   // half resolution, bilinear
uniform bool ground;
layout(location = 0) out vec4 color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(hdr, px, 0);
    float scale = exp2(exposure);
    vec3 bg = background_color;
    if (c.a >= 1.0) {
        // the person covers the pixel: no background to look up
    } else if (background_mode == BACKGROUND_PHOTO) {
        bg = texelFetch(background_image, px, 0).rgb;
    } else if (background_mode == BACKGROUND_ENVIRONMENT) {
        bg = environment_seen(environment, environment_rotation, ground_squash, vec2(px) + 0.5, focal_center_px, focal_px);
    }
    if (ground && c.a < 1.0) {
        bg *= clamp(1.0 - texture(ground_occlusion, (vec2(px) + 0.5) / vec2(textureSize(hdr, 0))).rgb, 0.0, 1.0);
    }
#ifdef HDR_OUTPUT
    if (background_mode == BACKGROUND_PHOTO) bg /= scale;  // shown unexposed: the HDR times 2^exposure is the display's
    color = background_mode == BACKGROUND_TRANSPARENT ? vec4(c.rgb * c.a, c.a) : vec4(mix(bg, c.rgb, c.a), 1.0);
#else
    vec3 fg = tonemap(c.rgb * scale, tonemap_op);
    if (background_mode == BACKGROUND_TRANSPARENT) {
        color = vec4(linear_to_srgb(fg), c.a);
        return;
    }
    vec3 back = background_mode == BACKGROUND_PHOTO ? clamp(bg, 0.0, 1.0) : tonemap(bg * scale, tonemap_op);  // the photo as it is
    color = vec4(linear_to_srgb(mix(back, fg, c.a)), 1.0);
#endif
}
