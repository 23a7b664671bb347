"""Contact-hardening soft shadows (PCSS): the light's sigma read as an angle, so a penumbra is sharp
where the blocker touches and widens with the distance to it (``shaders/pcss.glsl``, docs/engine.md);
the presets' method."""

from __future__ import annotations

from viewer.gl.soft import SoftMethod, register_soft_method
from viewer.scene import shadow_space as ss


@register_soft_method
class ContactHardening(SoftMethod):
    name = "pcss"
    shader = "soft_pcss.glsl"

    def defines(self, light_pass) -> dict:
        return {"PCSS_TAPS": ss.PCSS_TAPS, "PCSS_SEARCH_TAPS": ss.PCSS_SEARCH_TAPS}

    def bind(self, light_pass, prog, group) -> None:
        prog["shadow_window"] = group[0].frame.texel_world(light_pass.resolution) * light_pass.resolution
        prog["pcss_taps"].write(light_pass.pcss_taps)
        prog["pcss_search_taps"].write(light_pass.pcss_search_taps)
        prog["pcss_search"] = ss.PCSS_SEARCH
        prog["pcss_min_texels"] = light_pass.pcss_min_texels

    def twin(self, depth, sigma, frames, u, v, d, bias, normal, terms):
        from viewer.twin.pcss import twin_visibility

        return twin_visibility(depth, sigma, frames, u, v, d, bias, normal, terms)
