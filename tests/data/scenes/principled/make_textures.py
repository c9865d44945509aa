"""Makes textures/ridges.exr, the tangent-space normal map of this scene (run once; numpy +
mitsuba for the EXR writer). Ridges across u: height h(u) = A sin(2 pi k u), normal
(-dh/du * s, 0, 1) normalized with s the tangent scale, stored as (n + 1) / 2 (linear EXR).
The map depends on u only, so v's direction convention cannot matter."""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
w, h, k = 256, 4, 12
u = (np.arange(w) + 0.5) / w
slope = 0.6 * np.cos(2 * np.pi * k * u)  # tangent of the tilt, up to about 31 degrees
n = np.stack([-slope, np.zeros_like(slope), np.ones_like(slope)], axis=-1)
n /= np.linalg.norm(n, axis=-1, keepdims=True)
img = np.repeat(((n + 1) / 2)[None, :, :], h, axis=0).astype(np.float32)
mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB).write("textures/ridges.exr")
