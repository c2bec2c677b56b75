"""Writing renders: PNG for eyes (exposure, a tone mapper of scene/tonemap.py (none unless asked for:
values above 1 clip), then sRGB-encoded 8-bit), EXR for numbers (linear float32).

Arrays are image-oriented ([H, W, C], row 0 = top), as returned by ``render.read_rgba``.
Each output can get a JSON sidecar saying how it was made. Every file is written atomically
(inshade/files.py): a temporary file in the same folder, renamed into place when complete.
Reading: EXR (``read_exr``) and equirectangular environment maps (``load_environment``).
"""

from __future__ import annotations

import json
from importlib import metadata
from pathlib import Path

import numpy as np
import OpenEXR
from PIL import Image

from inshade.files import atomic_files
from inshade.sh import check_environment
from inshade.scene.tonemap import check_tonemap, tonemap as apply_tonemap
from inshade.provenance import utc_now


def srgb_oetf(linear: np.ndarray) -> np.ndarray:
    """sRGB encoding of linear values in [0, 1] (same formula as ``lib/colour.glsl``)."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, linear * 12.92, 1.055 * np.power(linear, 1.0 / 2.4) - 0.055)


def to_8bit(values: np.ndarray) -> np.ndarray:
    """Values in [0, 1] as the 8-bit integers a PNG holds (round to nearest)."""
    return np.rint(np.asarray(values, np.float64) * 255.0).astype(np.uint8)


def display_pixels(linear_rgb: np.ndarray, exposure: float = 1.0, tonemap: str = "none") -> np.ndarray:
    """Linear ``[H, W, 3|4]`` -> the 8-bit sRGB pixels a PNG holds (and the present pass shows):
    scale by exposure, apply ``tonemap`` (scene/tonemap.py TONEMAPS; ``"none"``: values above 1
    clip), clip to [0, 1], sRGB-encode. Alpha (if present) stays linear, without exposure or tonemap."""
    check_tonemap(tonemap)
    image = _check_image(linear_rgb).astype(np.float64)
    rgb = apply_tonemap(np.maximum(image[..., :3] * exposure, 0.0), tonemap)
    channels = [srgb_oetf(rgb)] + ([np.clip(image[..., 3:], 0.0, 1.0)] if image.shape[2] == 4 else [])
    return to_8bit(np.concatenate(channels, axis=2))


def write_png(path: str | Path, linear_rgb: np.ndarray, exposure: float = 1.0, tonemap: str = "none") -> Path:
    """Write linear ``[H, W, 3|4]`` as an 8-bit sRGB PNG of ``display_pixels``."""
    pixels = display_pixels(linear_rgb, exposure, tonemap)
    path = Path(path)
    with atomic_files(path) as tmp:
        Image.fromarray(pixels).save(tmp, format="PNG")
    return path


def write_exr(path: str | Path, linear: np.ndarray) -> Path:
    """Write linear ``[H, W, 3|4]`` float32 to an EXR (FLOAT channels, ZIP compression)."""
    image = np.ascontiguousarray(_check_image(linear), dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {"RGBA" if image.shape[2] == 4 else "RGB": image}
    path = Path(path)
    with atomic_files(path) as tmp, OpenEXR.File(header, channels) as exr:
        exr.write(str(tmp))
    return path


def read_exr(path: str | Path) -> np.ndarray:
    """Read an RGB or RGBA EXR back as float32 ``[H, W, 3|4]``; ValueError naming the file if it is
    not a readable RGB(A) EXR."""
    try:
        with OpenEXR.File(str(path)) as exr:
            channels = exr.channels()
            name = "RGBA" if "RGBA" in channels else "RGB" if "RGB" in channels else None
            if name is None:
                raise ValueError(f"no RGB or RGBA channels (has {', '.join(sorted(channels)) or 'none'})")
            return np.asarray(channels[name].pixels, dtype=np.float32)
    except ValueError as exc:
        raise ValueError(f"{path}: not a usable EXR ({exc})") from None
    except Exception as exc:  # OpenEXR raises RuntimeError (and others, by version) for unreadable files
        raise ValueError(f"{path}: not a readable EXR ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None


MAX_IMAGE_SIDE = 16384
IMAGE_READ_SUFFIXES = (".png", ".jpg", ".jpeg", ".exr")


def load_environment(path) -> np.ndarray:
    """Reads an equirectangular environment (.exr linear HDR; .png/.jpg sRGB decoded to linear)
    as float32 [H, W, 3]. Any problem (missing/unreadable file, wrong shape, NaN/inf, negative
    values) raises one ValueError naming the file."""
    path = Path(path)
    try:
        if not path.is_file():
            raise ValueError("no such file")
        suffix = path.suffix.lower()
        if suffix == ".exr":
            try:
                image = read_exr(path)
            except Exception as exc:  # OpenEXR's own errors differ by version
                raise ValueError(f"not a readable RGB(A) EXR ({exc})") from None
        elif suffix in (".png", ".jpg", ".jpeg"):
            with Image.open(path) as im:
                srgb = np.asarray(im.convert("RGB"), np.float64) / 255.0
            image = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
        else:
            raise ValueError(f"unsupported format {suffix!r}; expected .exr, .png or .jpg")
        return check_environment(image, "image").astype(np.float32)
    except ValueError as exc:
        raise ValueError(f"environment map {path}: {exc}") from None


def check_image_file(path: str | Path, *, exr: bool | None = None, max_side: int = MAX_IMAGE_SIDE) -> tuple[int, int]:
    """Check, from its header, that ``path`` is an image inshade can read (8-bit PNG/JPEG through
    Pillow, or an EXR when ``exr`` is true or the suffix is .exr) of at most ``max_side`` pixels a
    side, without decoding the pixels. Returns (width, height); ValueError naming the file otherwise."""
    import warnings

    from PIL import UnidentifiedImageError

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: {'is a folder, not an image file' if path.is_dir() else 'no such file'}")
    if exr is None:
        exr = path.suffix.lower() == ".exr"
    if exr:
        try:
            with OpenEXR.File(str(path), header_only=True) as f:
                window = f.header().get("dataWindow")
            (x0, y0), (x1, y1) = window if window is not None else ((0, 0), (-1, -1))
            size = (int(x1) - int(x0) + 1, int(y1) - int(y0) + 1)
        except Exception as exc:
            raise ValueError(f"{path}: not a readable EXR ({str(exc).splitlines()[0] if str(exc) else exc!r})") from None
    else:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                with Image.open(path) as im:
                    size = im.size
                    im.verify()   # chunk structure and checksums, without decoding the pixels
        except (UnidentifiedImageError, Image.DecompressionBombError) as exc:
            raise ValueError(f"{path}: not an image Pillow can read ({str(exc).splitlines()[0][:160]})") from None
        except (OSError, SyntaxError, ValueError, EOFError) as exc:   # Pillow's corrupt-file errors
            raise ValueError(f"{path}: corrupt or truncated image ({str(exc).splitlines()[0][:160] or type(exc).__name__})") from None
    if not (1 <= size[0] <= max_side and 1 <= size[1] <= max_side):
        raise ValueError(f"{path}: image size {size[0]}x{size[1]} out of range 1..{max_side}")
    return size


def write_sidecar(image_path: str | Path, info: dict) -> Path:
    """Write ``<image>.json`` (e.g. ``render.png.json``) with ``info`` plus version and UTC time.

    ``info`` carries what the caller knows (camera, settings, bundle hash, GL renderer); numpy
    values are converted to plain JSON.
    """
    path = sidecar_path(image_path)
    with atomic_files(path) as tmp:
        tmp.write_text(sidecar_text(info))
    return path


def sidecar_path(image_path: str | Path) -> Path:
    return Path(f"{image_path}.json")


def sidecar_text(info: dict) -> str:
    """The sidecar JSON of ``info`` plus the inshade version and the UTC time."""
    record = dict(info)
    record["inshade_version"] = metadata.version("inshade")
    record["timestamp_utc"] = utc_now()
    return json.dumps(record, sort_keys=True, indent=2, default=_to_json) + "\n"


def _to_json(value):
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _check_image(array: np.ndarray) -> np.ndarray:
    array = np.asarray(array)
    if array.ndim != 3 or array.shape[2] not in (3, 4):
        raise ValueError(f"expected an image [H, W, 3|4], got shape {array.shape}")
    return array
