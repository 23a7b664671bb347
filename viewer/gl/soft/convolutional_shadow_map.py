"""The paper's convolutional shadow maps (Annen et al. 2007): a Fourier basis of each light's shadow
map pre-filtered with its sigma (``shaders/csm.glsl``; ``EngineOptions.terms`` and ``prefilter``)."""

from __future__ import annotations

from viewer.gl.soft import SoftMethod, register_soft_method


@register_soft_method
class ConvolutionalShadowMap(SoftMethod):
    name = "csm"
    shader = "soft_csm.glsl"
    prefiltered = True

    def defines(self, light_pass) -> dict:
        return {"TERMS": light_pass.terms}

    def bind(self, light_pass, prog, group) -> None:
        prog["csm_offset"] = light_pass.csm_offset
        prog["csm_clamp"] = light_pass.csm_clamp

    def twin(self, depth, sigma, frames, u, v, d, bias, normal, terms):
        from viewer.twin.csm import twin_visibility

        return twin_visibility(depth, sigma, frames, u, v, d, bias, normal, terms)
