import OpenEXR, numpy as np, sys, subprocess
# crop.py SCENE_DIR NAME SIZE: crops A, B (with AOVs) to SIZE x SIZE at the centre, denoises the
# crops, and compares with the full images' denoised crops and the reference
d, sc, S = sys.argv[1], sys.argv[2], int(sys.argv[3])
def chans(p):
    f=OpenEXR.File(p); return f.header(), f.channels()
def rgb(ch):
    if 'RGB' in ch: return np.array(ch['RGB'].pixels,dtype=np.float64)
    return np.stack([np.array(ch[c].pixels,dtype=np.float64) for c in 'RGB'],-1)
ref=rgb(OpenEXR.File(d+'/reference.exr').channels())
H,W,_=ref.shape; y0=(H-S)//2; x0=(W-S)//2
out={}
for s in (1,2):
    h,ch=chans(f'/tmp/dg/{sc}-{s}.exr')
    newch={}
    for k,v in ch.items():
        px=np.ascontiguousarray(np.array(v.pixels)[y0:y0+S,x0:x0+S])
        newch[k]=OpenEXR.Channel(px)
    hdr={'compression': OpenEXR.ZIP_COMPRESSION,'type': OpenEXR.scanlineimage}
    OpenEXR.File(hdr,newch).write(f'/tmp/dg/{sc}-{s}-c{S}.exr')
    subprocess.run(['/tmp/irf6','denoise',f'/tmp/dg/{sc}-{s}-c{S}.exr',f'/tmp/dg/{sc}-{s}-c{S}.dn.exr'],check=True,capture_output=True)
    out[s]=rgb(OpenEXR.File(f'/tmp/dg/{sc}-{s}-c{S}.dn.exr').channels())
    out['full%d'%s]=rgb(OpenEXR.File(f'/tmp/dg/{sc}-{s}.dn.exr').channels())[y0:y0+S,x0:x0+S]
r=ref[y0:y0+S,x0:x0+S]
rel=lambda x: float(np.mean((x-r)**2/(r**2+0.01)))
m=(out[1]+out[2])/2
res=float(np.mean((out[1]-out[2])**2/(m**2+0.01)))/2
dn=(rel(out[1])+rel(out[2]))/2; dnf=(rel(out['full1'])+rel(out['full2']))/2
print('%-12s crop %d: denoised crop %.3e, full image denoised in the crop %.3e, res_var %.3e, ratio %.2f'%(sc,S,dn,dnf,res,dn/res))
