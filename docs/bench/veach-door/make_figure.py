"""The veach-ajar door figure of the README (issue 9): full frames side by side, the door at 2x
below each, one exposure for all (irfarm's preview rule on the last image, the reference).
Usage: python3 make_figure.py OUT.png BEFORE.exr AFTER.exr REFERENCE.exr
(BEFORE/AFTER: `irfarm render ../shared/scenes/veach-ajar/scene.xml --seed 7 -o X.exr` with the
binaries of 30457e3 and main)."""
import sys, OpenEXR, numpy as np
from PIL import Image
def load(p):
    f = OpenEXR.File(p); ch = f.channels()
    if "RGB" in ch: return np.asarray(ch["RGB"].pixels, dtype=np.float64)
    return np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], -1)
def srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
def png(a): return Image.fromarray((srgb(a) * 255 + 0.5).astype(np.uint8))
out = sys.argv[1]; paths = sys.argv[2:]
imgs = [load(p) for p in paths]
# One exposure for all, irfarm's preview rule on the last image (the reference): its 98th
# luminance percentile to about 0.5, a power of two.
lum = (imgs[-1] * [0.2126, 0.7152, 0.0722]).sum(-1)
exposure = 2.0 ** np.floor(np.log2(0.5 / np.percentile(lum, 98)))
imgs = [im * exposure for im in imgs]
h, w, _ = imgs[0].shape
gap = 4
# Full frames side by side, then the door (x 195..305, y 15..160) at 2x below each.
x0, x1, y0, y1 = 195, 305, 15, 160
crops = [np.kron(im[y0:y1, x0:x1], np.ones((2, 2, 1))) for im in imgs]
ch, cw, _ = crops[0].shape
W = len(imgs) * (max(w, cw) + gap)
H = h + gap + ch
canvas = np.ones((H, W, 3))
for i, (im, cr) in enumerate(zip(imgs, crops)):
    x = i * (max(w, cw) + gap)
    canvas[:h, x:x + w] = im
    canvas[h + gap:h + gap + ch, x:x + cw] = cr
png(canvas).save(out)
print("wrote", out, canvas.shape)
