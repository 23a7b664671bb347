// The background of the output frame in linear HDR, drawn once per background, map and rotation
// (the frame display only fetches it): the environment map seen through the frame's camera, the
// photo, or a colour (transparent: zero).
#include "envmap.glsl"
uniform sampler2D photo;              // linear RGB, frame resolution
uniform sampler2D environment;        // equirectangular, linear RGB
uniform int background_mode;          // BACKGROUND_*
uniform vec3 background_color;        // linear
uniform mat3 environment_rotation;    // camera-space view direction -> map direction
uniform float ground_squash;          // the map\'s ground seen from the camera\'s height (envmap.glsl: 1, as taken)
uniform vec2 focal_center_px;
uniform float focal_px;
layout(location = 0) out vec4 background;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 bg = background_mode == BACKGROUND_COLOR ? background_color : vec3(0.0);
    if (background_mode == BACKGROUND_PHOTO) {
        bg = texelFetch(photo, px, 0).rgb;
    } else if (background_mode == BACKGROUND_ENVIRONMENT) {
        bg = environment_seen(environment, environment_rotation, ground_squash, vec2(px) + 0.5, focal_center_px, focal_px);
    }
    background = vec4(bg, 1.0);
}
