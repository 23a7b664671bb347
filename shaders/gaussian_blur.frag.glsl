// One separable Gaussian pass over a basis atlas, clamp-to-edge within each tile. Cost is
// 2 radius + 1 taps whatever the light's sigma: the engine picks the pyramid level so that the
// residual sigma stays small (viewer/gl/prefilter.py).
uniform sampler2D source;
uniform int tile_size;
uniform ivec2 axis;      // (1, 0) horizontal or (0, 1) vertical
uniform int radius;
uniform float sigma;     // in texels of this level
uniform float norm;      // 1 / sum of the weights
layout(location = 0) out vec4 result;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    int x0 = (p.x / tile_size) * tile_size;
    ivec2 lo = ivec2(x0, 0);
    ivec2 hi = ivec2(x0 + tile_size - 1, tile_size - 1);
    float inv = -0.5 / max(sigma * sigma, 1e-12);
    vec4 acc = vec4(0.0);
    for (int i = -radius; i <= radius; ++i) {
        acc += exp(float(i * i) * inv) * texelFetch(source, clamp(p + axis * i, lo, hi), 0);
    }
    result = acc * norm;
}
