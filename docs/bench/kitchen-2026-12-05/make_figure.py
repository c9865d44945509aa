#!/usr/bin/env python3
"""Side by side: the reference, Mitsuba 3 at 256 spp, irfarm at its defaults, irfarm path at the
same time; sRGB, one exposure for all. Usage: make_figure.py REF MITSUBA IRFARM PATH OUT.png"""
import sys
import numpy as np
import OpenEXR
from PIL import Image, ImageDraw


def load(p):
    f = OpenEXR.File(p)
    ch = f.parts[0].channels
    if 'RGB' in ch:
        return np.array(ch['RGB'].pixels, dtype=np.float64)[:, :, :3]
    return np.stack([np.array(ch[c].pixels, dtype=np.float64) for c in 'RGB'], -1)


def srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


ref = load(sys.argv[1])
labels = sys.argv[6:] if len(sys.argv) > 6 else ['reference', 'Mitsuba 256 spp', 'irfarm', 'path']
tiles = []
for p, label in zip(sys.argv[1:5], labels):
    x = load(p)
    err = np.mean((x - ref) ** 2 / (ref ** 2 + 0.01))
    img = Image.fromarray((srgb(x) * 255).astype(np.uint8)).resize((x.shape[1] * 2, x.shape[0] * 2),
                                                                  Image.NEAREST)
    d = ImageDraw.Draw(img)
    d.text((4, 4), label + ('' if p == sys.argv[1] else ' %.1e' % err), fill=(255, 255, 0))
    tiles.append(img)
w = sum(t.width for t in tiles)
out = Image.new('RGB', (w, tiles[0].height))
x0 = 0
for t in tiles:
    out.paste(t, (x0, 0))
    x0 += t.width
out.save(sys.argv[5])
