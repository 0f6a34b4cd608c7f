#!/usr/bin/env python3
"""Renders the independent reference of the open-mirror bench scene with Mitsuba 3
(bench/scenes/open-mirror/README.md says why it is made this way).

A point light's caustics (light - mirror or glass - floor - camera) are paths a path tracer
cannot sample, so the reference is Mitsuba's light tracer (`ptracer`). The light tracer in
turn cannot render what the camera sees *in* the mirror or *through* the glass sphere
(camera - specular - floor - light): those pixels would be black. They are filled in from
Mitsuba's path tracer, without its caustics being counted twice:

    reference = T + mask * (P - P0)

* T: `ptracer`, PTRACER_PASSES passes of SPP_PER_PASS samples per pixel.
* P: `path`, PATH_PASSES passes of SPP_PER_PASS.
* P0: `path` on the same scene with the mirror and the glass made black (specular
  reflectance and transmittance 0), same seeds: P - P0 is what the path tracer finds through
  a specular surface, zero in expectation (and nearly zero in fact, the random streams being
  the same) where the camera sees only the floor.
* mask: pixels where at least one of MASK_SAMPLES² stratified camera rays first hits a
  delta (mirror or glass) surface. Outside it the reference is T alone, so the only
  path-traced light in it is seen through the mirror or the glass. In mixed pixels at the
  objects' outlines, P - P0 also holds floor - specular - floor - light paths, which T
  counts too: a second-order term (the floor is 0.5 diffuse and the objects are small).

Writes bench/scenes/open-mirror/reference/open-mirror_mitsuba-ptracer_128x128_<spp>spp_<s>s.exr
(and .png), where <spp> is T's samples per pixel and <s> the wall-clock seconds of all
three renders (JIT compilation included), plus a .json of what was run. Needs Mitsuba 3
with the LLVM variant (`bash scripts/setup-debian.sh --with-peers`; Debian's libllvm19).

    python3 scripts/reference_open_mirror.py [--threads 2] [--ptracer-passes 400]
"""

import argparse
import glob
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "bench/scenes/open-mirror/scene.xml"
OUT_DIR = ROOT / "bench/scenes/open-mirror/reference"
SPP_PER_PASS = 1024
MASK_SAMPLES = 8


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ptracer-passes", type=int, default=400, help=f"passes of {SPP_PER_PASS} spp of the light tracer")
    ap.add_argument("--path-passes", type=int, default=16, help=f"passes of {SPP_PER_PASS} spp of each path-tracer render")
    ap.add_argument("--out-dir", type=Path, default=OUT_DIR)
    args = ap.parse_args()

    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        found = sorted(glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM.so.19*"))
        if not found:
            sys.exit("reference_open_mirror: libLLVM 19 not found; `bash scripts/setup-debian.sh --with-peers` installs it (or set DRJIT_LIBLLVM_PATH)")
        os.environ["DRJIT_LIBLLVM_PATH"] = found[0]
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(args.threads)
    started = time.perf_counter()

    def render(scene, passes, label, seed_base):
        total = None
        t0 = time.perf_counter()
        for i in range(passes):
            img = np.array(mi.render(scene, spp=SPP_PER_PASS, seed=seed_base + i), dtype=np.float64)[:, :, :3]
            total = img if total is None else total + img
            if (i + 1) % 50 == 0 or i + 1 == passes:
                print(f"[reference] {label}: {i + 1}/{passes} passes, {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
        return total / passes

    scene_t = mi.load_file(str(SCENE), integrator="ptracer")
    scene_p = mi.load_file(str(SCENE), integrator="path")
    # The same scene with black specular surfaces (P0). The XML's Mirror and Glass BSDFs
    # get zero reflectance and transmittance; meshes are found through the scene's folder.
    text = SCENE.read_text()
    text, n_mirror = re.subn(r'(<string name="material" value="none"/>)', r'\1<rgb name="specular_reflectance" value="0"/>', text)
    text, n_glass = re.subn(r'(<bsdf type="dielectric" id="Glass">)', r'\1<rgb name="specular_reflectance" value="0"/><rgb name="specular_transmittance" value="0"/>', text)
    if (n_mirror, n_glass) != (1, 1):
        sys.exit(f"reference_open_mirror: cannot find the Mirror and Glass BSDFs in {SCENE} to blacken ({n_mirror}, {n_glass})")
    with tempfile.NamedTemporaryFile("w", suffix=".xml", dir=SCENE.parent, delete=False) as f:
        f.write(text)
        black_path = f.name
    try:
        scene_p0 = mi.load_file(black_path, integrator="path")
    finally:
        os.unlink(black_path)

    # Mask: pixels some of whose stratified camera rays first hit a delta BSDF.
    sensor = scene_t.sensors()[0]
    w, h = (int(v) for v in sensor.film().size())
    k = MASK_SAMPLES
    idx = dr.arange(mi.UInt32, w * h * k * k)
    pixel = idx // (k * k)
    sub = idx % (k * k)
    px = mi.Float(pixel % w) + (mi.Float(sub % k) + 0.5) / k
    py = mi.Float(pixel // w) + (mi.Float(sub // k) + 0.5) / k
    rays, _ = sensor.sample_ray(0.0, 0.0, mi.Point2f(px / w, py / h), mi.Point2f(0.5, 0.5))
    si = scene_t.ray_intersect(rays)
    delta = si.is_valid() & mi.has_flag(si.bsdf().flags(), mi.BSDFFlags.Delta)
    mask = np.array(delta).reshape(h, w, k * k).any(axis=2)

    T = render(scene_t, args.ptracer_passes, "ptracer", 0)
    P = render(scene_p, args.path_passes, "path", 1_000_000)
    P0 = render(scene_p0, args.path_passes, "path, black specular", 1_000_000)
    seconds = time.perf_counter() - started
    outside = np.abs(P - P0)[~mask]
    ref = T + mask[:, :, None] * (P - P0)

    spp = args.ptracer_passes * SPP_PER_PASS
    args.out_dir.mkdir(parents=True, exist_ok=True)
    stem = args.out_dir / f"open-mirror_mitsuba-ptracer_{w}x{h}_{spp}spp_{seconds:.0f}s"
    mi.Bitmap(ref.astype(np.float32)).write(str(stem.with_suffix(".exr")))
    mi.util.write_bitmap(str(stem.with_suffix(".png")), mi.Bitmap(ref.astype(np.float32)))
    info = {
        "scene": str(SCENE.relative_to(ROOT)),
        "mitsuba": mi.__version__,
        "variant": "llvm_ad_rgb",
        "threads": args.threads,
        "ptracer_spp": spp,
        "path_spp": args.path_passes * SPP_PER_PASS,
        "mask_samples_per_pixel": k * k,
        "mask_pixels": int(mask.sum()),
        "max_abs_path_difference_outside_mask": float(outside.max()) if outside.size else 0.0,
        "seconds": round(seconds, 1),
        "command": "python3 scripts/reference_open_mirror.py " + " ".join(sys.argv[1:]),
    }
    stem.with_suffix(".json").write_text(json.dumps(info, indent=2) + "\n")
    print(json.dumps(info))


if __name__ == "__main__":
    main()
