// Equirectangular environment-map lookup (viewer/envmap.py convention): longitude
// phi = 2 pi u - pi, latitude lam = pi/2 - pi v (u, v in [0, 1], v = 0 the top row, +y), and
// direction (cos lam sin phi, sin lam, -cos lam cos phi).
vec2 direction_to_equirect(vec3 d) {
    d = normalize(d);
    float phi = atan(d.x, -d.z);
    float lam = asin(clamp(d.y, -1.0, 1.0));
    return vec2((phi + PI) / (2.0 * PI), (0.5 * PI - lam) / PI);
}

// The environment as a perspective camera sees it at pixel position q (pixels, row 0 at the top),
// turned by rotation (camera-space view direction -> map direction).
vec3 environment_seen(sampler2D environment, mat3 rotation, vec2 q, vec2 center, float focal) {
    vec3 view = normalize(vec3((q.x - center.x) / focal, -(q.y - center.y) / focal, -1.0));
    return textureLod(environment, direction_to_equirect(rotation * view), 0.0).rgb;
}
