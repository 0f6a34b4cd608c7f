"""Writes the normalmap feature scene's textures (8-bit PNG, read `raw`):
textures/domes.png, a tangent-space normal map of 4 x 4 domes (64 x 64 texels), and
textures/stripes.png, a height map of sinusoidal stripes along u (64 x 64 texels).
Run with any Python that has numpy and mitsuba (for its PNG writer):
    python3 make_maps.py
"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
N = 64

# Domes: in each of the 4 x 4 cells a spherical cap of radius 0.8 (cell half-widths); the
# normal of the cap z = sqrt(1 - r^2) scaled flat by 0.6, flat outside.
y, x = np.mgrid[0:N, 0:N]
cx = ((x + 0.5) / (N / 4)) % 1.0 * 2.0 - 1.0
cy = ((y + 0.5) / (N / 4)) % 1.0 * 2.0 - 1.0
r2 = cx * cx + cy * cy
inside = r2 < 0.64
k = 0.6
nx = np.where(inside, k * cx, 0.0)
ny = np.where(inside, k * cy, 0.0)
nz = np.where(inside, np.sqrt(np.maximum(0.64 - r2, 0.0)) / 0.8, 1.0)
n = np.stack([nx, ny, nz], axis=-1)
n /= np.linalg.norm(n, axis=-1, keepdims=True)
domes = np.round((n * 0.5 + 0.5) * 255.0).astype(np.uint8)
mi.Bitmap(domes, pixel_format=mi.Bitmap.PixelFormat.RGB).write("textures/domes.png")

# Stripes: h = 0.5 + 0.5 sin(2 pi 4 u) along the image's columns, grey.
h = 0.5 + 0.5 * np.sin(2.0 * np.pi * 4.0 * (x + 0.5) / N)
stripes = np.round(np.repeat(h[..., None], 3, axis=-1) * 255.0).astype(np.uint8)
mi.Bitmap(stripes, pixel_format=mi.Bitmap.PixelFormat.RGB).write("textures/stripes.png")
