// Fourier basis maps of one shadow map (convolutional shadow map, before pre-filtering).
#include "csm.glsl"
uniform sampler2D shadow_map;
layout(location = 0) out vec4 basis[BASIS_TEXTURES];
void main() {
    float z = texelFetch(shadow_map, ivec2(gl_FragCoord.xy), 0).r;
    vec2 h[TERMS];
    csm_harmonics(z, h);
    for (int t = 0; t < BASIS_TEXTURES; ++t) {
        vec2 second = (2 * t + 1 < TERMS) ? h[2 * t + 1] : vec2(0.0);
        basis[t] = vec4(h[2 * t], second);
    }
}
