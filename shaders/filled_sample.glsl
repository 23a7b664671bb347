// Sampling a work-resolution image that holds values only inside the person's mask, at any point
// of the frame: the image is premultiplied by the mask (alpha = coverage) and mipmapped, so a
// bilinear lookup divided by its alpha is a normalized convolution: the person's values are
// averaged, the empty background never mixes in. Where no masked texel is near (a frame pixel on
// the soft matte's fringe outside the work mask), coarser mip levels reach further.
// FILLED_MIN_COVERAGE: a #define generated from viewer/constants.py

vec3 filled_sample(sampler2D image, vec2 uv, int max_lod) {
    vec4 s = textureLod(image, uv, 0.0);
    for (int lod = 1; s.a < FILLED_MIN_COVERAGE && lod <= max_lod; ++lod) {
        s = textureLod(image, uv, float(lod));
    }
    return s.a > 1e-6 ? s.rgb / s.a : vec3(0.0);
}
