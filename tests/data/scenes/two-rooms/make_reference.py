"""Makes this scene's Mitsuba 3 reference at the settings of tests/service/fanout_test.sh (96x48,
max_depth 4) and Mitsuba's own error against it (reference-depth4.exr, reference-depth4.json; not
reference.exr, as the scene's own default is max_depth -1): the independent tolerance of that
test. Mitsuba is not needed to run the test, only these files.

Run from this folder:
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so python3 make_reference.py
Needs `pip install mitsuba` (3.9.1 was used), variant llvm_ad_rgb, integrator `path` as in
scene.xml with max_depth 4 (what the test passes, -Dmax_depth=4). The reference is the mean of 16
renders of 1024 spp with seeds 1000..1015 (16384 spp); its own error is estimated from its two
halves (even and odd seeds). Then, for each spp in SPPS, 8 renders with seeds 1..8 (not used by
the reference) give Mitsuba's relMSE against the reference at that spp (same definition as
`irfarm compare`: mean over pixels and channels of (t-r)^2/(r^2+0.01)): each, the mean, the max.
"""
import json, time
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")

MAX_DEPTH = 4
CHUNK = 1024
SPPS = (16, 64, 256, 1024)


def relmse(a, b):
    return float(np.mean((a - b) ** 2 / (b ** 2 + 0.01)))


def render(spp, seed):
    scene = mi.load_file("scene.xml", spp=spp, max_depth=MAX_DEPTH)
    return np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)


t0 = time.time()
chunks = [render(CHUNK, 1000 + i) for i in range(16)]
ref = np.mean(chunks, axis=0)
even, odd = np.mean(chunks[0::2], axis=0), np.mean(chunks[1::2], axis=0)
mi.Bitmap(ref.astype(np.float32),
          pixel_format=mi.Bitmap.PixelFormat.RGB).write("reference-depth4.exr")
h, w, _ = ref.shape
out = {"renderer": "mitsuba " + mi.__version__, "variant": "llvm_ad_rgb", "integrator": "path",
       "max_depth": MAX_DEPTH, "rfilter": "box", "width": w, "height": h,
       "spp": 16 * CHUNK, "seeds": "1000..1015", "made_with": "python3 make_reference.py",
       "relmse_definition": "mean over pixels and channels of (t-r)^2/(r^2+0.01)",
       "mean_rgb": [float(c) for c in ref.mean(axis=(0, 1))],
       "nonfinite_pixels": int(np.sum(~np.isfinite(ref).all(axis=2))),
       "relmse_half_vs_half": relmse(even, odd),
       "relmse_est_ref_vs_truth": relmse(even, odd) / 4, "mitsuba": {}}
for spp in SPPS:
    errs = [relmse(render(spp, s), ref) for s in range(1, 9)]
    out["mitsuba"]["%dspp" % spp] = {"seeds": "1..8", "relmse_vs_ref": errs,
                                     "relmse_vs_ref_mean": float(np.mean(errs)),
                                     "relmse_vs_ref_max": max(errs)}
    print(spp, float(np.mean(errs)), max(errs), flush=True)
out["seconds"] = round(time.time() - t0, 1)
json.dump(out, open("reference-depth4.json", "w"), indent=2)
