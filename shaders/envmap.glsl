// Equirectangular environment-map lookup (viewer/lighting/envmap.py convention): longitude
// phi = 2 pi u - pi, latitude lam = pi/2 - pi v (u, v in [0, 1], v = 0 the top row, +y), and
// direction (cos lam sin phi, sin lam, -cos lam cos phi).
vec2 direction_to_equirect(vec3 d) {
    d = normalize(d);
    float phi = atan(d.x, -d.z);
    float lam = asin(clamp(d.y, -1.0, 1.0));
    return vec2((phi + PI) / (2.0 * PI), (0.5 * PI - lam) / PI);
}

// A cubic B-spline lookup from four bilinear ones (Sigg and Hadwiger 2005): a magnified map shows
// no texel's square and no bilinear cross, wherever the window is larger than the map.
vec3 bicubic(sampler2D image, vec2 uv) {
    vec2 size = vec2(textureSize(image, 0));
    vec2 p = uv * size - 0.5;
    vec2 f = fract(p);
    vec2 f2 = f * f, f3 = f2 * f;
    vec2 w0 = (1.0 - 3.0 * f + 3.0 * f2 - f3) / 6.0;
    vec2 w1 = (4.0 - 6.0 * f2 + 3.0 * f3) / 6.0;
    vec2 w2 = (1.0 + 3.0 * f + 3.0 * f2 - 3.0 * f3) / 6.0;
    vec2 w3 = f3 / 6.0;
    vec2 g0 = w0 + w1, g1 = w2 + w3;
    vec2 c = floor(p) + 0.5;
    vec2 t0 = (c - 1.0 + w1 / g0) / size, t1 = (c + 1.0 + w3 / g1) / size;
    return g0.y * (g0.x * textureLod(image, vec2(t0.x, t0.y), 0.0).rgb + g1.x * textureLod(image, vec2(t1.x, t0.y), 0.0).rgb)
         + g1.y * (g0.x * textureLod(image, vec2(t0.x, t1.y), 0.0).rgb + g1.x * textureLod(image, vec2(t1.x, t1.y), 0.0).rgb);
}

// The map's ground seen from a camera that stands higher or lower than the map was taken from: a ray
// below the horizon meets the ground plane (the camera h metres above it) at the point the map's own
// camera (h_map above it) sees along the direction with its height scaled by squash = h_map / h. The
// horizon stays; the ground's paving, grass and shadows take the size they have at the person's feet.
// 1: the map as it was taken. Also returns how many times finer the map's rows are looked up there
// (the mipmap level follows the squashed footprint, no aliasing where the ground is compressed).
vec3 ground_projected(vec3 d, float squash, out float finer) {
    finer = 1.0;
    if (d.y >= 0.0 || squash == 1.0) return d;
    float c2 = dot(d.xz, d.xz), s = -d.y;
    vec3 e = normalize(vec3(d.x, d.y * squash, d.z));
    // d(latitude')/d(latitude) for latitude' = atan(squash tan latitude)
    finer = squash * (c2 + s * s) / max(c2 + squash * squash * s * s, 1e-12);
    return e;
}

// The environment as a perspective camera sees it at pixel position q (pixels, row 0 at the top),
// turned by rotation (camera-space view direction -> map direction), its ground seen from the camera's
// height (ground_projected's squash): bicubic where a pixel is smaller than a texel, else the mipmap
// level of the pixel's footprint (no aliasing of a large map).
vec3 environment_seen(sampler2D environment, mat3 rotation, float squash, vec2 q, vec2 center, float focal) {
    vec3 view = normalize(vec3((q.x - center.x) / focal, -(q.y - center.y) / focal, -1.0));
    float finer;
    vec2 uv = direction_to_equirect(ground_projected(rotation * view, squash, finer));
    float texels_per_pixel = float(textureSize(environment, 0).x) / (2.0 * PI * focal) * max(finer, 1.0);
    return texels_per_pixel <= 1.0 ? bicubic(environment, uv) : textureLod(environment, uv, log2(texels_per_pixel)).rgb;
}
