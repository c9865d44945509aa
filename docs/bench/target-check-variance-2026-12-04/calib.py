import json, subprocess, sys, numpy as np, OpenEXR, os
def rd(p):
    f=OpenEXR.File(p); ch=f.parts[0].channels
    if 'RGB' in ch: return np.array(ch['RGB'].pixels,dtype=np.float64)[:,:,:3]
    return np.stack([np.array(ch[c].pixels,dtype=np.float64) for c in 'RGB'],-1)
binary=sys.argv[1]; E=sys.argv[2]; levels=sys.argv[3]; seeds=sys.argv[4].split(','); dirs=sys.argv[5:]
bias=float(os.environ.get('BIAS','1.5'))
for d in dirs:
  name=os.path.basename(d.rstrip('/'))
  ref=rd(f'{d}/reference.exr')
  try: referr=json.load(open(f'{d}/reference.json')).get('relmse_est_ref_vs_truth',0)
  except Exception: referr=0
  for seed in seeds:
    out=f'/tmp/sec/c-{name}-{levels}-{seed}.exr'
    subprocess.run([binary,'render',f'{d}/scene.xml','-o',out,'--seed',seed,'--stats',out+'.json','-q','--target-error',E,'--cache-levels',levels],check=True)
    st=json.load(open(out+'.json')); x=rd(out)
    m=float(np.mean((x-ref)**2/(ref**2+0.01)))
    ee=st['error_estimate']; cache=ee['cache_relmse']/(bias if levels=='2' else 1); samp=ee['sampling_relmse']
    truth_cache=m-referr-samp
    print(f"{name:12s} lv{levels} s{seed} meas {m:.2e} ref {referr:.1e} samp {samp:.2e} cache_est(raw) {cache:.2e} cache_truth {truth_cache:.2e} ratio {truth_cache/cache if cache>0 else float('nan'):.2f} est {ee['relmse']:.2e} rounds {len(ee['cache_rounds'])} cpu {st['cpu_seconds']['total']:.1f}",flush=True)
