#!/usr/bin/env python3
"""relMSE of images against a reference, raw and after box-filtering both by 2, 4 and 8:

    python3 binned_relmse.py REFERENCE.exr IMAGE.exr...

prints one line per image: its path and relMSE at bins 1, 2, 4, 8 (mean over pixels and channels
of (x - ref)^2 / (ref^2 + 0.01)). The binned figures keep the low-frequency error (a cache's
blotches, a map's bias) and divide the reference's own per-pixel noise by the bin's pixel count.
The tables in README.md here were made with it, each image rendered by
`build/irfarm render SCENE.xml --seed S -o IMAGE.exr`, CPU seconds from `/usr/bin/time -f %U`."""
import sys

import Imath
import numpy as np
import OpenEXR


def load(path):
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    return np.stack([np.frombuffer(f.channel(c, Imath.PixelType(Imath.PixelType.FLOAT)),
                                   dtype=np.float32).reshape(h, w) for c in "RGB"], -1)


def binned(x, b):
    h, w = x.shape[0] // b * b, x.shape[1] // b * b
    return x[:h, :w].reshape(h // b, b, w // b, b, -1).mean(axis=(1, 3))


def main():
    ref = load(sys.argv[1])
    for path in sys.argv[2:]:
        x = load(path)
        errs = []
        for b in (1, 2, 4, 8):
            xb, rb = binned(x, b), binned(ref, b)
            errs.append(np.mean((xb - rb) ** 2 / (rb ** 2 + 0.01)))
        print(path, " ".join("%.2e" % e for e in errs))


if __name__ == "__main__":
    main()
