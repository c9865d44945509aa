import json, subprocess, sys, numpy as np, OpenEXR, os
def rd(p):
    f=OpenEXR.File(p); ch=f.parts[0].channels
    if 'RGB' in ch: return np.array(ch['RGB'].pixels,dtype=np.float64)[:,:,:3]
    return np.stack([np.array(ch[c].pixels,dtype=np.float64) for c in 'RGB'],-1)
d=sys.argv[1]; E=float(sys.argv[2]); n=int(sys.argv[3]); bins=sys.argv[4:]
ref=rd(f'{d}/reference.exr'); referr=json.load(open(f'{d}/reference.json')).get('relmse_est_ref_vs_truth',0)
res={b:[] for b in bins}
for i in range(n):
  for b in bins:
    out=f'/tmp/sec/rep-{os.path.basename(b)}.exr'
    subprocess.run([b,'render',f'{d}/scene.xml','-o',out,'--seed',str(int(os.environ.get('SEED0','7'))+i),'--stats',out+'.json','-q','--target-error',str(E)],check=True,stderr=subprocess.DEVNULL)
    st=json.load(open(out+'.json')); x=rd(out)
    t=float(np.mean((x-ref)**2/(ref**2+0.01)))-referr; est=st['error_estimate']['relmse']
    res[b].append((t,est,st['cpu_seconds']['total']))
for b in bins:
  r=res[b]; inb=sum(E/2<=t<=2*E for t,_,_ in r); close=sum(max(t/e,e/t)<=1.5 for t,e,_ in r if t>0)
  print(f"{os.path.basename(d)} E={E:g} {os.path.basename(b)}: in band {inb}/{n}, est within 1.5x {close}/{n}, cpu {sum(c for _,_,c in r):.1f}, truths {' '.join(f'{t:.2e}' for t,_,_ in r)}")
