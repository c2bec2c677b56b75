"""A drop-in's textures as the image files an engine imports, with the import settings that keep
them data, and the engine's reading of those files back (what ``check_drop_in`` binds).

Every texture becomes RGBA, the channels it lacks 0 and its alpha 1 (what a GPU returns for a
texture of fewer channels): float32 texels as a float EXR, half texels as a half EXR, 8-bit texels
as an 8-bit PNG; 16-bit normalised texels as the floats q / 65535 they stand for (exact in float32).
Rows: the network reads texel (x, y) with ``Load``, y counted from the first row of memory. Unity
stores an imported image bottom row first (its texture origin is the bottom left), Unreal top row
first; so the file for Unity holds the rows bottom-up and the file for Unreal top-down.
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.codegen.glsl import TextureResource
from inshade.codegen.targets import TargetError

# engine -> whether the first row of an imported image is the last row of texture memory
BOTTOM_UP = {"unity": True, "unreal": False}
# texel dtype -> (file format, the texels as the file holds them, the dtype the engine's texture has)
FORMATS = {"f4": ("exr float", np.float32, "f4"), "nu2": ("exr float", np.float32, "f4"),
           "f2": ("exr half", np.float16, "f2"), "f1": ("png 8-bit", np.uint8, "f1")}
SUFFIX = {"exr float": ".exr", "exr half": ".exr", "png 8-bit": ".png"}


@dataclass(frozen=True)
class TextureFile:
    name: str          # the network's texture (the function's argument, the node's texture input)
    file: str          # the image file's name
    format: str        # "exr float", "exr half" or "png 8-bit"
    width: int
    height: int
    filtered: bool     # read through a bilinear sampler (else point sampled)
    wrap: str          # clamp | repeat


def texture_files(resources, engine: str, stem: str) -> list[tuple[TextureFile, np.ndarray]]:
    """(the record, the RGBA pixels in file row order) of each texture in ``resources``; TargetError
    naming a texture an engine import cannot make (3D, an array, mip levels, integer texels)."""
    out = []
    for r in resources:
        why = ("not a texture" if not isinstance(r, TextureResource) else "a 3D texture" if r.dims == 3
               else "a texture array" if r.array else "mip levels" if r.mips
               else "integer texels" if r.dtype not in FORMATS else None)
        if why:
            raise TargetError(f"{engine}: {r.name}: {why}, which this drop-in does not import as an image file "
                              "yet; use --target hlsl without --engine and bind it yourself")
        fmt, kind, _ = FORMATS[r.dtype]
        data = np.asarray(r.data)
        if r.dtype == "nu2":
            data = data.astype(np.float32) / np.float32(65535.0)
        h, w, c = data.shape
        rgba = np.zeros((h, w, 4), kind)
        rgba[..., 3] = 255 if kind is np.uint8 else 1.0
        rgba[..., :c] = data
        rows = rgba[::-1] if BOTTOM_UP[engine] else rgba
        out.append((TextureFile(r.name, f"{r.name}{SUFFIX[fmt]}", fmt, w, h, r.filter == "linear", r.wrap),
                    np.ascontiguousarray(rows)))
    return out


def image_bytes(record: TextureFile, pixels: np.ndarray) -> bytes:
    """The image file of ``pixels`` (RGBA, file row order)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / record.file
        if record.format == "png 8-bit":
            from PIL import Image

            Image.fromarray(pixels, "RGBA").save(path, format="PNG")
        else:
            import OpenEXR

            header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
            with OpenEXR.File(header, {"RGBA": pixels}) as exr:
                exr.write(str(path))
        return path.read_bytes()


def engine_texture(record: TextureFile, path: Path, engine: str, resource: TextureResource) -> TextureResource:
    """``resource`` with the texels the engine's texture holds after importing the file at ``path``
    (its rows in memory order, as ``Load`` reads them)."""
    if record.format == "png 8-bit":
        from PIL import Image

        pixels = np.asarray(Image.open(path).convert("RGBA"))
    else:
        import OpenEXR

        with OpenEXR.File(str(path)) as exr:
            pixels = np.asarray(exr.channels()["RGBA"].pixels)
    memory = pixels[::-1] if BOTTOM_UP[engine] else pixels
    return TextureResource(resource.name, np.ascontiguousarray(memory), FORMATS[resource.dtype][2],
                           filter=resource.filter, wrap=resource.wrap)
