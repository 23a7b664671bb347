"""U-Nets: one encoder, any number of decoders, each ending in its own 1x1 head.

The paper's inverse-rendering network is one encoder with three decoders (normal; albedo +
specular + roughness; lights) and its depth network a single decoder with a 1x1 last layer and a
sigmoid. ``width`` (channels of the first level, doubled per level) and ``levels`` are the
network-size knob. The lights come from a :class:`VectorHead` on the bottleneck.
"""

from __future__ import annotations

import torch
from torch import nn


def _block(c_in: int, c_out: int) -> nn.Sequential:
    groups = 8 if c_out % 8 == 0 else 1
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, padding=1, bias=False), nn.GroupNorm(groups, c_out), nn.SiLU(inplace=True),
        nn.Conv2d(c_out, c_out, 3, padding=1, bias=False), nn.GroupNorm(groups, c_out), nn.SiLU(inplace=True),
    )


class Encoder(nn.Module):
    def __init__(self, in_channels: int, width: int, levels: int):
        super().__init__()
        chans = [width * 2**k for k in range(levels)]
        self.channels = chans
        self.blocks = nn.ModuleList([_block(in_channels, chans[0])] + [_block(a, b) for a, b in zip(chans[:-1], chans[1:])])
        self.pool = nn.AvgPool2d(2)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        skips = []
        for k, block in enumerate(self.blocks):
            x = block(x if k == 0 else self.pool(x))
            skips.append(x)
        return skips  # finest first; the last is the bottleneck


class Decoder(nn.Module):
    def __init__(self, channels: list[int], out_channels: int):
        super().__init__()
        rev = channels[::-1]
        self.ups = nn.ModuleList([nn.Conv2d(a, b, 1) for a, b in zip(rev[:-1], rev[1:])])
        self.blocks = nn.ModuleList([_block(2 * b, b) for b in rev[1:]])
        self.head = nn.Conv2d(channels[0], out_channels, 1)

    def forward(self, skips: list[torch.Tensor]) -> torch.Tensor:
        x = skips[-1]
        for up, block, skip in zip(self.ups, self.blocks, skips[-2::-1]):
            x = nn.functional.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            x = block(torch.cat([up(x), skip], dim=1))
        return self.head(x)


class VectorHead(nn.Module):
    """A vector from the bottleneck (the paper's lights decoder): mean- and max-pooled features
    through a two-layer perceptron."""

    def __init__(self, channels: int, out_features: int, hidden: int = 256):
        super().__init__()
        self.mlp = nn.Sequential(nn.Linear(2 * channels, hidden), nn.SiLU(inplace=True), nn.Linear(hidden, out_features))

    def forward(self, skips: list[torch.Tensor]) -> torch.Tensor:
        x = skips[-1]
        return self.mlp(torch.cat([x.mean(dim=(2, 3)), x.amax(dim=(2, 3))], dim=1))


class UNet(nn.Module):
    """``outputs``: decoder name -> output channels (images); ``vectors``: head name -> features
    (vectors from the bottleneck); ``inputs``: names of what the input channels hold (recorded in
    the card). Input sides must be divisible by 2^(levels-1)."""

    def __init__(self, in_channels: int, outputs: dict[str, int], width: int = 16, levels: int = 5,
                 vectors: dict[str, int] | None = None, inputs: list[str] | None = None):
        super().__init__()
        vectors = dict(vectors or {})
        self.config = {"in_channels": in_channels, "outputs": dict(outputs), "width": width, "levels": levels}
        if vectors:
            self.config["vectors"] = vectors
        if inputs:  # what the input channels are (viewer.nets.photo.INPUTS); absent: photo and mask
            self.config["inputs"] = list(inputs)
        self.encoder = Encoder(in_channels, width, levels)
        self.decoders = nn.ModuleDict({name: Decoder(self.encoder.channels, c) for name, c in outputs.items()})
        self.heads = nn.ModuleDict({name: VectorHead(self.encoder.channels[-1], n) for name, n in vectors.items()})
        self.multiple = 2 ** (levels - 1)

    def forward(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        h, w = x.shape[-2:]
        if h % self.multiple or w % self.multiple:
            raise ValueError(f"input {h}x{w} is not a multiple of {self.multiple}")
        skips = self.encoder(x)
        out = {name: dec(skips) for name, dec in self.decoders.items()}
        out.update({name: head(skips) for name, head in self.heads.items()})
        return out
