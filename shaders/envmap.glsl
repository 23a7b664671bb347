// Equirectangular environment-map lookup (viewer/envmap.py convention): longitude
// phi = 2 pi u - pi, latitude lam = pi/2 - pi v (u, v in [0, 1], v = 0 the top row, +y), and
// direction (cos lam sin phi, sin lam, -cos lam cos phi).
vec2 direction_to_equirect(vec3 d) {
    d = normalize(d);
    float phi = atan(d.x, -d.z);
    float lam = asin(clamp(d.y, -1.0, 1.0));
    return vec2((phi + 3.14159265358979) / (2.0 * 3.14159265358979), (1.5707963267949 - lam) / 3.14159265358979);
}
