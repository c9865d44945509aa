import sys, OpenEXR, Imath, numpy as np
def load(p):
    f=OpenEXR.InputFile(p); dw=f.header()['dataWindow']; w=dw.max.x-dw.min.x+1; h=dw.max.y-dw.min.y+1
    return np.stack([np.frombuffer(f.channel(c,Imath.PixelType(Imath.PixelType.FLOAT)),np.float32).reshape(h,w) for c in 'RGB'],-1)
a=load(sys.argv[1]); r=load(sys.argv[2])
e=((a-r)**2/(r**2+0.01)).mean()
H,W=a.shape[:2]; B=40
d=[]
for by in range(0,H-B+1,B):
    for bx in range(0,W-B+1,B):
        d.append(a[by:by+B,bx:bx+B].mean()/r[by:by+B,bx:bx+B].mean()-1)
d=np.array(d)
print('%.3e mean %+.3f blockrms %.3f blockmax %+.3f' % (e, a.mean()/r.mean()-1, np.sqrt((d**2).mean()), d[np.argmax(np.abs(d))]))
