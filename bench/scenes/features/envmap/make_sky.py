"""Writes textures/sky.exr, the envmap scene's 64x32 equirectangular map (linear RGB, float):
a sky brightening towards the horizon above, a dim ground below, and a sun of 3x2 texels at
about 35 degrees elevation (rows 9-10, columns 0-2: behind the sphere as the camera sees it),
bright enough that the glass sphere casts a caustic towards the camera. Needs numpy and mitsuba (for its EXR writer): python3 make_sky.py"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
W, H = 64, 32
img = np.zeros((H, W, 3), np.float32)
for j in range(H):
    t = (j + 0.5) / H  # 0 at the zenith
    if t < 0.5:
        a = t / 0.5
        img[j, :] = (0.25 + 0.35 * a, 0.35 + 0.35 * a, 0.8 + 0.1 * a)
    else:
        img[j, :] = (0.12, 0.1, 0.08)
# Some azimuthal variation, so that the map's orientation matters.
for i in range(W):
    img[: H // 2, i, 0] *= 1.0 + 0.3 * np.cos(2 * np.pi * i / W)
img[9:11, 0:3] = (400.0, 360.0, 300.0)
mi.Bitmap(img).write("textures/sky.exr")
