// One separable Gaussian pass over a basis atlas, clamp-to-edge within each tile. The taps run over
// the tile's texels only (at most tile_size of them): the weight of the taps the clamp would put on
// an edge texel is added to that texel once, so a kernel wider than the tile (the exact prefilter of
// a wide light: 6 sigma can be 6 tiles) costs no more than the tile. Pyramid levels keep the residual
// sigma small (viewer/gl/prefilter.py), so there the kernel is short anyway.
#include "gaussian_mass.glsl"
uniform sampler2D source;
uniform int tile_size;
uniform ivec2 axis;      // (1, 0) horizontal or (0, 1) vertical
uniform int radius;
uniform float sigma;     // in texels of this level
uniform float norm;      // 1 / sum of the weights over [-radius, radius]
layout(location = 0) out vec4 result;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    int x0 = (p.x / tile_size) * tile_size;
    ivec2 lo = ivec2(x0, 0);
    ivec2 hi = ivec2(x0 + tile_size - 1, tile_size - 1);
    int along = p.x * axis.x + p.y * axis.y;
    int first = lo.x * axis.x + lo.y * axis.y - along;  // the lowest offset still inside the tile
    int last = hi.x * axis.x + hi.y * axis.y - along;
    float inv = -0.5 / max(sigma * sigma, 1e-12);
    vec4 acc = vec4(0.0);
    float inside = 0.0;
    for (int i = max(-radius, first); i <= min(radius, last); ++i) {
        float w = exp(float(i * i) * inv);
        acc += w * texelFetch(source, p + axis * i, 0);
        inside += w;
    }
    float outside = max(1.0 / norm - inside, 0.0);  // the clamped taps' weight, shared by the two edges
    float below = first > -radius ? gaussian_mass(float(-radius) - 0.5, float(first) - 0.5, sigma) : 0.0;
    float above = last < radius ? gaussian_mass(float(last) + 0.5, float(radius) + 0.5, sigma) : 0.0;
    float share = below / max(below + above, 1e-30);
    acc += outside * (share * texelFetch(source, p + axis * first, 0)
                      + (1.0 - share) * texelFetch(source, p + axis * last, 0));
    result = acc * norm;
}
