"""Image quality metrics and the sRGB transfer functions, written once for trainers, benches and tests.

numpy only at import; ``torch`` is touched only when a function is handed tensors, scikit-image
only inside `ssim`, ``flip-evaluator`` only inside `flip`.

- `psnr_from_mse` / `psnr`: ``10 log10(peak^2 / mse)`` dB, ``inf`` for a zero error. `psnr`
  takes numpy arrays (float64 difference) or torch tensors (float64 difference, torch mean),
  an optional boolean ``mask`` over the leading (pixel) axes, and ``peak`` (1.0 for [0, 1]
  values, 255.0 for 8-bit ones).
- `ssim`: scikit-image's structural similarity (``data_range`` 1, channels last, 7x7 window or
  the largest odd window a small image allows).
- `srgb_eotf` / `srgb_oetf`: IEC 61966-2-1 decode / encode in float64 after clipping to [0, 1]
  (the same formulas as ``lib/colour.glsl``).
- `flip`: mean FLIP (NVIDIA ``flip-evaluator``, LDR by default); `flip_unavailable` says why it
  cannot run, or None.

Every function here gives bit-identical numbers to the copies it replaced (same dtype, same order
of operations), so recorded results do not move.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["psnr_from_mse", "psnr", "mse", "ssim", "srgb_eotf", "srgb_oetf", "flip", "flip_unavailable"]


# ---------------------------------------------------------------------------------------------
# PSNR

def psnr_from_mse(mse: float, peak: float = 1.0) -> float:
    """``10 log10(peak^2 / mse)`` dB as a Python float; ``inf`` when ``mse`` is 0."""
    mse = float(mse)
    return float("inf") if mse == 0 else 10.0 * math.log10(peak * peak / mse)


def _is_tensor(x) -> bool:
    return type(x).__module__.split(".")[0] == "torch"


def mse(a, b, mask=None) -> float:
    """Mean squared difference in float64 as a Python float. numpy inputs: ``np.asarray(x,
    np.float64)`` of each, then ``mask`` (boolean over the leading axes) selects the elements;
    torch tensors: ``.double()`` of each and ``torch.mean``."""
    if _is_tensor(a) or _is_tensor(b):
        import torch

        a = torch.as_tensor(a).double()
        b = torch.as_tensor(b).double()
        if mask is not None:
            mask = torch.as_tensor(mask, dtype=torch.bool)
            a, b = a[mask], b[mask]
        return float(torch.mean((a - b) ** 2))
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if mask is not None:
        mask = np.asarray(mask, bool)
        a, b = a[mask], b[mask]
    return float(np.mean((a - b) ** 2))


def psnr(a, b, peak: float = 1.0, mask=None) -> float:
    """PSNR (dB) of ``a`` against ``b`` (symmetric): `psnr_from_mse` of `mse` (``mask``: boolean
    over the leading axes, e.g. ``[H, W]`` for ``[H, W, C]`` images; only those pixels count)."""
    return psnr_from_mse(mse(a, b, mask), peak)


# ---------------------------------------------------------------------------------------------
# SSIM

def ssim_window(height: int, width: int) -> int:
    """The SSIM window: 7, or for an image smaller than 7 pixels on a side the largest odd size
    below its short side (scikit-image needs an odd window no larger than the image)."""
    short = min(height, width)
    return min(7, short // 2 * 2 - 1) if short < 7 else 7


def ssim(image: np.ndarray, reference: np.ndarray, *, data_range: float = 1.0, channel_axis: int | None = -1,
         win_size: int | None = None) -> float:
    """Mean structural similarity of ``image`` against ``reference`` (scikit-image's
    ``structural_similarity(reference, image, ...)``; float arrays, channels last by default,
    ``channel_axis=None`` for one channel). ``win_size`` defaults to `ssim_window`."""
    from skimage.metrics import structural_similarity

    image, reference = np.asarray(image), np.asarray(reference)
    if win_size is None:
        win_size = ssim_window(*image.shape[:2])
    return float(structural_similarity(reference, image, data_range=data_range, channel_axis=channel_axis,
                                       win_size=win_size))


# ---------------------------------------------------------------------------------------------
# sRGB

def srgb_eotf(encoded: np.ndarray) -> np.ndarray:
    """sRGB-encoded [0, 1] -> linear [0, 1] (IEC 61966-2-1; same formula as lib/colour.glsl),
    float64, input clipped to [0, 1] first."""
    encoded = np.clip(np.asarray(encoded, np.float64), 0.0, 1.0)
    return np.where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055) ** 2.4)


def srgb_oetf(linear: np.ndarray) -> np.ndarray:
    """Linear [0, 1] -> sRGB-encoded [0, 1] (IEC 61966-2-1; same formula as lib/colour.glsl),
    float64, input clipped to [0, 1] first."""
    linear = np.clip(np.asarray(linear, np.float64), 0.0, 1.0)
    return np.where(linear <= 0.0031308, linear * 12.92, 1.055 * linear ** (1.0 / 2.4) - 0.055)


# ---------------------------------------------------------------------------------------------
# FLIP

def _flip_module():
    import flip_evaluator

    return flip_evaluator


def flip_unavailable() -> str | None:
    """None when ``flip-evaluator`` imports, else the reason it does not (for a report row)."""
    try:
        _flip_module()
    except Exception as e:  # noqa: BLE001 - report any failure as the reason
        return f"flip-evaluator not usable: {e}"
    return None


def flip(reference: np.ndarray, test: np.ndarray, mode: str = "LDR") -> float:
    """Mean FLIP error of ``test`` against ``reference`` ([H, W, 3] RGB; uint8 arrays are scaled
    by 1/255 in float32, float ones passed as float32 in [0, 1], sRGB-encoded for ``"LDR"``).
    RuntimeError with the reason when ``flip-evaluator`` is unusable."""
    try:
        fe = _flip_module()
    except Exception as e:  # noqa: BLE001
        raise RuntimeError(f"flip-evaluator not usable: {e}") from None

    def prep(x):
        x = np.asarray(x)
        return x.astype(np.float32) / 255.0 if x.dtype == np.uint8 else np.asarray(x, np.float32)

    _, mean, _ = fe.evaluate(prep(reference), prep(test), mode, applyMagma=False)
    return float(mean)
