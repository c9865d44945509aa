import sys, numpy as np, OpenEXR, Imath, pyoidn
def ch(f, names):
    dw=f.header()['dataWindow']; w=dw.max.x-dw.min.x+1; h=dw.max.y-dw.min.y+1
    return np.stack([np.frombuffer(f.channel(c,Imath.PixelType(Imath.PixelType.FLOAT)),np.float32).reshape(h,w) for c in names],-1).copy()
def load(p):
    f=OpenEXR.InputFile(p); return ch(f,'RGB')
def den(color, albedo, normal):
    out=np.zeros_like(color)
    dev=pyoidn.Device(); dev.commit()
    flt=pyoidn.Filter(dev,"RT")
    flt.set_image(pyoidn.OIDN_IMAGE_COLOR, np.ascontiguousarray(color,np.float32), pyoidn.OIDN_FORMAT_FLOAT3)
    if albedo is not None:
        flt.set_image(pyoidn.OIDN_IMAGE_ALBEDO, np.ascontiguousarray(albedo,np.float32), pyoidn.OIDN_FORMAT_FLOAT3)
        flt.set_image(pyoidn.OIDN_IMAGE_NORMAL, np.ascontiguousarray(normal,np.float32), pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_bool("hdr", True); flt.commit(); flt.execute()
    return out
f=OpenEXR.InputFile(sys.argv[1]); ref=load(sys.argv[2])
img=ch(f,'RGB'); alb=ch(f,['albedo.R','albedo.G','albedo.B']); nor=ch(f,['normal.X','normal.Y','normal.Z'])
dr=ch(f,['direct.R','direct.G','direct.B']); ind=ch(f,['indirect.R','indirect.G','indirect.B']); em=ch(f,['emission.R','emission.G','emission.B'])
rel=lambda x: ((x-ref)**2/(ref**2+0.01)).mean()
print("sum check", np.abs(dr+ind-img).max(), "emission in direct?", np.abs(em).max())
print("raw %.3e"%rel(img))
print("image %.3e"%rel(den(img,alb,nor)))
print("direct+indirect separately %.3e"%rel(den(dr,alb,nor)+den(ind,alb,nor)))
print("den(direct)+indirect raw %.3e"%rel(den(dr,alb,nor)+ind))
print("direct raw + den(indirect) %.3e"%rel(dr+den(ind,alb,nor)))
