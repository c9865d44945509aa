#!/usr/bin/env python3
"""Where denoising is biased: a figure of reference | render | denoised | error maps, for a crop.

  python3 bench/denoise_figure.py REF.exr NOISY.exr DENOISED.exr OUT.png [--crop x0,y0,x1,y1]

Images are shown in sRGB at the reference's preview exposure (2^floor(log2(0.5 / p98 lum)));
error maps show |x - ref| / (ref + 0.01) per pixel (mean over channels), same colour scale for
both (the denoised map's 99.5th percentile), so detail the denoiser removed (texture, thin shadows) shows as structure in its map.
Reads EXRs (multi-layer ones too: the RGB root layer) with Mitsuba's Bitmap.
"""
import argparse

import numpy as np


def read_rgb(path):
    import mitsuba as mi
    if not mi.variant():
        mi.set_variant("scalar_rgb")
    for name, layer in mi.Bitmap(path).split():
        if name == "<root>":
            return np.array(layer, dtype=np.float32)[:, :, :3]
    raise ValueError(path + ": no RGB layer")


def to_srgb(x, exposure):
    v = np.clip(x * exposure, 0, 1)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("ref")
    ap.add_argument("noisy")
    ap.add_argument("denoised")
    ap.add_argument("out")
    ap.add_argument("--crop", default="")
    ap.add_argument("--title", default="")
    args = ap.parse_args()
    ref, noisy, den = (read_rgb(p) for p in (args.ref, args.noisy, args.denoised))
    lum = (0.2126 * ref[..., 0] + 0.7152 * ref[..., 1] + 0.0722 * ref[..., 2]).ravel()
    exposure = 2.0 ** np.floor(np.log2(0.5 / max(np.percentile(lum, 98), 1e-9)))
    if args.crop:
        x0, y0, x1, y1 = (int(v) for v in args.crop.split(","))
        ref, noisy, den = (a[y0:y1, x0:x1] for a in (ref, noisy, den))

    def err(x):
        return np.mean(np.abs(x - ref) / (ref + 0.01), axis=2)

    def rel(x):
        return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    e_n, e_d = err(noisy), err(den)
    # Scaled to the denoised error, so that its structure (the bias) shows; the render saturates.
    vmax = float(np.percentile(e_d.ravel(), 99.5))
    fig, axs = plt.subplots(1, 5, figsize=(15, 3.4))
    panels = [("reference", to_srgb(ref, exposure)),
              (f"render (relMSE {rel(noisy):.2e})", to_srgb(noisy, exposure)),
              (f"denoised (relMSE {rel(den):.2e})", to_srgb(den, exposure)),
              ("render error", e_n), ("denoised error", e_d)]
    for ax, (title, img) in zip(axs, panels):
        if img.ndim == 2:
            ax.imshow(img, cmap="inferno", vmin=0, vmax=vmax, interpolation="nearest")
        else:
            ax.imshow(img, interpolation="nearest")
        ax.set_title(title, fontsize=8)
        ax.axis("off")
    if args.title:
        fig.suptitle(args.title, fontsize=9)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(args.out, "relMSE of crop: render", rel(noisy), "denoised", rel(den))


if __name__ == "__main__":
    main()
