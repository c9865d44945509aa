#!/bin/bash
# usage: tg.sh BIN "scenes" "targets" tag [extra args]; scenes resolved in /tmp/unseen/all or /tmp/mesh
for sc in $2; do d=/tmp/unseen/all/$sc; [ -d $d ] || d=/tmp/mesh/$sc; for E in $3; do
  out=/tmp/ss/tg-$4-$sc-$E.exr
  $1 render $d/scene.xml --seed 7 -q --target-error $E -o $out --stats $out.json $5
  python3 - $d $out $E $sc $4 <<'PY'
import sys, json, numpy as np, OpenEXR
def rd(p):
    f=OpenEXR.File(p); ch=f.parts[0].channels
    return np.array(ch['RGB'].pixels,dtype=np.float64) if 'RGB' in ch else np.stack([np.array(ch[c].pixels,dtype=np.float64) for c in 'RGB'],-1)
d,out,E,sc,tag=sys.argv[1:]; E=float(E)
r=rd(d+'/reference.exr'); x=rd(out); m=((x-r)**2/(r**2+0.01)).mean()
ref=json.load(open(d+'/reference.json')).get('relmse_est_ref_vs_truth',0)
st=json.load(open(out+'.json')); est=st['error_estimate']['relmse']; s=st['settings']
mt=max(m-ref,0)
print('%s %-12s E %g truth %.2e est %.2e ratio %.2f band %s a %.3f rays %d wall %.1f'%(tag,sc,E,mt,est,mt/est,'yes' if E/2<=mt<=2*E else 'NO',s['accuracy'],s['record_rays'],st['seconds']['total']))
PY
done; done
