// Basis atlas of one shadow map (convolutional shadow map, before the Gaussian): tile t holds
// Fourier terms 2t and 2t+1, averaged over block x block shadow-map texels. That average is mip
// level log2(block) of the basis, computed directly so that wide Gaussians run on a small map
// (viewer/gl/prefilter.py). Blocks are read four texels at a time with textureGather.
#include "csm.glsl"
uniform sampler2D shadow_map;
uniform int block;
uniform int tile_size;
uniform float empty_depth;   // texels no triangle covers: their basis is one constant per tile
layout(location = 0) out vec4 basis;

vec4 texel_basis(int t, float z, vec4 empty) {
    return (z == empty_depth) ? empty : csm_basis(t, z);
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    int t = p.x / tile_size;
    ivec2 origin = ivec2(p.x - t * tile_size, p.y) * block;
    vec4 empty = csm_basis(t, empty_depth);
    if (block == 1) {
        basis = texel_basis(t, texelFetch(shadow_map, origin, 0).r, empty);
        return;
    }
    vec2 inv_size = 1.0 / vec2(textureSize(shadow_map, 0));
    vec4 sum = vec4(0.0);
    for (int j = 0; j < block; j += 2) {
        for (int i = 0; i < block; i += 2) {
            vec4 z = textureGather(shadow_map, vec2(origin + ivec2(i + 1, j + 1)) * inv_size);
            if (all(equal(z, vec4(empty_depth)))) {
                sum += 4.0 * empty;
            } else {
                sum += texel_basis(t, z.x, empty) + texel_basis(t, z.y, empty) + texel_basis(t, z.z, empty) + texel_basis(t, z.w, empty);
            }
        }
    }
    basis = sum / float(block * block);
}
