"""The image application's target: a 2048x2048 collage of the photographs scikit-image ships, each at
its native resolution (cropped, never resampled), so every pixel is a real photograph's pixel.

scikit-image ships no photograph of 2048 pixels or more on a side (the largest are retina, 1411x1411,
and hubble_deep_field, 1000x872), so the large image is assembled: four shelves of photographs, each
shelf as tall as its shortest photograph, each photograph centre-cropped to its cell. Greyscale
photographs are repeated into three channels. The layout is data (``SHELVES``): the same pixels on
every machine, from the files scikit-image installs (no download).
"""
from __future__ import annotations

import numpy as np

SIZE = 2048
# (shelf height, [(skimage.data name, cell width), ...]); the widths of a shelf add up to SIZE and the
# heights to SIZE. Every cell is no larger than its photograph, so a crop never resamples.
SHELVES = (
    (872, (("hubble_deep_field", 1000), ("retina", 1048))),
    (500, (("motorcycle_left", 741), ("astronaut", 512), ("immunohistochemistry", 512), ("cell", 283))),
    (400, (("coffee", 600), ("rocket", 640), ("camera", 512), ("motorcycle_right", 296))),
    (276, (("chelsea", 451), ("coins", 384), ("brick", 512), ("grass", 512), ("gravel", 189))),
)


# Photographs that skimage.data returns as one item of a tuple: name -> (function, item).
TUPLES = {"motorcycle_left": ("stereo_motorcycle", 0), "motorcycle_right": ("stereo_motorcycle", 1)}


def photograph(name: str) -> np.ndarray:
    """A skimage.data photograph as uint8 [H, W, 3]."""
    import skimage.data

    function, item = TUPLES.get(name, (name, None))
    pixels = getattr(skimage.data, function)()
    pixels = np.asarray(pixels if item is None else pixels[item])
    if pixels.ndim == 2:
        pixels = np.repeat(pixels[..., None], 3, axis=2)
    return np.ascontiguousarray(pixels[..., :3], np.uint8)


def centre_crop(pixels: np.ndarray, width: int, height: int) -> np.ndarray:
    h, w = pixels.shape[:2]
    if width > w or height > h:
        raise ValueError(f"a {width}x{height} cell is larger than its {w}x{h} photograph")
    top, left = (h - height) // 2, (w - width) // 2
    return pixels[top:top + height, left:left + width]


def mosaic() -> np.ndarray:
    """The collage, uint8 sRGB [SIZE, SIZE, 3], row 0 = top."""
    rows = []
    for height, cells in SHELVES:
        rows.append(np.concatenate([centre_crop(photograph(name), width, height) for name, width in cells], 1))
    out = np.concatenate(rows, 0)
    assert out.shape == (SIZE, SIZE, 3), out.shape
    return out


def sources() -> list[str]:
    """The photographs in the collage, shelf by shelf (for the bundle's provenance)."""
    return [f"skimage.data.{TUPLES.get(name, (name,))[0]}{'[%d]' % TUPLES[name][1] if name in TUPLES else ''} "
            f"({width}x{height} centre crop)" for height, cells in SHELVES for name, width in cells]
