"""Shared by the scene folders' make_reference.py: makes a scene's Mitsuba 3 reference.

Run a folder's make_reference.py from that folder (python3 make_reference.py --spp 4096). Needs
`pip install mitsuba` (3.9.1 was used). Renders scene.xml with Mitsuba's `path` integrator
(max_depth -1, variant llvm_ad_rgb) in chunks of 256 spp with seeds 1000, 1001, ...; the mean of
the chunks is the reference (with a box filter this equals one render at the total spp). The
even and odd chunks are two independent half-spp images; their relMSE (relmse_half_vs_half)
gives the reference's own expected error, relmse_est_ref_vs_truth = half_vs_half / 4.
Writes reference.exr, reference-x4.exr (box-filtered by 4 x 4: the golden tests render at 1/4
size) and reference.json. Optional figures of Mitsuba's own noise:
  quarter_noise: two renders at 1/4 size and 64 spp (seeds 1 and 2, as the golden test renders
    irfarm), relmse(A, B) / 2 as mitsuba_quarter_64spp_noise;
  full_256: renders at full size and 256 spp (seeds 1 and 2, or 1 ... full_256 when it is a
    number above 2): mitsuba_full_256spp_noise (from the first two), their relMSE against the
    reference and their channel means.
The reference is the mean of the chunks whatever the scene's rfilter (recorded from scene.xml,
gaussian when it names none, as Mitsuba's default); with a box filter it equals one render.
Set DRJIT_LIBLLVM_PATH if drjit does not find libLLVM (e.g. /usr/lib/x86_64-linux-gnu/libLLVM-19.so).
"""
import argparse, json, re, time
import numpy as np
import mitsuba as mi


def relmse(a, b):
    return float(np.mean((a - b) ** 2 / (b ** 2 + 0.01)))


def render(scene, spp, seed):
    return np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)


def make_reference(quarter_noise=False, full_256=False):
    mi.set_variant("llvm_ad_rgb")
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=4096)
    args = ap.parse_args()
    chunk = 256
    n = max(2, args.spp // chunk)
    found = re.search(r'<rfilter\s+type="(\w+)"', open("scene.xml").read())
    rfilter = found.group(1) if found else "gaussian"
    scene = mi.load_file("scene.xml", spp=chunk)
    t0 = time.time()
    imgs = [render(scene, chunk, 1000 + i) for i in range(n)]
    seconds = time.time() - t0
    ref = np.mean(imgs, axis=0)
    hvh = relmse(np.mean(imgs[0::2], axis=0), np.mean(imgs[1::2], axis=0))
    h, w, _ = ref.shape
    x4 = ref.reshape(h // 4, 4, w // 4, 4, 3).mean(axis=(1, 3))
    pf = mi.Bitmap.PixelFormat.RGB
    mi.Bitmap(ref.astype(np.float32), pixel_format=pf).write("reference.exr")
    mi.Bitmap(x4.astype(np.float32), pixel_format=pf).write("reference-x4.exr")
    info = {
        "renderer": "mitsuba " + mi.__version__, "variant": "llvm_ad_rgb", "integrator": "path",
        "max_depth": -1, "spp": n * chunk, "seconds": round(seconds, 2), "width": w, "height": h,
        "rfilter": rfilter, "chunks": {"count": n, "spp_each": chunk, "seeds": f"1000..{999 + n}"},
        "mean_rgb": [float(c) for c in ref.mean(axis=(0, 1))],
        "nonfinite_pixels": int(np.sum(~np.isfinite(ref))),
        "relmse_definition": "mean over pixels and channels of (test-ref)^2/(ref^2+0.01)",
        "relmse_half_vs_half": hvh, "relmse_est_second_vs_ref": hvh / 2,
        "relmse_est_ref_vs_truth": hvh / 4,
    }
    if quarter_noise:
        quarter = mi.load_file("scene.xml", spp=64, resx=w // 4, resy=h // 4)
        info["mitsuba_quarter_64spp_noise"] = relmse(render(quarter, 64, 1),
                                                     render(quarter, 64, 2)) / 2
    if full_256:
        full = mi.load_file("scene.xml", spp=256)
        runs = [render(full, 256, seed) for seed in range(1, max(2, int(full_256)) + 1)]
        info["mitsuba_full_256spp_noise"] = relmse(runs[0], runs[1]) / 2
        info["mitsuba_full_256spp_relmse_vs_ref"] = [relmse(x, ref) for x in runs]
        info["mitsuba_full_256spp_means"] = [[float(c) for c in x.mean(axis=(0, 1))]
                                             for x in runs]
    info["made_with"] = "python3 make_reference.py --spp %d" % args.spp
    json.dump(info, open("reference.json", "w"), indent=2)
    print("spp", n * chunk, "seconds", seconds, "half_vs_half", hvh)
