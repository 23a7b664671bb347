// Receiver coordinates in a light's shadow map and the hard shadow test, robust at grazing angles:
// the receiver is pushed along its normal and the depth bias grows with the slope.
// The numpy statement of this rule is viewer.scene.shadow_space.receiver_coordinates.

uniform float texel_world;    // world size of one shadow-map texel (the same for every light)
uniform float hard_threshold;
uniform float normal_offset_texels;
uniform float slope_bias_texels;
uniform float max_slope;
uniform float empty_depth;     // normalised depth of texels no triangle covers (the same for every light)

// frame: camera space -> (u, v, z, 1), z = normalised depth (0 at the light)
vec3 receiver_uvd(mat4 frame, vec3 p, vec3 n) {
    vec3 q = p + n * (normal_offset_texels * texel_world);
    return (frame * vec4(q, 1.0)).xyz;
}

// l: unit direction to the light; depth_scale: metres per unit of normalised depth
float receiver_bias(vec3 n, vec3 l, float depth_scale) {
    float c = abs(dot(n, l));
    float t = min(sqrt(max(1.0 - c * c, 0.0)) / max(c, 1e-6), max_slope);
    return hard_threshold + slope_bias_texels * texel_world * t / depth_scale;
}

// The shadow map's depth in the texel containing uv (clamped to the map).
float shadow_depth(sampler2D shadow_map, vec2 uv) {
    ivec2 size = textureSize(shadow_map, 0);
    ivec2 texel = clamp(ivec2(floor(uv * vec2(size))), ivec2(0), size - 1);
    return texelFetch(shadow_map, texel, 0).r;
}

float hard_visibility(sampler2D shadow_map, vec3 uvd, float bias) {
    return (uvd.z - bias <= shadow_depth(shadow_map, uvd.xy)) ? 1.0 : 0.0;
}
