#!/bin/bash
# hr.sh OUT "seeds": veach-ajar at 640x360, old vs new, box-filtered 2x2 to the 320x180 reference
OUT=$1
for s in $2; do for arm in old:/tmp/irf0 new:/tmp/irf6; do l=${arm%%:*}; b=${arm#*:}
 t=$( { /usr/bin/time -f "%U %S %e" $b render /work/shared/scenes/veach-ajar/scene.xml -D resx=640 -D resy=360 --seed $s -o /tmp/hr_$l.exr -q ; } 2>&1 | tail -1)
 e=$(python3 - /tmp/hr_$l.exr <<'PY'
import OpenEXR, numpy as np, sys
def load(p):
    f=OpenEXR.File(p); ch=f.channels()
    if 'RGB' in ch: return np.array(ch['RGB'].pixels,dtype=np.float64)
    return np.stack([np.array(ch[c].pixels,dtype=np.float64) for c in 'RGB'],-1)
x=load(sys.argv[1]); ref=load('/work/shared/scenes/veach-ajar/reference.exr')
H,W,_=ref.shape; x=x.reshape(H,2,W,2,3).mean((1,3))
print(float(np.mean((x-ref)**2/(ref**2+0.01))))
PY
)
 echo "veach-ajar-640 $s $l $t $e 1" >> $OUT
done; done; echo done >> $OUT
