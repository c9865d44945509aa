"""living-room at seed 7, with the guide and without (run.sh's images), beside the reference:
irrcache at its defaults (top) and path at 64 spp (bottom), tone-mapped the same way.
   make_figure.py IRRCACHE_RUN_DIR PATH_RUN_DIR REFERENCE.exr OUT.png"""
import sys
import numpy as np
import OpenEXR, Imath
import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt


def load(p):
    f = OpenEXR.InputFile(p)
    dw = f.header()['dataWindow']
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    return np.stack([np.frombuffer(f.channel(c, Imath.PixelType(Imath.PixelType.FLOAT)),
                                   np.float32).reshape(h, w) for c in 'RGB'], -1)


def tone(x):
    return np.clip(x / (1 + x), 0, 1) ** (1 / 2.2)


def relmse(x, ref):
    return float(((x - ref) ** 2 / (ref ** 2 + 0.01)).mean())


ir, pa, ref_path, out = sys.argv[1:5]
ref = load(ref_path)
fig, ax = plt.subplots(2, 3, figsize=(15, 6))
for row, (d, label) in enumerate([(ir, 'irrcache defaults'), (pa, 'path 64 spp')]):
    for col, mode in enumerate(['off', 'guide']):
        img = load(f'{d}/living-room-{mode}-7.exr')
        ax[row][col].imshow(tone(img))
        name = 'without the guide' if mode == 'off' else 'with the guide'
        ax[row][col].set_title(f'{label}, {name}: relMSE {relmse(img, ref):.3g}')
    ax[row][2].imshow(tone(ref))
    ax[row][2].set_title('Mitsuba 3 reference')
for a in ax.flat:
    a.axis('off')
plt.tight_layout()
plt.savefig(out, dpi=60)
