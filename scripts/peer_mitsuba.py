#!/usr/bin/env python3
"""Renders a scene with Mitsuba 3 for a wall-clock budget: the equal-time peer of `arpa bench`.

Loads the Mitsuba XML as it is (the shared scenes are Mitsuba 3 files), renders one untimed
warm-up pass (the LLVM variant compiles its kernels then), then renders passes with new seeds
until the budget is spent, keeping the spp-weighted mean. After pass 1, 2, 4, 8, ... and after
the last pass it writes the mean so far as OpenEXR and prints one JSON line:

    {"event": "checkpoint", "pass": 4, "spp": 16, "seconds": 1.93, "file": "DIR/pass-4.exr"}

`seconds` is the render time of the passes so far (warm-up and writing excluded), the same
accounting as `arpa bench`'s own rows. The last line is {"event": "done", ...} with the same
fields. If Mitsuba is not installed it prints {"event": "skipped", "reason": ...} and exits 3,
so the caller can record a loud "skipped" row; any other failure exits 1 with a message.

Usage:
    scripts/peer_mitsuba.py --scene S.xml --integrator ptracer|path --seconds 10 \
        --threads 2 --out-dir DIR [--res WxH] [--variant llvm_ad_rgb] [--seed 0]
"""

import argparse
import glob
import json
import os
import sys
import time


def emit(event, **fields):
    print(json.dumps({"event": event, **fields}), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", required=True)
    ap.add_argument("--integrator", required=True, choices=["ptracer", "path"])
    ap.add_argument("--seconds", type=float, required=True)
    ap.add_argument("--threads", type=int, required=True)
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--res", default=None, help="WxH, default: the scene file's")
    ap.add_argument("--variant", default=None, help="default: llvm_ad_rgb where LLVM is found, else scalar_rgb")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--spp-per-pass", type=int, default=0, help="0: chosen from the warm-up's speed")
    args = ap.parse_args()

    if "DRJIT_LIBLLVM_PATH" not in os.environ:
        # Debian's libllvm19 (scripts/setup-debian.sh --with-peers) for the LLVM variant;
        # Debian 12's libLLVM 14 and 15 fail to compile Dr.Jit's kernels.
        for lib in sorted(glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM.so.19*")):
            os.environ["DRJIT_LIBLLVM_PATH"] = lib
            break
    try:
        import mitsuba as mi
        import drjit as dr
        import numpy as np
    except ImportError as e:
        emit("skipped", reason=f"mitsuba is not installed ({e}); `bash scripts/setup-debian.sh --with-peers` installs it")
        return 3

    variants = [args.variant] if args.variant else ["llvm_ad_rgb", "scalar_rgb"]
    chosen = None
    errors = []
    for v in variants:
        try:
            mi.set_variant(v)
            chosen = v
            break
        except Exception as e:  # noqa: BLE001 (a variant that cannot start: try the next)
            errors.append(f"{v}: {e}")
    if chosen is None:
        emit("skipped", reason="no Mitsuba variant starts: " + "; ".join(errors))
        return 3
    dr.set_thread_count(args.threads)

    params = {"integrator": args.integrator}
    if args.res:
        w, h = args.res.lower().split("x")
        params["res_x"], params["res_y"] = int(w), int(h)
    try:
        scene = mi.load_file(args.scene, **params)
    except Exception as e:  # noqa: BLE001
        print(f"peer_mitsuba: cannot load '{args.scene}': {e}", file=sys.stderr)
        return 1
    os.makedirs(args.out_dir, exist_ok=True)

    # Warm-up, not counted: compiles the kernels (LLVM variant; a kernel is compiled per
    # spp), measures one sample per pixel, then compiles for the spp per pass chosen.
    t0 = time.perf_counter()
    np.array(mi.render(scene, spp=1, seed=2**31 - 1))
    spp = args.spp_per_pass
    if spp <= 0:
        # About 20 passes in the budget, so the time checkpoints are fine-grained.
        t1 = time.perf_counter()
        np.array(mi.render(scene, spp=1, seed=2**31 - 2))
        one = max(time.perf_counter() - t1, 1e-4)
        spp = max(1, int(args.seconds / 20.0 / one))
    np.array(mi.render(scene, spp=spp, seed=2**31 - 3))
    warm = time.perf_counter() - t0

    total = None
    total_spp = 0
    elapsed = 0.0
    passes = 0

    def write(event):
        path = os.path.join(args.out_dir, f"pass-{passes}.exr")
        mi.Bitmap((total / total_spp).astype(np.float32)).write(path)
        emit(event, **{"pass": passes, "spp": total_spp, "seconds": round(elapsed, 6), "file": path,
                       "variant": chosen, "threads": args.threads, "warmup_seconds": round(warm, 3)})

    while passes == 0 or elapsed < args.seconds:
        t0 = time.perf_counter()
        img = np.array(mi.render(scene, spp=spp, seed=args.seed * 100003 + passes), dtype=np.float64)
        elapsed += time.perf_counter() - t0
        img = img[:, :, :3] * spp
        total = img if total is None else total + img
        total_spp += spp
        passes += 1
        if passes & (passes - 1) == 0:
            write("checkpoint")
    write("done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
