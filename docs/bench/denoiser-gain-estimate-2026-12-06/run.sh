#!/bin/bash
# dg: the denoiser's gain on path noise, estimated from two independent renders vs measured
for sc in "$@"; do
  d=$(ls -d /work/shared/scenes/$sc /tmp/fr/$sc 2>/dev/null | head -1)
  for s in 1 2; do
    /tmp/irf6 render $d/scene.xml -o /tmp/dg/$sc-$s.exr --integrator path --spp 16 --seed $s --aovs -q > /dev/null 2>&1
    /tmp/irf6 denoise /tmp/dg/$sc-$s.exr /tmp/dg/$sc-$s.dn.exr > /dev/null 2>&1
  done
  python3 - $sc $d <<'PY'
import OpenEXR, numpy as np, sys
sc, d = sys.argv[1], sys.argv[2]
def load(p):
    f=OpenEXR.File(p); ch=f.channels()
    if 'RGB' in ch: return np.array(ch['RGB'].pixels,dtype=np.float64)
    return np.stack([np.array(ch[c].pixels,dtype=np.float64) for c in 'RGB'],-1)
ref=load(d+'/reference.exr')
A=load(f'/tmp/dg/{sc}-1.exr'); B=load(f'/tmp/dg/{sc}-2.exr')
DA=load(f'/tmp/dg/{sc}-1.dn.exr'); DB=load(f'/tmp/dg/{sc}-2.dn.exr')
if A.shape!=ref.shape:
    print(sc,'shape',A.shape,ref.shape); sys.exit()
rel=lambda x,r: float(np.mean((x-r)**2/(r**2+0.01)))
m=(DA+DB)/2
raw_var = float(np.mean((A-B)**2/(m**2+0.01)))/2
res_var = float(np.mean((DA-DB)**2/(m**2+0.01)))/2
true_raw=(rel(A,ref)+rel(B,ref))/2; true_dn=(rel(DA,ref)+rel(DB,ref))/2
print('%-12s raw %.3e dn %.3e gain_true %.1f | est raw_var %.3e res_var %.3e gain_est %.1f | dn_true/res_var %.2f'%(sc,true_raw,true_dn,true_raw/true_dn,raw_var,res_var,raw_var/res_var,true_dn/res_var))
PY
done
