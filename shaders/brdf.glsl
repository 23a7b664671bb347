// Shared BRDF: Lambert diffuse and the Disney principled specular lobe (GGX), per unit light
// intensity, the light treated as directional (the paper, Stage 1) except that its angular size
// widens the specular lobe (below). Included by every pass that shades; mirrored by
// viewer/twin/brdf.py. View vector (0, 0, 1) as in the paper.
// PI, MIN_ALPHA and SPECULAR_SCALE are #defines generated from viewer/constants.py.

float lambert_shading(vec3 n, vec3 l) {
    return max(dot(n, l), 0.0) / PI;
}

// Smith G1 in the form that already contains 1 / (2 n.x): 1 / (x + sqrt(a2 + x^2 - a2 x^2)).
float smith_g1(float x, float a2) {
    return 1.0 / (x + sqrt(a2 + x * x - a2 * x * x));
}

// GGX alpha of a lobe lit by a light of angular (Gaussian) sigma light_angle, in radians: the
// half vector spreads by half the light's angle, whose slope variance adds to the lobe's
// (alpha^2 ~ 2 x slope variance), so alpha'^2 = alpha^2 + light_angle^2 / 2. The roughness
// widening of Karis 2013 for sphere lights, in the variance form; D stays normalised, so the
// highlight keeps its energy and loses its peak. Capped at 1 (a fully rough lobe).
float widened_alpha(float roughness, float light_angle) {
    float alpha = max(roughness * roughness, MIN_ALPHA);
    return min(sqrt(alpha * alpha + 0.5 * light_angle * light_angle), 1.0);
}

// n.l * F * D * G for the Disney specular lobe with F0 = SPECULAR_SCALE * specular, alpha = roughness^2
// widened by the light's angular size (widened_alpha).
float disney_specular_shading(vec3 n, vec3 l, float specular, float roughness, float light_angle) {
    const vec3 v = vec3(0.0, 0.0, 1.0);
    float nl = dot(n, l);
    float nv = dot(n, v);
    if (nl <= 0.0 || nv <= 0.0 || specular <= 0.0) return 0.0;
    vec3 h = normalize(l + v);
    float nh = max(dot(n, h), 0.0);
    float lh = max(dot(l, h), 0.0);
    float alpha = widened_alpha(roughness, light_angle);
    float a2 = alpha * alpha;
    float f0 = SPECULAR_SCALE * specular;
    float m = 1.0 - lh;
    float m2 = m * m;
    float fresnel = f0 + (1.0 - f0) * (m2 * m2 * m);  // Schlick; cheaper than pow() on llvmpipe
    float t = nh * nh * (a2 - 1.0) + 1.0;
    float d = a2 / (PI * t * t);
    float g = smith_g1(nl, a2) * smith_g1(nv, a2);
    return nl * fresnel * d * g;
}
