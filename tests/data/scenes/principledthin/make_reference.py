"""Makes this scene's Mitsuba 3 reference (reference.exr, reference-x4.exr, reference.json).

Run from this folder:  python3 make_reference.py --spp 4096
Needs `pip install mitsuba` (3.9.1 was used). Renders with Mitsuba's `path` integrator
(max_depth -1, variant llvm_ad_rgb) in chunks of 256 spp with seeds 1000, 1001, ...; the mean of
the chunks is the reference (with a box filter this equals one render at the total spp). The
even and odd chunks are two independent half-spp images; their relMSE (relmse_half_vs_half)
gives the reference's own expected error, relmse_est_ref_vs_truth = half_vs_half / 4.
reference-x4.exr is the reference box-filtered by 4 x 4 (the golden test renders at 1/4 size).
Also renders the scene twice at 1/4 size and 64 spp (seeds 1 and 2, as the golden test renders
irfarm) and records Mitsuba's own noise there, relmse(A, B) / 2, as mitsuba_quarter_64spp_noise,
and likewise at full size and 256 spp (seeds 1 and 2) as mitsuba_full_256spp_noise, with the
channel means of those two renders (mitsuba_full_256spp_means).
Set DRJIT_LIBLLVM_PATH if drjit does not find libLLVM (e.g. /usr/lib/x86_64-linux-gnu/libLLVM-19.so).
"""
import argparse, json, time
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")


def relmse(a, b):
    return float(np.mean((a - b) ** 2 / (b ** 2 + 0.01)))


ap = argparse.ArgumentParser()
ap.add_argument("--spp", type=int, default=4096)
args = ap.parse_args()
chunk = 256
n = max(2, args.spp // chunk)
scene = mi.load_file("scene.xml", spp=chunk)
imgs = []
t0 = time.time()
for i in range(n):
    imgs.append(np.array(mi.render(scene, spp=chunk, seed=1000 + i), dtype=np.float64))
seconds = time.time() - t0
ref = np.mean(imgs, axis=0)
quarter = mi.load_file("scene.xml", spp=64, resx=ref.shape[1] // 4, resy=ref.shape[0] // 4)
qa = np.array(mi.render(quarter, spp=64, seed=1), dtype=np.float64)
qb = np.array(mi.render(quarter, spp=64, seed=2), dtype=np.float64)
full = mi.load_file("scene.xml", spp=256)
fa = np.array(mi.render(full, spp=256, seed=1), dtype=np.float64)
fb = np.array(mi.render(full, spp=256, seed=2), dtype=np.float64)
even = np.mean(imgs[0::2], axis=0)
odd = np.mean(imgs[1::2], axis=0)
hvh = relmse(even, odd)
h, w, _ = ref.shape
x4 = ref.reshape(h // 4, 4, w // 4, 4, 3).mean(axis=(1, 3))
pf = mi.Bitmap.PixelFormat.RGB
mi.Bitmap(ref.astype(np.float32), pixel_format=pf).write("reference.exr")
mi.Bitmap(x4.astype(np.float32), pixel_format=pf).write("reference-x4.exr")
json.dump({
    "renderer": "mitsuba " + mi.__version__, "variant": "llvm_ad_rgb", "integrator": "path",
    "max_depth": -1, "spp": n * chunk, "seconds": round(seconds, 2), "width": w, "height": h,
    "rfilter": "box", "chunks": {"count": n, "spp_each": chunk, "seeds": f"1000..{999 + n}"},
    "mean_rgb": [float(c) for c in ref.mean(axis=(0, 1))],
    "nonfinite_pixels": int(np.sum(~np.isfinite(ref))),
    "relmse_definition": "mean over pixels and channels of (test-ref)^2/(ref^2+0.01)",
    "relmse_half_vs_half": hvh, "relmse_est_second_vs_ref": hvh / 2,
    "relmse_est_ref_vs_truth": hvh / 4,
    "mitsuba_quarter_64spp_noise": relmse(qa, qb) / 2,
    "mitsuba_full_256spp_noise": relmse(fa, fb) / 2,
    "mitsuba_full_256spp_relmse_vs_ref": [relmse(fa, ref), relmse(fb, ref)],
    "mitsuba_full_256spp_means": [[float(c) for c in fa.mean(axis=(0, 1))],
                                  [float(c) for c in fb.mean(axis=(0, 1))]],
    "made_with": "python3 make_reference.py --spp %d" % args.spp,
}, open("reference.json", "w"), indent=2)
print("spp", n * chunk, "seconds", seconds, "half_vs_half", hvh)
