"""Video frames as packed pixels: one ``uint32`` a pixel, ``0x00RRGGBB``, a frame ``(height, width)``.

A packed frame is what pygame draws into (a surface with these masks) and what turns into the planes
x264 encodes without a byte shuffle: red, green and blue are shifts of one word, so the conversion runs
over whole rows at once where a ``(height, width, 3)`` array would be read three bytes at a time.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

from rlcompare.compiled import njit


def pack(rgb: np.ndarray) -> np.ndarray:
    """``(height, width, 3)`` uint8 to a packed frame."""
    rgb = rgb.astype(np.uint32)
    packed: np.ndarray = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
    return packed


def unpack(packed: np.ndarray) -> np.ndarray:
    """A packed frame to ``(height, width, 3)`` uint8."""
    return np.stack([(packed >> shift).astype(np.uint8) for shift in (16, 8, 0)], axis=-1)


def image(packed: np.ndarray) -> Image.Image:
    """A packed frame as a Pillow RGB image (its bytes are B, G, R, 0 on a little-endian machine)."""
    height, width = packed.shape
    words = np.ascontiguousarray(packed, dtype="<u4")
    return Image.frombuffer("RGB", (width, height), words, "raw", "BGRX", 0, 1)


@njit(cache=True)
def yuv420(packed: np.ndarray, out: np.ndarray) -> None:
    """A packed frame (even height and width) into ``out``: its Y, U and V planes, ITU-R BT.601 limited range.

    The 8-bit integer form of BT.601 (Y in 16..235, U and V in 16..240 around 128), each chroma sample from the
    mean of a 2x2 block, as ``yuv420p`` stores them; ``out`` has ``height * width * 3 // 2`` bytes.
    """
    height, width = packed.shape
    pixels = packed.ravel()
    byte, k = np.uint32(255), np.uint32  # unsigned 32-bit arithmetic: eight pixels to a vector register
    for i in range(pixels.size):
        red, green, blue = (pixels[i] >> k(16)) & byte, (pixels[i] >> k(8)) & byte, pixels[i] & byte
        out[i] = ((k(66) * red + k(129) * green + k(25) * blue + k(128)) >> k(8)) + k(16)
    half, quarter = width // 2, pixels.size // 4
    u = out[pixels.size:pixels.size + quarter].reshape(height // 2, half)
    v = out[pixels.size + quarter:pixels.size + 2 * quarter].reshape(height // 2, half)
    for row in range(0, height, 2):
        top, bottom, u_row, v_row = packed[row], packed[row + 1], u[row // 2], v[row // 2]
        for column in range(half):
            a, b, c, d = top[2 * column], top[2 * column + 1], bottom[2 * column], bottom[2 * column + 1]
            red = (((a >> k(16)) & byte) + ((b >> k(16)) & byte) + ((c >> k(16)) & byte) + ((d >> k(16)) & byte)
                   + k(2)) >> k(2)
            green = (((a >> k(8)) & byte) + ((b >> k(8)) & byte) + ((c >> k(8)) & byte) + ((d >> k(8)) & byte)
                     + k(2)) >> k(2)
            blue = ((a & byte) + (b & byte) + (c & byte) + (d & byte) + k(2)) >> k(2)
            # 32896 = 128 * 256 + 128: ((x + 128) >> 8) + 128 with every sum positive, so unsigned
            u_row[column] = (k(112) * blue + k(32896) - k(38) * red - k(74) * green) >> k(8)
            v_row[column] = (k(112) * red + k(32896) - k(94) * green - k(18) * blue) >> k(8)


@njit(cache=True)
def halved(packed: np.ndarray) -> np.ndarray:
    """A packed frame (even height and width) at half its height and width: each pixel the rounded mean
    of a 2x2 block, channel by channel."""
    height, width = packed.shape
    out = np.empty((height // 2, width // 2), dtype=np.uint32)
    byte, k = np.uint32(255), np.uint32
    for row in range(height // 2):
        top, bottom, small = packed[2 * row], packed[2 * row + 1], out[row]
        for column in range(width // 2):
            a, b, c, d = top[2 * column], top[2 * column + 1], bottom[2 * column], bottom[2 * column + 1]
            pixel = k(0)
            for shift in (k(16), k(8), k(0)):
                total = ((a >> shift) & byte) + ((b >> shift) & byte) + ((c >> shift) & byte) + ((d >> shift) & byte)
                pixel |= ((total + k(2)) >> k(2)) << shift
            small[column] = pixel
    return out
