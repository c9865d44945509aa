import sys, os, re, numpy as np, OpenEXR, Imath
src, dst = sys.argv[1], sys.argv[2]
os.makedirs(dst, exist_ok=True)
x=open(src).read()
m=re.search(r'<vector name="direction" value="([^"]+)"/>\s*<rgb name="irradiance" value="([^"]+)"/>',x)
dirv=np.array([float(v) for v in m.group(1).split(',')]); E=np.array([float(v) for v in m.group(2).split(',')])
m2=re.search(r'<emitter type="constant">\s*<rgb name="radiance" value="([^"]+)"/>',x)
sky=np.array([float(v) for v in m2.group(1).split(',')])
W,H=512,256
u=(np.arange(W)+0.5)/W; v=(np.arange(H)+0.5)/H
phi=u[None,:]*2*np.pi; th=v[:,None]*np.pi
d=np.stack([np.sin(th)*np.sin(phi), np.cos(th)*np.ones_like(phi), -np.sin(th)*np.cos(phi)],-1)
s=-dirv/np.linalg.norm(dirv)
mask=np.arccos(np.clip(d@s,-1,1))<np.radians(1.5)
dom=(2*np.pi/W)*(np.pi/H)*np.sin(th)*np.ones_like(phi)
img=np.ones((H,W,3))*sky
img[mask]=sky+E/(dom*mask).sum()
hdr=OpenEXR.Header(W,H); hdr['channels']={c:Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT)) for c in 'RGB'}
o=OpenEXR.OutputFile(os.path.join(dst,'sky.exr'),hdr); o.writePixels({c:img[...,i].astype(np.float32).tobytes() for i,c in enumerate('RGB')}); o.close()
x=re.sub(r'<emitter type="directional">.*?</emitter>\s*<emitter type="constant">.*?</emitter>','<emitter type="envmap"><string name="filename" value="sky.exr"/></emitter>',x,flags=re.S)
open(os.path.join(dst,'scene.xml'),'w').write(x)
print(dst, mask.sum())
