#!/usr/bin/env python3
"""Prints a PNG's size and how many pixels have each colour, as JSON: {"width", "height",
"colours": {"r,g,b": count}}. 8-bit RGB PNGs as the coordinator writes them (stb_image_write),
decoded with zlib and the PNG spec's scanline filters (no imaging library needed).

Usage: png_colours.py FILE.png
"""
import json
import struct
import sys
import zlib


def decode(data):
    assert data[:8] == b"\x89PNG\r\n\x1a\n", data[:60]
    w, h, depth, ctype = struct.unpack(">IIBB", data[16:26])
    assert depth == 8 and ctype == 2, (depth, ctype)  # 8-bit RGB
    i, idat = 8, b""
    while i < len(data):
        n, t = struct.unpack(">I4s", data[i:i + 8])
        if t == b"IDAT":
            idat += data[i + 8:i + 8 + n]
        i += 12 + n
    raw = zlib.decompress(idat)
    # Undo the per-scanline filters (PNG spec 9: None, Sub, Up, Average, Paeth; 3 bytes a pixel).
    stride, prev, rows = 3 * w, bytearray(3 * w), []
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - 3] if x >= 3 else 0
            b, c = prev[x], prev[x - 3] if x >= 3 else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    return w, h, rows


if __name__ == "__main__":
    w, h, rows = decode(open(sys.argv[1], "rb").read())
    colours = {}
    for r in rows:
        for x in range(w):
            k = "%d,%d,%d" % (r[3 * x], r[3 * x + 1], r[3 * x + 2])
            colours[k] = colours.get(k, 0) + 1
    print(json.dumps({"width": w, "height": h, "colours": colours}))
