"""Block-compressed texture baselines as encode + decode round trips on 8-bit images.

``import inshade.bench.codecs`` is cheap and torch-free: the encoders (``astc-encoder-py``, ``etcpak``)
and Pillow's ``bcn`` decoder are imported inside the functions that use them.

Every round trip takes a uint8 ``[H, W, 3]`` (RGB; alpha 255 is added for the encoder) or
``[H, W, 4]`` (RGBA) image and returns a `Roundtrip` ``(image, nbytes)``: the decoded image with
the input's channel count, and the compressed size in bytes (``.bpp``: bits per pixel). It
unpacks as a pair, ``decoded, nbytes = astc_roundtrip(rgba8, 6)``. A codec that cannot run (package
missing or failing, size not a multiple of its block) raises `CodecError` (a RuntimeError) whose
message is the reason, for a report's "unavailable" row.

- `astc_roundtrip`: ARM astcenc, LDR profile, quality `ASTC_QUALITY`, any block footprint
  (`ASTC_BLOCKS` are the ones the benches use); 128 bits a block.
- `bc_roundtrip` (`bc1_roundtrip`, `bc7_roundtrip`): ``etcpak`` encoder, Pillow ``bcn`` decoder
  (etcpak 0.9.15's ``decompress_bc*`` crash); BC1 4 bpp, BC7 8 bpp; width and height multiples of 4.
- `etc1_roundtrip`: ``etcpak``'s ETC1 encoder and the numpy ETC1 decoder here (etcpak's
  ``decompress_etc*`` crash too); 4 bpp RGB (alpha passes through unchanged).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ASTC_QUALITY", "ASTC_BLOCKS", "BC_CODECS", "RGB8_BPP", "CodecError", "Roundtrip", "to_rgba8",
           "astc_roundtrip", "bc_roundtrip", "bc1_roundtrip", "bc7_roundtrip", "etc1_roundtrip", "etc1_decode"]

ASTC_QUALITY = 60.0
ASTC_BLOCKS = (4, 6, 8, 12)
RGB8_BPP = 24.0
# name -> (etcpak encoder, Pillow bcn decoder number, extra encoder arguments)
BC_CODECS = {"BC1": ("compress_bc1", 1, ()), "BC7": ("compress_bc7", 7, (None,))}


class CodecError(RuntimeError):
    """A codec that cannot run here; the message is the reason."""


class Roundtrip(NamedTuple):
    image: np.ndarray   # decoded uint8 [H, W, C], C as in the input
    nbytes: int         # compressed size

    @property
    def bpp(self) -> float:
        """Bits per pixel of the compressed data."""
        return 8.0 * self.nbytes / (self.image.shape[0] * self.image.shape[1])


def to_rgba8(img8: np.ndarray) -> np.ndarray:
    """Contiguous uint8 RGBA: an RGB image gets alpha 255, an RGBA one is kept."""
    img8 = np.asarray(img8, np.uint8)
    if img8.ndim != 3 or img8.shape[2] not in (3, 4):
        raise ValueError(f"expected a uint8 [H, W, 3|4] image, got shape {img8.shape}")
    if img8.shape[2] == 4:
        return np.ascontiguousarray(img8)
    return np.ascontiguousarray(np.concatenate([img8, np.full(img8.shape[:2] + (1,), 255, np.uint8)], -1))


def _like(decoded_rgba: np.ndarray, img8: np.ndarray) -> np.ndarray:
    return decoded_rgba if np.shape(img8)[2] == 4 else decoded_rgba[..., :3]


# ---------------------------------------------------------------------------------------------
# ASTC

def astc_roundtrip(img8: np.ndarray, block: int, quality: float = ASTC_QUALITY) -> Roundtrip:
    """astcenc (LDR profile, ``quality``) at a ``block`` x ``block`` footprint, then its decoder."""
    try:
        from astc_encoder import ASTCConfig, ASTCContext, ASTCImage, ASTCProfile, ASTCSwizzle, ASTCType
    except Exception as e:  # noqa: BLE001
        raise CodecError(f"astc-encoder-py not usable ({e}); pip install astc-encoder-py") from None
    rgba8 = to_rgba8(img8)
    h, w = rgba8.shape[:2]
    try:
        ctx = ASTCContext(ASTCConfig(ASTCProfile.LDR, block, block, 1, quality))
        sw = ASTCSwizzle.from_str("RGBA")
        comp = ctx.compress(ASTCImage(ASTCType.U8, w, h, data=rgba8.tobytes()), sw)
        dec = ctx.decompress(comp, ASTCImage(ASTCType.U8, w, h), sw)
    except Exception as e:  # noqa: BLE001
        raise CodecError(f"astcenc failed: {e}") from None
    return Roundtrip(_like(np.frombuffer(dec.data, np.uint8).reshape(h, w, 4), img8), len(comp))


# ---------------------------------------------------------------------------------------------
# BC1 / BC7

def _etcpak():
    try:
        import etcpak
    except Exception as e:  # noqa: BLE001
        raise CodecError(f"etcpak not usable ({e}); pip install etcpak") from None
    return etcpak


def _check_blocks(h: int, w: int):
    if h % 4 or w % 4:
        raise CodecError(f"{w}x{h} is not a multiple of the 4x4 block")


def bc_roundtrip(img8: np.ndarray, codec: str = "BC7") -> Roundtrip:
    """``codec`` ("BC1" or "BC7", see `BC_CODECS`): etcpak's encoder, Pillow's bcn decoder."""
    if codec not in BC_CODECS:
        raise ValueError(f"unknown BC codec {codec!r}; expected one of {sorted(BC_CODECS)}")
    fn, n, extra = BC_CODECS[codec]
    etcpak = _etcpak()
    try:
        from PIL import Image
    except Exception as e:  # noqa: BLE001
        raise CodecError(f"Pillow not usable ({e})") from None
    rgba8 = to_rgba8(img8)
    h, w = rgba8.shape[:2]
    _check_blocks(h, w)
    try:
        comp = getattr(etcpak, fn)(rgba8.tobytes(), w, h, *extra)
        dec = np.asarray(Image.frombytes("RGBA", (w, h), comp, "bcn", (n,)))
    except Exception as e:  # noqa: BLE001
        raise CodecError(f"etcpak/Pillow failed: {e}") from None
    return Roundtrip(_like(dec, img8), len(comp))


def bc1_roundtrip(img8: np.ndarray) -> Roundtrip:
    """`bc_roundtrip` with BC1 (4 bpp)."""
    return bc_roundtrip(img8, "BC1")


def bc7_roundtrip(img8: np.ndarray) -> Roundtrip:
    """`bc_roundtrip` with BC7 (8 bpp)."""
    return bc_roundtrip(img8, "BC7")


# ---------------------------------------------------------------------------------------------
# ETC1

# ETC1 intensity modifier tables (Khronos Data Format Specification, ETC1 section).
_ETC1_MODIFIERS = np.array([[2, 8, -2, -8], [5, 17, -5, -17], [9, 29, -9, -29], [13, 42, -13, -42],
                            [18, 60, -18, -60], [24, 80, -24, -80], [33, 106, -33, -106],
                            [47, 183, -47, -183]], np.int32)


def etc1_decode(data: bytes, width: int, height: int) -> np.ndarray:
    """Decode ETC1 blocks (8 bytes each, big-endian, blocks in row-major order) to uint8 RGB
    ``[height, width, 3]``; width and height multiples of 4."""
    _check_blocks(height, width)
    bw, bh = width // 4, height // 4
    blocks = np.frombuffer(data, ">u8", count=bw * bh).astype(np.uint64)

    def bits(lo, n):
        return ((blocks >> np.uint64(lo)) & np.uint64((1 << n) - 1)).astype(np.int32)

    diff, flip = bits(33, 1).astype(bool), bits(32, 1).astype(bool)
    table = np.stack([bits(37, 3), bits(34, 3)], -1)                    # [N, 2] sub-block codeword
    base = np.empty(blocks.shape + (2, 3), np.int32)
    for c, (hi4, lo4, hi5, d3) in enumerate(((60, 56, 59, 56), (52, 48, 51, 48), (44, 40, 43, 40))):
        # individual mode: two 4-bit colours, extended to 8 bits by replication
        c1, c2 = bits(hi4, 4), bits(lo4, 4)
        ind = np.stack([c1 * 17, c2 * 17], -1)
        # differential mode: 5-bit colour + signed 3-bit delta, extended by replication
        b5 = bits(hi5, 5)
        d = bits(d3, 3)
        d = np.where(d >= 4, d - 8, d)
        b5b = b5 + d
        dif = np.stack([(b5 << 3) | (b5 >> 2), (b5b << 3) | (b5b >> 2)], -1)
        base[..., c] = np.where(diff[:, None], dif, ind)
    # pixel indices: msb in bits 16..31, lsb in bits 0..15; pixel p = x * 4 + y (column-major)
    p = np.arange(16, dtype=np.uint64)
    lsb = ((blocks[:, None] >> p) & np.uint64(1)).astype(np.int32)
    msb = ((blocks[:, None] >> (p + np.uint64(16))) & np.uint64(1)).astype(np.int32)
    index = msb * 2 + lsb                                                # [N, 16] -> 0..3
    x, y = np.arange(16) // 4, np.arange(16) % 4
    sub = np.where(flip[:, None], (y >= 2)[None], (x >= 2)[None]).astype(np.int64)   # [N, 16]
    n = np.arange(blocks.size)[:, None]
    modifier = _ETC1_MODIFIERS[table[n, sub], index]                     # [N, 16]
    rgb = np.clip(base[n, sub] + modifier[..., None], 0, 255).astype(np.uint8)      # [N, 16, 3]
    # [by, bx, x, y, c] -> [by, y, bx, x, c]
    return rgb.reshape(bh, bw, 4, 4, 3).transpose(0, 3, 1, 2, 4).reshape(height, width, 3)


def etc1_roundtrip(img8: np.ndarray) -> Roundtrip:
    """etcpak's ETC1 encoder (RGB; 4 bpp) and `etc1_decode`; an input alpha channel is returned
    unchanged (ETC1 has none, and its size is not counted)."""
    etcpak = _etcpak()
    rgba8 = to_rgba8(img8)
    h, w = rgba8.shape[:2]
    _check_blocks(h, w)
    try:
        comp = etcpak.compress_etc1_rgb(rgba8.tobytes(), w, h)
    except Exception as e:  # noqa: BLE001
        raise CodecError(f"etcpak failed: {e}") from None
    rgb = etc1_decode(comp, w, h)
    out = np.concatenate([rgb, rgba8[..., 3:]], -1) if np.shape(img8)[2] == 4 else rgb
    return Roundtrip(out, len(comp))
