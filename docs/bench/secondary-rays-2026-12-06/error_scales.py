import sys, numpy as np, OpenEXR, Imath
from scipy.ndimage import uniform_filter
def load(p):
    f=OpenEXR.InputFile(p); dw=f.header()['dataWindow']; w=dw.max.x-dw.min.x+1; h=dw.max.y-dw.min.y+1
    return np.stack([np.frombuffer(f.channel(c,Imath.PixelType(Imath.PixelType.FLOAT)),np.float32).reshape(h,w) for c in 'RGB'],-1)
x=load(sys.argv[1]); r=load(sys.argv[2])
e=(x-r)**2/(r**2+0.01)
print("relmse %.3e"%e.mean())
lum=r.mean(-1)
for name,m in [("bright(ref>2)",lum>2),("room",lum<=2)]:
    print(name, "frac %.3f"%m.mean(), "contrib %.3e"%(e[m].sum()/e.size))
# low-frequency part: blur the difference
for k in (3,7,15):
    d=np.stack([uniform_filter(x[...,c]-r[...,c],k) for c in range(3)],-1)
    el=(d**2/(r**2+0.01)).mean(); print("blur%d relmse %.3e"%(k,el))
# top pixels share
pe=e.mean(-1).ravel(); s=np.sort(pe)[::-1]
print("top0.1%% %.2f top1%% %.2f"%(s[:len(s)//1000].sum()/s.sum(), s[:len(s)//100].sum()/s.sum()))
