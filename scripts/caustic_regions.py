#!/usr/bin/env python3
"""Finds the caustic regions of bench/projection.toml (`caustic_region`, pixel rectangles
[x0, y0, x1, y1] of the full-size film, half-open) from the scenes' reference images, and
with --preview DIR writes each reference as PNG with its rectangle drawn in red.

* cornell-caustic: the focused spot under the glass sphere, in the light tracer's reference:
  the 4-connected pixels around the brightest floor pixel (rows >= 200) whose luminance
  (Gaussian sigma 1 px) is above 0.3 and above 1.5 times its Gaussian surround (sigma 8 px),
  plus a 4-pixel margin. (The strip lit by the mirror box is a caustic too; the sphere's
  spot is the one the scene is built around.)
* caustic-glass: where the light tracer's reference exceeds the path tracer's, which cannot
  sample the spot light's caustic: that excess (sigma 2 px) above 10 % of its peak, largest
  4-connected component, plus a 4-pixel margin.
* water-caustic: under a point light above the water, all light below the surface has come
  through it (the photon-GI reference's excess over the path tracer is most of the light in
  every row from 52 down), so the criterion gives no smaller region. The rectangle is the
  underwater part of the back wall, read off the reference: below the surface's lowest edge,
  above the floor, between the side walls (the two boxes in front of it are inside).
* open-mirror: the plane mirror's caustic on the floor (between the mirror and the light),
  the 4-connected pixels around SEED whose luminance (sigma 1 px) is 1.15 times its Gaussian
  surround (sigma 8 px) or more, plus a 2-pixel margin. The glass sphere's caustic, at the
  other side of the image, is left out: one rectangle around both would be mostly plain
  floor.

Needs numpy and Mitsuba 3 (only to read OpenEXR).

    python3 scripts/caustic_regions.py [--scenes ../shared/scenes] [--preview DIR]
"""

import argparse
import glob
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OPEN_MIRROR_SEED = (96, 60)  # (x, y): inside the mirror's caustic at 128x128


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=Path, default=ROOT.parent / "shared/scenes")
    ap.add_argument("--preview", type=Path, default=None)
    args = ap.parse_args()
    import mitsuba as mi

    mi.set_variant("scalar_rgb")

    def load(path):
        return np.array(mi.Bitmap(str(path))).astype(np.float64)[..., :3]

    def lum(a):
        return a @ np.array([0.2126, 0.7152, 0.0722])

    def blur(x, sigma):
        r = int(3 * sigma)
        k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
        k /= k.sum()
        p = np.pad(x, r, mode="edge")
        p = np.apply_along_axis(lambda v: np.convolve(v, k, "valid"), 0, p)
        return np.apply_along_axis(lambda v: np.convolve(v, k, "valid"), 1, p)

    def component(mask, seed):
        """The 4-connected component of `mask` containing `seed` (y, x)."""
        out = np.zeros(mask.shape, bool)
        stack = [seed]
        out[seed] = True
        while stack:
            y, x = stack.pop()
            for dy, dx in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                a, b = y + dy, x + dx
                if 0 <= a < mask.shape[0] and 0 <= b < mask.shape[1] and mask[a, b] and not out[a, b]:
                    out[a, b] = True
                    stack.append((a, b))
        return out

    def largest(mask):
        best, size = None, 0
        seen = np.zeros(mask.shape, bool)
        for y, x in zip(*np.nonzero(mask)):
            if seen[y, x]:
                continue
            c = component(mask, (y, x))
            seen |= c
            if c.sum() > size:
                best, size = c, c.sum()
        return best

    def bbox(mask, pad):
        ys, xs = np.nonzero(mask)
        h, w = mask.shape
        return [int(max(0, xs.min() - pad)), int(max(0, ys.min() - pad)), int(min(w, xs.max() + 1 + pad)), int(min(h, ys.max() + 1 + pad))]

    regions = {}
    s = args.scenes
    a = load(s / "cornell-caustic/reference/cornell-caustic_mitsuba-ptracer_256x256_4096spp_211s.exr")
    l1 = blur(lum(a), 1.0)
    cand = (l1 > 1.5 * blur(lum(a), 8.0)) & (l1 > 0.3)
    cand[:200] = False
    seed = np.unravel_index(np.argmax(np.where(cand, l1, 0.0)), l1.shape)
    regions["cornell-caustic"] = (a, bbox(component(cand, seed), 4))

    a = load(s / "caustic-glass/reference/caustic-glass_mitsuba-ptracer_320x180_4096spp_45s.exr")
    b = load(s / "caustic-glass/reference/caustic-glass_mitsuba-path_320x180_1024spp_5s.exr")
    d = blur(lum(a) - lum(b), 2.0)
    regions["caustic-glass"] = (a, bbox(largest(d > 0.1 * d.max()), 4))

    a = load(s / "water-caustic/reference/water-caustic_luxcore-pathcpu-photongi1_256x256_294spp_902s.exr")
    regions["water-caustic"] = (a, [21, 80, 235, 232])

    refs = sorted(glob.glob(str(ROOT / "bench/scenes/open-mirror/reference/open-mirror_mitsuba-ptracer_*.exr")))
    if refs:
        a = load(refs[-1])
        l1 = blur(lum(a), 1.0)
        cand = l1 >= 1.15 * blur(lum(a), 8.0)
        x, y = OPEN_MIRROR_SEED
        regions["open-mirror"] = (a, bbox(component(cand, (y, x)), 2))

    for name, (img, box) in regions.items():
        print(f"{name}: caustic_region = {box}")
        if args.preview:
            args.preview.mkdir(parents=True, exist_ok=True)
            p = np.clip(img / max(np.percentile(lum(img), 99), 1e-6), 0, 1) ** (1 / 2.2)
            x0, y0, x1, y1 = box
            p[y0:y1, [x0, x1 - 1]] = [1, 0, 0]
            p[[y0, y1 - 1], x0:x1] = [1, 0, 0]
            p = np.repeat(np.repeat(p, 3, 0), 3, 1)
            mi.util.write_bitmap(str(args.preview / f"{name}.png"), mi.Bitmap((p * 255).astype(np.uint8)))


if __name__ == "__main__":
    main()
