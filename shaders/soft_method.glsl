// The soft-shadow method's GLSL (its soft_visibility), included by light_visibility.glsl: the engine
// gives its method's text in this file's place (viewer/gl/soft/, ProgramCache.get's sources); a shader
// compiled alone (its tests, a tool) gets the paper's convolutional shadow maps.
#include "soft_csm.glsl"
