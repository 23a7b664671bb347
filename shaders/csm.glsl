// Convolutional shadow map (Annen et al. 2007; the paper's DCSM): Fourier basis of the
// shadow-map depth z and reconstruction of soft visibility from the (pre-filtered) basis.
// TERMS Fourier terms, packed two per RGBA texture: (cos c_k z, sin c_k z, cos c_k+1 z, sin c_k+1 z),
// c_k = pi (2k - 1). The harmonics come from one sin/cos pair by rotation (two trig calls per
// texel instead of 2 TERMS). Mirrored by viewer/twin/csm.py.

#ifndef TERMS
#define TERMS 4
#endif
#define BASIS_TEXTURES ((TERMS + 1) / 2)

float csm_frequency(int k) {  // k = 0 .. TERMS-1
    return 3.14159265358979 * float(2 * k + 1);
}

// (cos c_k x, sin c_k x) for k = 0 .. TERMS-1, written into out_cs.
void csm_harmonics(float x, out vec2 out_cs[TERMS]) {
    float t = 3.14159265358979 * x;
    vec2 cs = vec2(cos(t), sin(t));
    vec2 rot = vec2(cs.x * cs.x - cs.y * cs.y, 2.0 * cs.x * cs.y);  // angle 2 pi x
    for (int k = 0; k < TERMS; ++k) {
        out_cs[k] = cs;
        cs = vec2(cs.x * rot.x - cs.y * rot.y, cs.y * rot.x + cs.x * rot.y);
    }
}

// Soft visibility of a receiver at normalised depth d from the filtered basis values (one vec4 per
// texture). offset and clamp_value come from viewer.shadow_space.csm_constants(TERMS).
float csm_visibility(vec4 basis[BASIS_TEXTURES], float d, float offset, float clamp_value) {
    vec2 h[TERMS];
    csm_harmonics(d - offset, h);
    float s = 0.0;
    for (int k = 0; k < TERMS; ++k) {
        vec4 b = basis[k / 2];
        vec2 f = (k % 2 == 0) ? b.xy : b.zw;  // (F[cos c z], F[sin c z])
        s += (2.0 / csm_frequency(k)) * (h[k].x * f.y - h[k].y * f.x);
    }
    return clamp((clamp(s, -clamp_value, clamp_value) + clamp_value) / (2.0 * clamp_value), 0.0, 1.0);
}
