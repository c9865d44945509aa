"""Measures Mitsuba 3's own error on this scene against reference-x4.exr (64x64) and writes it to
mitsuba-x4-noise.json: the independent tolerances of the service tests that compare a service
render with reference-x4.exr (tests/service/two_workers_test.sh, worker_kill_test.sh,
standby_test.sh). Mitsuba is not needed to run those tests, only this file.

Run from this folder:
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so python3 make_x4_noise.py
Needs `pip install mitsuba` (3.9.1 was used), variant llvm_ad_rgb (the reference's). For each
(resolution, spp) in RUNS, renders scene.xml at that resolution with 8 seeds (1..8; the reference
used 1000..1031), box-filters a 128x128 render 2x2 to 64x64 (as the tests do with
`irfarm downsample --factor 2`), and records each image's relMSE against reference-x4.exr (same
definition as `irfarm compare`: mean over pixels and channels of (t-r)^2/(r^2+0.01)), their mean
and their max, under the key "<res> <spp>spp".
"""
import json, time
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")

RUNS = ((64, 4), (64, 16), (64, 64), (64, 256), (64, 1024), (128, 64), (128, 256))
SEEDS = range(1, 9)


def relmse(a, b):
    return float(np.mean((a - b) ** 2 / (b ** 2 + 0.01)))


def box2(img):
    h, w, c = img.shape
    return img.reshape(h // 2, 2, w // 2, 2, c).mean(axis=(1, 3))


ref = np.array(mi.Bitmap("reference-x4.exr"), dtype=np.float64)
assert ref.shape == (64, 64, 3), ref.shape
out = {"scene": "cornell-box", "renderer": "mitsuba " + mi.__version__, "variant": "llvm_ad_rgb",
       "integrator": "path", "max_depth": -1, "rfilter": "box",
       "against": "reference-x4.exr (reference.exr, 8192 spp at 256x256, box-filtered 4x4)",
       "relmse_definition": "mean over pixels and channels of (t-r)^2/(r^2+0.01)",
       "seeds": "1..8", "made_with": "python3 make_x4_noise.py",
       "128x128": "box-filtered 2x2 to 64x64 before the comparison", "renders": {}}
t0 = time.time()
for res, spp in RUNS:
    scene = mi.load_file("scene.xml", spp=spp, resx=res, resy=res)
    errs = []
    for s in SEEDS:
        img = np.array(mi.render(scene, spp=spp, seed=s), dtype=np.float64)
        while img.shape[0] > 64:
            img = box2(img)
        errs.append(relmse(img, ref))
    key = "%dx%d %dspp" % (res, res, spp)
    out["renders"][key] = {"relmse_vs_ref": errs, "relmse_vs_ref_mean": float(np.mean(errs)),
                           "relmse_vs_ref_max": max(errs)}
    print(key, float(np.mean(errs)), max(errs), flush=True)
out["seconds"] = round(time.time() - t0, 1)
json.dump(out, open("mitsuba-x4-noise.json", "w"), indent=2)
