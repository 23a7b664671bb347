// Basis atlas of one shadow map (convolutional shadow map, before the Gaussian): tile t holds
// Fourier terms 2t and 2t+1, averaged over block x block shadow-map texels. That average is mip
// level log2(block) of the basis, computed directly so that wide Gaussians run on a small map
// (viewer/gl/prefilter.py).
#include "csm.glsl"
uniform sampler2D shadow_map;
uniform int block;
uniform int tile_size;
uniform float empty_depth;   // texels no triangle covers: their basis is one constant per tile
layout(location = 0) out vec4 basis;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    int t = p.x / tile_size;
    ivec2 origin = ivec2(p.x - t * tile_size, p.y) * block;
    vec4 empty = csm_basis(t, empty_depth);
    vec4 sum = vec4(0.0);
    for (int j = 0; j < block; ++j) {
        for (int i = 0; i < block; ++i) {
            float z = texelFetch(shadow_map, origin + ivec2(i, j), 0).r;
            sum += (z == empty_depth) ? empty : csm_basis(t, z);
        }
    }
    basis = sum / float(block * block);
}
