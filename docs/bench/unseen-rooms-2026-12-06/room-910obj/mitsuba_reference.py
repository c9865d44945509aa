import sys, numpy as np, mitsuba as mi
mi.set_variant('llvm_ad_rgb')
scene = mi.load_file(sys.argv[1])
n = int(sys.argv[2]); acc = None
for k in range(n):
    img = np.array(mi.render(scene, spp=256, seed=1000 + k))
    acc = img if acc is None else acc + img
mi.util.write_bitmap(sys.argv[3], acc / n)
print("done")
