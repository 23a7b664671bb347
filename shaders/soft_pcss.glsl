// Contact-hardening soft shadows (viewer/gl/soft/contact_hardening.py): the soft visibility light_visibility.glsl
// asks for, from the shadow map itself, the penumbra as wide as the light's angular sigma makes it at
// the blocker's distance.
#include "pcss.glsl"

float soft_visibility(int j, sampler2D shadow_map, sampler2D filtered_basis, vec3 uvd, vec3 n, vec3 l, float bias) {
    return pcss_visibility(shadow_map, uvd, receiver_gradient(light_frame[j], n, l, max_slope), bias, light_alpha[j],
                           shadow_window, depth_scale[j]);
}
