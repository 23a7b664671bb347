// The paper's convolutional shadow maps (viewer/gl/soft/convolutional_shadow_map.py): the soft visibility light_visibility.glsl
// asks for, from the light's Fourier basis pre-filtered with its sigma.
#include "csm.glsl"

uniform float csm_offset;
uniform float csm_clamp;

float soft_visibility(int j, sampler2D shadow_map, sampler2D filtered_basis, vec3 uvd, vec3 n, vec3 l, float bias) {
    return csm_visibility(filtered_basis, uvd.xy, uvd.z, csm_offset, csm_clamp);
}
