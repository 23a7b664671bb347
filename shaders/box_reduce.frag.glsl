// Box average of factor x factor texel blocks of a basis atlas, tile by tile (tiles of tile_size
// texels in, tile_size / factor out): the further mip levels of the CSM basis, kept in a separate
// cheap pass so that the basis pass itself always has enough pixels to run in parallel.
uniform sampler2D source;
uniform int factor;
layout(location = 0) out vec4 result;
void main() {
    ivec2 origin = ivec2(gl_FragCoord.xy) * factor;
    vec4 sum = vec4(0.0);
    for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i)
            sum += texelFetch(source, origin + ivec2(i, j), 0);
    result = sum / float(factor * factor);
}
