# Mitsuba 3 reference for the thinlens scene: 16 x 1024 spp (seeds 1000..1015), and the relMSE
# against it of 8 Mitsuba renders at 256 spp (seeds 1..8), the tolerance of thinlens_test.cc.
#   DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so python3 make_reference.py
import json, numpy as np, mitsuba as mi
mi.set_variant('llvm_ad_rgb')
scene = mi.load_file('scene.xml')
ref = sum(np.array(mi.render(scene, spp=1024, seed=1000 + i)) for i in range(16)) / 16
mi.util.write_bitmap('reference.exr', ref.astype(np.float32))
def rel(x):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))
errs = [rel(np.array(mi.render(scene, spp=256, seed=s))) for s in range(1, 9)]
json.dump({'reference_spp': 16384, 'mitsuba_256spp_vs_ref': errs,
           'mitsuba_256spp_vs_ref_max': max(errs)}, open('reference.json', 'w'), indent=1)
print(errs)
