// Exposure, tone mapping and the sRGB transfer function for display images.
vec3 tonemap_neutral(vec3 x) {
    // The photo's own tones: linear up to TONEMAP_KNEE on the brightest channel; above it that
    // channel is compressed towards 1 (1 - d^2 / (peak + d - knee), d = 1 - knee: the knee's value
    // and slope are kept) and the colour scaled with it, so hue and saturation stay; then what was
    // compressed away moves it towards white by TONEMAP_DESATURATION (Khronos PBR Neutral's shoulder,
    // without its toe, which would change the photo's darks).
    x = clamp(x, vec3(0.0), vec3(TONEMAP_INPUT_MAX));
    float peak = max(x.r, max(x.g, x.b));
    if (peak <= TONEMAP_KNEE) return x;
    float d = 1.0 - TONEMAP_KNEE;
    float top = 1.0 - d * d / (peak + d - TONEMAP_KNEE);
    float g = 1.0 - 1.0 / (TONEMAP_DESATURATION * (peak - top) + 1.0);
    return mix(x * (top / peak), vec3(top), g);
}
vec3 tonemap_aces(vec3 x) {  // Narkowicz 2015 fit of the ACES filmic curve, per channel
    x = clamp(x, vec3(0.0), vec3(TONEMAP_INPUT_MAX));  // the curve is 1 long before; beyond, x^2 would overflow
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}
vec3 tonemap_reinhard(vec3 x) {
    x = clamp(x, vec3(0.0), vec3(1e30));
    return x / (1.0 + x);
}
vec3 tonemap(vec3 x, int op) {
    if (op == TONEMAP_NEUTRAL) return tonemap_neutral(x);
    if (op == TONEMAP_ACES) return tonemap_aces(x);
    if (op == TONEMAP_REINHARD) return tonemap_reinhard(x);
    return clamp(x, 0.0, 1.0);
}
vec3 linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
