// Minimum of factor x factor texel blocks of a depth map (channel r): each block's depth nearest to
// the light. Chained, these give the coarse map the contact-hardening soft shadows' blocker search
// reads first (pcss.glsl: a receiver nearer than every depth around it has no blocker).
uniform sampler2D source;
uniform int factor;
layout(location = 0) out vec4 result;
void main() {
    ivec2 origin = ivec2(gl_FragCoord.xy) * factor;
    ivec2 last = textureSize(source, 0) - 1;
    float m = texelFetch(source, min(origin, last), 0).r;
    for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i)
            m = min(m, texelFetch(source, min(origin + ivec2(i, j), last), 0).r);
    result = vec4(m);
}
