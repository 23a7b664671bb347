// Inspection views of the scene bundle and of one light's visibility, drawn into the display
// image instead of the relit frame: albedo (sRGB), normal (n * 0.5 + 0.5), depth (near = white),
// specular, roughness, and a light's shadow (its soft or hard visibility, white = lit). Drawn at
// the display's size: a scene with a frame layer shows each output pixel's nearest work pixel.
#include "tonemap.glsl"
uniform sampler2D positions;    // camera-space points (xyz) and roughness (w)
uniform sampler2D normals;      // unit normals (xyz) and specular (w)
uniform sampler2D albedo_mask;  // linear albedo (rgb) and mask (a)
uniform sampler2D light_plane;  // the light atlas plane holding the inspected light
uniform int view;               // INSPECT_*: the map shown, or one light's shadow
uniform vec2 depth_range;       // nearest and farthest depth inside the mask (metres)
uniform ivec2 tile_origin;      // the inspected light's tile in the light atlas
uniform ivec2 box_origin;       // the mask's bounding box in the image
uniform int visibility_channel; // VISIBILITY_SOFT or VISIBILITY_HARD
uniform bool light_valid;       // false for a light that contributes nothing (skipped): shown black
uniform vec3 background_color;  // display (sRGB) colour outside the mask
uniform vec2 display_to_work;   // work pixels per display pixel (1 without a frame layer)
layout(location = 0) out vec4 color;
void main() {
    ivec2 px = min(ivec2(gl_FragCoord.xy * display_to_work), textureSize(albedo_mask, 0) - 1);
    vec4 am = texelFetch(albedo_mask, px, 0);
    if (am.a < 0.5) { color = vec4(background_color, 1.0); return; }
    vec4 pr = texelFetch(positions, px, 0);
    vec4 ns = texelFetch(normals, px, 0);
    vec3 c;
    if (view == INSPECT_ALBEDO) {
        c = linear_to_srgb(am.rgb);
    } else if (view == INSPECT_NORMAL) {
        c = ns.xyz * 0.5 + 0.5;
    } else if (view == INSPECT_DEPTH) {
        float span = max(depth_range.y - depth_range.x, 1e-9);
        c = vec3(clamp(1.0 - (-pr.z - depth_range.x) / span, 0.0, 1.0));
    } else if (view == INSPECT_SPECULAR) {
        c = vec3(clamp(ns.w, 0.0, 1.0));
    } else if (view == INSPECT_ROUGHNESS) {
        c = vec3(clamp(pr.w, 0.0, 1.0));
    } else {  // INSPECT_SHADOW
        vec4 b = light_valid ? texelFetch(light_plane, px - box_origin + tile_origin, 0) : vec4(0.0);
        // where the surface faces away from the light (no shading) the light's visibility is 0
        c = vec3(clamp(visibility_channel == VISIBILITY_SOFT ? b.x : b.y, 0.0, 1.0));
    }
    color = vec4(c, 1.0);
}
