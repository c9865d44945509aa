import sys, time, mitsuba as mi, numpy as np
mi.set_variant(sys.argv[4] if len(sys.argv) > 4 else 'llvm_ad_rgb')
scene = mi.load_file(sys.argv[1])
spp = int(sys.argv[2]); t = time.time()
acc = None; n = 0; step = min(spp, 256)
for i in range(spp // step):
    img = np.array(mi.render(scene, spp=step, seed=i + int(sys.argv[5] if len(sys.argv) > 5 else 1000)))
    acc = img if acc is None else acc + img; n += 1
img = acc / n
mi.Bitmap(img[:, :, :3]).write(sys.argv[3])
print("done", spp, time.time() - t, "s")
