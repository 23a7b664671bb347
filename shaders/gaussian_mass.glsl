// The mass of a centred Gaussian of standard deviation sigma between a and b (in units of sigma's):
// 0.5 (erf(b / (sigma sqrt 2)) - erf(a / (sigma sqrt 2))), with Abramowitz & Stegun's 7.1.26 erf
// (absolute error <= 1.5e-7). Used to share the weight of clamped taps between two edges.
float erf_approx(float x) {
    float t = 1.0 / (1.0 + 0.3275911 * abs(x));
    float y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t
              * exp(-x * x);
    return sign(x) * y;
}

float gaussian_mass(float a, float b, float sigma) {
    float k = 0.7071067811865476 / max(sigma, 1e-6);
    return max(0.5 * (erf_approx(b * k) - erf_approx(a * k)), 0.0);
}
