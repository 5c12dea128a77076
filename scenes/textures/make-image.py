#!/usr/bin/env python3
"""Writes tiles.png, the image the textures scene maps onto its panel: 96x64 pixels (not a
power of two, so Kiln resamples it for its MIP map), four coloured quadrants (red top left,
green top right, blue bottom left, white bottom right) under a grid of dark lines every 8
pixels, so that orientation and filtering can be seen. Standard library only."""
import struct
import zlib

W, H = 96, 64


def pixel(x, y):
    if x % 8 == 0 or y % 8 == 0:
        return (40, 40, 40)
    left, top = x < W // 2, y < H // 2
    return {
        (True, True): (200, 40, 30),
        (False, True): (40, 180, 60),
        (True, False): (40, 70, 200),
        (False, False): (230, 230, 230),
    }[(left, top)]


def chunk(kind, data):
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))


rows = b"".join(b"\0" + bytes(c for x in range(W) for c in pixel(x, y)) for y in range(H))
png = b"\x89PNG\r\n\x1a\n"
png += chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 2, 0, 0, 0))
png += chunk(b"IDAT", zlib.compress(rows, 9))
png += chunk(b"IEND", b"")
with open("tiles.png", "wb") as f:
    f.write(png)
