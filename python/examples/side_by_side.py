"""Renders the shared cornell-caustic scene with arpa and with Mitsuba 3 (its light tracer,
``ptracer``, what Mitsuba users render caustics with) for about the same time, from one
``mitsuba.load_dict`` dict, and prints the relMSE of both against the scene's reference.

    python python/examples/side_by_side.py [--seconds 10] [--scenes ../shared/scenes]

Mitsuba is optional (``pip install mitsuba``): without it only arpa runs, and the Mitsuba
row says loudly that it was skipped. relMSE is arpa's metric: the mean over pixels and
channels of (x - ref)^2 / (ref^2 + 0.01).
"""

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

import arpa

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cornell_caustic  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def rel_mse(image: np.ndarray, reference: np.ndarray) -> float:
    image = np.nan_to_num(image.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    reference = reference.astype(np.float64)
    return float(np.mean((image - reference) ** 2 / (reference**2 + 0.01)))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0, help="render time of each renderer (default 10)")
    parser.add_argument("--scenes", type=Path, default=Path(os.environ.get("ARPA_SHARED_SCENES", REPO.parent / "shared" / "scenes")))
    args = parser.parse_args()

    scene_dir = args.scenes / "cornell-caustic"
    refs = sorted((scene_dir / "reference").glob("*mitsuba-path*.exr"))
    if not refs:
        print(f"error: no reference under {scene_dir / 'reference'} (pass --scenes DIR)", file=sys.stderr)
        return 2
    reference = arpa.read_exr(refs[0])
    print(f"reference: {refs[0].name}, {reference.shape[1]}x{reference.shape[0]}")

    try:
        import mitsuba as mi

        mi.set_variant("scalar_rgb")
        look_at = mi.ScalarTransform4f.look_at
    except ImportError:
        mi, look_at = None, None
    # One dict for both renderers (Mitsuba needs its own transform type; arpa reads it too).
    d = cornell_caustic.scene_dict(str(scene_dir), look_at_fn=look_at)

    t0 = time.monotonic()
    ours = arpa.render(arpa.load_dict(d), seconds=args.seconds, seed=1)
    t_ours = time.monotonic() - t0
    print(f"arpa (cpu, ARPA)        {t_ours:6.1f} s   relMSE {rel_mse(ours, reference):.5f}   mean/ref {ours.mean() / reference.mean():.4f}")

    if mi is None:
        print("mitsuba                 SKIPPED: mitsuba is not installed (pip install mitsuba) -- no comparison row", file=sys.stderr)
    else:
        d["integrator"] = {"type": "ptracer", "max_depth": 12}
        scene = mi.load_dict(d)
        # Calibrate the sample count to the same wall-clock time.
        t0 = time.monotonic()
        mi.render(scene, spp=4)
        per_spp = (time.monotonic() - t0) / 4
        spp = max(1, int(args.seconds / max(per_spp, 1e-6)))
        t0 = time.monotonic()
        theirs = np.array(mi.render(scene, spp=spp, seed=1), dtype=np.float32)
        t_theirs = time.monotonic() - t0
        print(f"mitsuba (ptracer, {spp:4d} spp) {t_theirs:5.1f} s   relMSE {rel_mse(theirs, reference):.5f}   mean/ref {theirs.mean() / reference.mean():.4f}")

    return 0


if __name__ == "__main__":
    sys.exit(main())
