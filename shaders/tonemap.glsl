// Exposure, tone mapping and the sRGB transfer function for display images.
vec3 tonemap_aces(vec3 x) {  // Narkowicz 2015 fit of the ACES filmic curve
    x = clamp(x, vec3(0.0), vec3(TONEMAP_INPUT_MAX));  // the curve is 1 long before; beyond, x^2 would overflow
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}
vec3 tonemap_reinhard(vec3 x) {
    x = clamp(x, vec3(0.0), vec3(1e30));
    return x / (1.0 + x);
}
vec3 tonemap(vec3 x, int op) {
    if (op == TONEMAP_ACES) return tonemap_aces(x);
    if (op == TONEMAP_REINHARD) return tonemap_reinhard(x);
    return clamp(x, 0.0, 1.0);
}
vec3 linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
