// One separable Gaussian pass over the CSM basis textures (clamp-to-edge), at mip level `level`
// of the source. Cost is 2 radius + 1 taps whatever the light's sigma: the engine picks the
// pyramid level so that the residual sigma stays small (viewer/gl/prefilter.py).
#include "csm.glsl"
uniform sampler2D source[BASIS_TEXTURES];
uniform int level;
uniform ivec2 axis;      // (1, 0) horizontal or (0, 1) vertical
uniform int radius;
uniform float sigma;     // in texels of this level
uniform float norm;      // 1 / sum of the weights
layout(location = 0) out vec4 result[BASIS_TEXTURES];
void main() {
    ivec2 size = textureSize(source[0], level);
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 acc[BASIS_TEXTURES];
    for (int t = 0; t < BASIS_TEXTURES; ++t) acc[t] = vec4(0.0);
    float inv = -0.5 / max(sigma * sigma, 1e-12);
    for (int i = -radius; i <= radius; ++i) {
        float w = exp(float(i * i) * inv);
        ivec2 q = clamp(p + axis * i, ivec2(0), size - 1);
        for (int t = 0; t < BASIS_TEXTURES; ++t) acc[t] += w * texelFetch(source[t], q, level);
    }
    for (int t = 0; t < BASIS_TEXTURES; ++t) result[t] = acc[t] * norm;
}
