import sys, OpenEXR, Imath, numpy as np
def load(p):
    f = OpenEXR.InputFile(p); dw = f.header()['dataWindow']
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    return np.stack([np.frombuffer(f.channel(c, Imath.PixelType(Imath.PixelType.FLOAT)), np.float32).reshape(h, w) for c in 'RGB'], -1)
ref = load(sys.argv[1])
for p in sys.argv[2:]:
    x = load(p); e = (x - ref) ** 2 / (ref ** 2 + 0.01)
    print(f"{p}: relMSE {e.mean():.3e}  mean {x.mean():.4f} (ref {ref.mean():.4f})")
