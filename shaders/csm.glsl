// Convolutional shadow map (Annen et al. 2007; the paper's DCSM): Fourier basis of the
// shadow-map depth z and reconstruction of soft visibility from the (pre-filtered) basis.
// TERMS Fourier terms, packed two per RGBA tile, (cos c_k z, sin c_k z, cos c_k+1 z, sin c_k+1 z),
// c_k = pi (2k - 1); the BASIS_TILES tiles of n x n texels sit side by side in one texture (the
// basis atlas), so every pass binds one texture. Mirrored by viewer/twin/csm.py.

#ifndef TERMS
#error TERMS is defined by the engine (EngineOptions.terms)
#endif
#define BASIS_TILES ((TERMS + 1) / 2)

float csm_frequency(int k) {  // k = 0 .. TERMS-1
    return PI * float(2 * k + 1);
}

// The four basis values of tile t at depth z.
vec4 csm_basis(int t, float z) {
    float c0 = csm_frequency(2 * t);
    vec4 b = vec4(cos(c0 * z), sin(c0 * z), 0.0, 0.0);
    if (2 * t + 1 < TERMS) {
        float c1 = csm_frequency(2 * t + 1);
        b.zw = vec2(cos(c1 * z), sin(c1 * z));
    }
    return b;
}

// Bilinear lookup of tile t of a basis atlas at shadow-map coordinates uv, clamped to the tile's
// edge texels (so tiles never bleed into each other).
vec4 csm_fetch(sampler2D atlas, int t, vec2 uv) {
    float n = float(textureSize(atlas, 0).y);
    vec2 p = clamp(uv * n, vec2(0.5), vec2(n - 0.5));
    return texture(atlas, vec2((p.x + float(t) * n) / (n * float(BASIS_TILES)), p.y / n));
}

// Soft visibility of a receiver at normalised depth d from the filtered basis atlas.
// offset and clamp_value come from viewer.scene.shadow_space.csm_constants(TERMS).
float csm_visibility(sampler2D atlas, vec2 uv, float d, float offset, float clamp_value) {
    float dd = clamp(d, 0.0, 1.0) - offset;  // receivers pushed past the range must not wrap
    float t0 = PI * dd;
    vec2 cs = vec2(cos(t0), sin(t0));                                   // (cos c_k dd, sin c_k dd)
    vec2 rot = vec2(cs.x * cs.x - cs.y * cs.y, 2.0 * cs.x * cs.y);      // rotation by 2 pi dd
    float s = 0.0;
    for (int t = 0; t < BASIS_TILES; ++t) {
        vec4 b = csm_fetch(atlas, t, uv);                               // filtered (cos, sin) pairs
        for (int j = 0; j < 2; ++j) {
            int k = 2 * t + j;
            if (k >= TERMS) break;
            vec2 f = (j == 0) ? b.xy : b.zw;
            s += (2.0 / csm_frequency(k)) * (cs.x * f.y - cs.y * f.x);
            cs = vec2(cs.x * rot.x - cs.y * rot.y, cs.y * rot.x + cs.x * rot.y);
        }
    }
    return clamp((clamp(s, -clamp_value, clamp_value) + clamp_value) / (2.0 * clamp_value), 0.0, 1.0);
}
