"""Makes this scene's Mitsuba 3 references and noise figures (reference.exr, reference-tent.exr,
reference.json), used by tests/render/film_filter_test.cc.

Run from this folder:
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so python3 make_reference.py
Needs `pip install mitsuba` (3.9.1 was used), variant llvm_ad_rgb (its film evaluates the filter
exactly; scalar_rgb uses a tabulated filter). For each filter (gaussian, Mitsuba's default with
stddev 0.5, and tent, radius 1): the reference is the mean of 16 renders of 256 spp with seeds
1000..1015 (4096 spp); then 8 more renders at 256 spp (seeds 1..8, not used by the reference)
measure Mitsuba's own noise at the test's spp: relMSE of each against the reference
(mitsuba_256spp_vs_ref, the error a Mitsuba render at 256 spp has against this reference) and of
consecutive pairs against each other (mitsuba_256spp_pairs). Also renders the scene with a box
filter at 4096 spp (seeds 2000..2015) and records its relMSE against each reference: how far the
wrong filter is from the right one, without irfarm.
"""
import json, time
import numpy as np
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")

CHUNK = 256


def relmse(a, b):
    return float(np.mean((a - b) ** 2 / (b ** 2 + 0.01)))


SCENES = {}


def render(filt, spp, seeds):
    if filt not in SCENES:
        SCENES[filt] = mi.load_file("scene.xml", spp=spp, filter=filt)
    return np.mean([np.array(mi.render(SCENES[filt], spp=spp, seed=s), dtype=np.float64)
                    for s in seeds], axis=0)


out = {"renderer": "mitsuba " + mi.__version__, "variant": "llvm_ad_rgb", "integrator": "path",
       "max_depth": 3, "relmse_definition": "mean over pixels and channels of (t-r)^2/(r^2+0.01)",
       "made_with": "python3 make_reference.py"}
t0 = time.time()
box = render("box", CHUNK, range(2000, 2016))
for filt, name in (("gaussian", "reference.exr"), ("tent", "reference-tent.exr")):
    chunks = [render(filt, CHUNK, [1000 + i]) for i in range(16)]
    ref = np.mean(chunks, axis=0)
    even, odd = np.mean(chunks[0::2], axis=0), np.mean(chunks[1::2], axis=0)
    singles = [render(filt, CHUNK, [s]) for s in range(1, 9)]
    vs_ref = [relmse(s, ref) for s in singles]
    pairs = [relmse(singles[i], singles[i + 1]) for i in range(0, 8, 2)]
    mi.Bitmap(ref.astype(np.float32), pixel_format=mi.Bitmap.PixelFormat.RGB).write(name)
    h, w, _ = ref.shape
    out[filt] = {
        "file": name, "spp": 16 * CHUNK, "seeds": "1000..1015", "width": w, "height": h,
        "mean_rgb": [float(c) for c in ref.mean(axis=(0, 1))],
        "relmse_half_vs_half": relmse(even, odd),
        "relmse_est_ref_vs_truth": relmse(even, odd) / 4,
        "mitsuba_256spp_vs_ref": vs_ref, "mitsuba_256spp_vs_ref_max": max(vs_ref),
        "mitsuba_256spp_pairs": pairs, "mitsuba_256spp_pairs_max": max(pairs),
        "mitsuba_box_4096spp_vs_ref": relmse(box, ref),
    }
    print(filt, json.dumps(out[filt], indent=1))
out["seconds"] = round(time.time() - t0, 1)
json.dump(out, open("reference.json", "w"), indent=2)
