"""The shared cornell-caustic scene (../shared/scenes/cornell-caustic/scene.xml) written as a
``mitsuba.load_dict`` dict: the same dict renders in arpa (``arpa.load_dict``) and, unchanged,
in Mitsuba 3 (``mi.load_dict``)."""

import os
from typing import Any, Callable, Dict, Optional


def look_at(origin, target, up):
    """Mitsuba's look-at matrix (row-major 4x4 nested lists, float64), for use without
    Mitsuba; with Mitsuba pass ``mi.ScalarTransform4f.look_at`` instead."""
    import numpy as np

    o, t, u = (np.asarray(v, dtype=np.float64) for v in (origin, target, up))
    d = t - o
    d = d / np.linalg.norm(d)
    left = np.cross(u, d)
    left = left / np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, o
    return m.tolist()


def scene_dict(scene_dir: str, width: int = 256, height: int = 256, spp: int = 256, max_depth: int = 12,
               look_at_fn: Optional[Callable[..., Any]] = None) -> Dict[str, Any]:
    """The dict; ``scene_dir`` holds ``meshes/``; ``look_at_fn(origin=, target=, up=)`` makes
    the camera transform (default: :func:`look_at`; ``mi.ScalarTransform4f.look_at`` for Mitsuba)."""
    make = look_at_fn or look_at
    mesh = lambda name: os.path.join(scene_dir, "meshes", name + ".ply")  # noqa: E731

    def twosided(rgb):
        return {"type": "twosided", "material": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}}}

    def ply(name, bsdf, **extra):
        return {"type": "ply", "filename": mesh(name), "bsdf": {"type": "ref", "id": bsdf}, **extra}

    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": 19.5,
            "to_world": make(origin=[0, 1, 6.8], target=[0, 1, 0], up=[0, 1, 0]),
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
        "White": twosided([0.725, 0.71, 0.68]),
        "Red": twosided([0.63, 0.065, 0.05]),
        "Green": twosided([0.14, 0.45, 0.091]),
        "Glass": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0},
        "Mirror": {"type": "twosided", "material": {"type": "conductor", "material": "none",
                                                     "specular_reflectance": {"type": "rgb", "value": [0.95, 0.95, 0.95]}}},
        "Black": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
        "floor": ply("Floor", "White"),
        "ceiling": ply("Ceiling", "White"),
        "back": ply("BackWall", "White"),
        "left": ply("LeftWall", "Red"),
        "right": ply("RightWall", "Green"),
        "sphere": ply("GlassSphere", "Glass"),
        "mirror": ply("MirrorBox", "Mirror"),
        "light": ply("Light", "Black", emitter={"type": "area", "radiance": {"type": "rgb", "value": [40.0, 34.0, 26.0]}}),
    }
