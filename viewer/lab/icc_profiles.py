"""ICC profiles of wide-gamut RGB spaces (Adobe RGB (1998), Display P3), written here from their
published primaries, white point and tone curve: photos in these spaces for the colour-management
tests and the campaign, without profile files from the internet. A v2 matrix/TRC display profile
(ICC.1:2001-04): header, tag table, the description, the media white point, the three colorants
(adapted to the PCS's D50 by Bradford, as ICC requires) and one tone curve per channel."""

from __future__ import annotations

import struct

import numpy as np

D50 = np.array([0.9642, 1.0, 0.8249])
BRADFORD = np.array([[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]])

# (name, primaries xy of R, G, B, white xy, gamma)
ADOBE_RGB = ("Adobe RGB (1998) compatible", ((0.64, 0.33), (0.21, 0.71), (0.15, 0.06)), (0.3127, 0.3290), 563 / 256)
DISPLAY_P3 = ("Display P3 compatible (gamma 2.2)", ((0.680, 0.320), (0.265, 0.690), (0.150, 0.060)), (0.3127, 0.3290), 2.2)


def _xyz(xy) -> np.ndarray:
    x, y = xy
    return np.array([x / y, 1.0, (1 - x - y) / y])


def colorants(primaries, white) -> np.ndarray:
    """(3, 3) columns: the XYZ of R, G, B at full value, scaled so they sum to ``white`` (Y = 1),
    then adapted from ``white`` to D50 (Bradford)."""
    p = np.stack([_xyz(c) for c in primaries], axis=1)
    w = _xyz(white)
    m = p * np.linalg.solve(p, w)[None, :]
    adapt = np.linalg.inv(BRADFORD) @ np.diag((BRADFORD @ D50) / (BRADFORD @ w)) @ BRADFORD
    return adapt @ m


def _s15(v: float) -> bytes:
    return struct.pack(">i", int(round(v * 65536)))


def _xyz_tag(v) -> bytes:
    return b"XYZ " + bytes(4) + b"".join(_s15(c) for c in v)


def _curve(gamma: float) -> bytes:
    return b"curv" + bytes(4) + struct.pack(">IH", 1, int(round(gamma * 256))) + bytes(2)  # padded to 4 bytes


def _desc(text: str) -> bytes:
    ascii_ = text.encode("ascii") + b"\0"
    return b"desc" + bytes(4) + struct.pack(">I", len(ascii_)) + ascii_ + struct.pack(">II", 0, 0) + struct.pack(">HB", 0, 0) + bytes(67)


def _pad(b: bytes) -> bytes:
    return b + bytes(-len(b) % 4)


def matrix_trc_profile(space=ADOBE_RGB) -> bytes:
    """The ICC profile (bytes) of ``space`` (name, primaries, white, gamma)."""
    name, primaries, white, gamma = space
    m = colorants(primaries, white)
    curve = _curve(gamma)
    tags = [(b"desc", _desc(name)), (b"wtpt", _xyz_tag(D50)), (b"rXYZ", _xyz_tag(m[:, 0])), (b"gXYZ", _xyz_tag(m[:, 1])),
            (b"bXYZ", _xyz_tag(m[:, 2])), (b"rTRC", curve), (b"gTRC", curve), (b"bTRC", curve),
            (b"cprt", _pad(b"text" + bytes(4) + b"no copyright, use freely\0"))]
    offset = 128 + 4 + 12 * len(tags)
    table, data = b"", b""
    for sig, body in tags:
        body = _pad(body)
        table += sig + struct.pack(">II", offset + len(data), len(body))
        data += body
    size = offset + len(data)
    header = (struct.pack(">I", size) + b"lcms" + struct.pack(">I", 0x02100000) + b"mntr" + b"RGB " + b"XYZ "
              + struct.pack(">6H", 2026, 11, 28, 0, 0, 0) + b"acsp" + bytes(4) + struct.pack(">I", 0) + bytes(4) + bytes(4)
              + bytes(8) + struct.pack(">I", 0) + b"".join(_s15(c) for c in D50) + bytes(4) + bytes(16) + bytes(28))
    assert len(header) == 128
    return header + struct.pack(">I", len(tags)) + table + data
