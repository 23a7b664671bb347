"""What a photo's bundle is made from, hashed: the networks' weights, the pipeline's version and the
code its maps come from (a bundle cached by other code is inferred again), and the photo's and mask's
bytes with the sizes (:func:`bundle_key`, the cache's name for it)."""

from __future__ import annotations

from pathlib import Path

from viewer.errors import InputError
from viewer.files.kinds import regular_file
from viewer.photo import detail as detail_mod
from viewer.photo.frames import MAX_SIZE, WORK_PERSON
from viewer.resources import network_dir

NETWORKS = ("inverse", "depth")
PIPELINE = "frame-8"  # bundles cached by an older pipeline are inferred again (frame-8: the photo's lens in the frame)
# the code a bundle's maps come from: the photo path, the networks, the scene types, the lighting and
# the engine that renders the photo's own shading, and the shaders
CODE = ("photo", "nets", "scene", "lighting", "gl", "twin", "files")


def code_files() -> list[Path]:
    """Every ``.py`` of ``CODE`` and of the package's root, and the shaders."""
    from viewer.resources import shader_dir

    package = Path(__file__).resolve().parents[1]
    return (sorted(package.glob("*.py")) + sorted(f for part in CODE for f in (package / part).rglob("*.py"))
            + sorted(shader_dir().glob("*.glsl")))


def code_digest() -> str:
    """The SHA-256 of :func:`code_files`: a bundle cached by other code is inferred again, whether
    or not someone remembered to change ``PIPELINE``."""
    import hashlib

    h = hashlib.sha256()
    for f in code_files():
        h.update(f"{f.parent.name}/{f.name}".encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def inference_version(networks_dir=None) -> str:
    """The networks' weights, the pipeline's version and its code (:func:`code_digest`), hashed:
    what every bundle is made with."""
    import hashlib

    h = hashlib.sha256(f"{PIPELINE} {detail_mod.DEFAULT} {code_digest()}".encode())
    networks_dir = Path(networks_dir) if networks_dir is not None else network_dir()
    for path in (networks_dir / f"{n}.safetensors" for n in NETWORKS):
        if not path.is_file():
            raise InputError(path, "not found")
        h.update(path.read_bytes())
    return h.hexdigest()


def bundle_key(photo_path, mask_path=None, size: int = WORK_PERSON, max_size: int = MAX_SIZE, networks_dir=None,
               version: str | None = None, digests: dict | None = None) -> str:
    """What a photo's bundle is made from, hashed: the photo's and mask's bytes, the sizes and the
    :func:`inference_version` (``version``: already computed, for many photos); a missing file is
    one line naming it. ``digests`` (when given) gets the SHA-256 of each file's bytes as read here,
    under "photo" and "mask" (each file is read once)."""
    import hashlib

    h = hashlib.sha256((version or inference_version(networks_dir)).encode())
    for path, what in ((photo_path, "photo"), *([(mask_path, "mask")] if mask_path is not None else [])):
        data = regular_file(path, what).read_bytes()
        h.update(data)
        if digests is not None:
            digests[what] = hashlib.sha256(data).hexdigest()
    h.update(f"{size} {max_size} {mask_path is None}".encode())
    return h.hexdigest()
