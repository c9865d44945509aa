# High-resolution check: irfarm and Mitsuba 3 (+ OIDN) at k x the reference's size, box-filtered
# k x k down to it and compared with the reference (relMSE), side by side in one run.
# Run: python3 hires.py IRFARM SCENES_DIR SCENE K (Mitsuba 3 llvm_ad_rgb and pyoidn installed).
import sys, os, json, time, subprocess
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', 'bench'))
import denoise_bench as db
irfarm, scenes_dir, scene, k = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
out = os.environ.get('HIRES_OUT', '/tmp/hires'); os.makedirs(out, exist_ok=True)
ref_path = os.path.join(scenes_dir, scene, 'reference.exr')
import mitsuba as mi
mi.set_variant('llvm_ad_rgb')
ref = db.read_rgb_exr(ref_path)
H, W = ref.shape[:2]
def down(img):
    return img[:, :, :3].reshape(H, k, W, k, 3).mean((1, 3))
def rel(img):
    return db.relmse(down(img), ref)
rows = []
for label, extra in [('irfarm default', []), ('irfarm --denoise', ['--denoise'])]:
    base = f'{out}/{scene}-{k}-{label.split()[-1].strip("-")}'
    subprocess.run([irfarm, 'render', os.path.join(scenes_dir, scene, 'scene.xml'), f'-Dresx={W*k}',
                    f'-Dresy={H*k}', '-o', base + '.exr', '-q', '--stats', base + '.json'] + extra, check=True)
    st = json.load(open(base + '.json'))
    sec = sum(st['seconds'].get(x, 0) for x in ('pilot', 'overture', 'render', 'denoise'))
    rows.append((label, sec, rel(db.read_rgb_exr(base + '.exr')), st['integrator'], st['settings'].get('cache_levels'), st['settings'].get('record_rays')))
    print(rows[-1], flush=True)
import pyoidn
s = mi.load_file(os.path.join(scenes_dir, scene, 'scene.xml'), resx=W * k, resy=H * k)
integ = s.integrator()
guides = mi.load_dict({'type': 'aov', 'aovs': 'albedo:albedo,nn:sh_normal'})
for spp in [16, 64, 256]:
    chunk = min(spp, 64)
    if spp <= 64:
        mi.render(s, integrator=integ, spp=chunk, seed=7); mi.render(s, integrator=guides, spp=chunk, seed=7)
    t = time.time()
    img = np.mean([np.array(mi.render(s, integrator=integ, spp=chunk, seed=1234 + spp + j)) for j in range(spp // chunk)], axis=0)
    rs = time.time() - t
    t = time.time(); aux = np.array(mi.render(s, integrator=guides, spp=chunk, seed=4321 + spp)); gs = time.time() - t
    color = np.ascontiguousarray(img[:, :, 0:3], dtype=np.float32)
    alb = np.ascontiguousarray(aux[:, :, -6:-3], dtype=np.float32); nrm = np.ascontiguousarray(aux[:, :, -3:], dtype=np.float32)
    db.oidn_denoise(pyoidn, color, alb, nrm)
    t = time.time(); den = db.oidn_denoise(pyoidn, color, alb, nrm); ds = time.time() - t
    rows.append((f'mitsuba {spp}spp', rs, rel(color))); print(rows[-1], flush=True)
    rows.append((f'mitsuba {spp}spp + oidn', rs + gs + ds, rel(den))); print(rows[-1], flush=True)
print('RESULT', scene, k, json.dumps(rows))
