"""Mitsuba 3 scene dicts (the format of ``mitsuba.load_dict``) as the Mitsuba XML that
arpa's loader reads.

Each element goes on its own line, and the line of every element is mapped to the dict key
path it came from (``"shape_floor.bsdf.reflectance"``), so that a loader error about a line
of the generated XML is reported against the key.
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Dict, List, Tuple
from xml.sax.saxutils import quoteattr

# Mitsuba 3 plugin types by the XML tag of their kind. Types the loader does not support
# still convert, and the loader then names them in an "unsupported" error.
_KINDS: Dict[str, Tuple[str, ...]] = {
    "shape": ("obj", "ply", "serialized", "rectangle", "cube", "sphere", "cylinder", "disk", "shapegroup",
              "instance", "mesh", "bsplinecurve", "linearcurve", "sdfgrid", "ellipsoids", "ellipsoidsmesh"),
    "bsdf": ("diffuse", "conductor", "roughconductor", "dielectric", "roughdielectric", "thindielectric",
             "plastic", "roughplastic", "principled", "principledthin", "twosided", "mask", "bumpmap",
             "normalmap", "blendbsdf", "null", "hair", "pplastic", "measured", "polarizer", "retarder",
             "circular"),
    "emitter": ("point", "spot", "directional", "area", "constant", "envmap", "projector", "directionalarea"),
    "texture": ("bitmap", "checkerboard", "mesh_attribute", "volume"),
    "sensor": ("perspective", "thinlens", "orthographic", "radiancemeter", "irradiancemeter", "distant", "batch"),
    "film": ("hdrfilm", "specfilm"),
    "sampler": ("independent", "stratified", "multijitter", "orthogonal", "ldsampler"),
    "rfilter": ("box", "tent", "gaussian", "mitchell", "catmullrom", "lanczos"),
    "integrator": ("path", "ptracer", "direct", "volpath", "volpathmis", "aov", "moment", "depth", "prb",
                   "prb_basic", "direct_projective", "prb_projective", "stokes", "particle"),
    "medium": ("homogeneous", "heterogeneous"),
    "phase": ("isotropic", "hg", "rayleigh", "blendphase", "tabphase"),
}
_TAG_OF = {t: kind for kind, types in _KINDS.items() for t in types}
# Top-level objects are written in this order (referenced objects before their users).
_ORDER = {"texture": 0, "bsdf": 1, "medium": 1}


class DictError(ValueError):
    """A dict that cannot be converted; ``key`` is the key path of the problem."""

    def __init__(self, key: str, message: str):
        super().__init__(f"scene dict, key '{key}': {message}")
        self.key = key


def _num(v: float) -> str:
    # repr of a Python float round-trips exactly, so the loader reads the same double.
    return repr(float(v))


def _matrix(value: Any) -> List[List[float]] | None:
    """A 4x4 matrix from a Mitsuba transform (``.matrix``) or a nested sequence/array."""
    m = getattr(value, "matrix", value)
    try:
        import numpy as np

        a = np.asarray(m, dtype=np.float64)
    except Exception:
        return None
    if a.shape == (4, 4):
        return a.tolist()
    if a.shape == (3, 3):
        b = np.eye(4)
        b[:3, :3] = a
        return b.tolist()
    return None


def _vector(value: Any) -> List[float] | None:
    """Three numbers from a list/tuple/array or a Mitsuba/Dr.Jit 3-vector."""
    if isinstance(value, (str, bytes, dict)):
        return None
    try:
        items = list(value)
    except TypeError:
        return None
    if len(items) != 3:
        return None
    try:
        return [float(x) for x in items]
    except (TypeError, ValueError):
        return None


class _Writer:
    def __init__(self) -> None:
        self.lines: List[str] = ['<?xml version="1.0" encoding="utf-8"?>']
        self.keys: Dict[int, str] = {}
        # String values by key path, to name the key of an error about a file (which has no line).
        self.strings: Dict[str, str] = {}

    def line(self, depth: int, text: str, key: str) -> None:
        self.lines.append("    " * depth + text)
        self.keys[len(self.lines)] = key

    def value(self, depth: int, name: str, value: Any, key: str, parent_type: str) -> None:
        """A property or nested object ``name`` of an object."""
        n = quoteattr(name)
        if isinstance(value, dict):
            self.obj(depth, name, value, key, nested=True)
        elif isinstance(value, bool):
            self.line(depth, f'<boolean name={n} value="{str(value).lower()}"/>', key)
        elif isinstance(value, numbers.Integral):
            self.line(depth, f'<integer name={n} value="{int(value)}"/>', key)
        elif isinstance(value, numbers.Real):
            if not math.isfinite(float(value)):
                raise DictError(key, f"{value!r} is not a finite number")
            self.line(depth, f'<float name={n} value="{_num(value)}"/>', key)
        elif isinstance(value, str):
            self.strings[key] = value
            self.line(depth, f"<string name={n} value={quoteattr(value)}/>", key)
        elif hasattr(value, "matrix") or (name == "to_world" or name == "to_uv"):
            m = _matrix(value)
            if m is None:
                raise DictError(key, f"expected a transform (a 4x4 matrix or a Mitsuba transform), got {type(value).__name__}")
            flat = ", ".join(_num(x) for row in m for x in row)
            self.line(depth, f"<transform name={n}>", key)
            self.line(depth + 1, f'<matrix value="{flat}"/>', key)
            self.line(depth, "</transform>", key)
        else:
            v = _vector(value)
            if v is None:
                raise DictError(key, f"cannot convert a value of type {type(value).__name__} (expected a number, bool, string, 3-vector, transform or dict)")
            tag = "rgb" if "Color" in type(value).__name__ else "point"
            self.line(depth, f'<{tag} name={n} value="{", ".join(_num(x) for x in v)}"/>', key)

    def obj(self, depth: int, name: str | None, d: Dict[str, Any], key: str, nested: bool) -> None:
        """An object ``d`` (a dict with ``type``): its element and its properties."""
        t = d.get("type")
        if not isinstance(t, str):
            raise DictError(key, "a nested dict needs a 'type' (a plugin name, 'rgb', 'spectrum' or 'ref')")
        n = f" name={quoteattr(name)}" if (nested and name is not None) else ""
        extra = sorted(set(d) - {"type", "value", "id", "filename"})
        if t == "rgb":
            if extra:
                raise DictError(f"{key}.{extra[0]}", "an 'rgb' dict takes only 'value'")
            v = d.get("value")
            if isinstance(v, numbers.Real) and not isinstance(v, bool):
                v = [float(v)] * 3
            vec = _vector(v)
            if vec is None:
                raise DictError(f"{key}.value", "an 'rgb' value is a number or 3 numbers")
            self.line(depth, f'<rgb{n} value="{", ".join(_num(x) for x in vec)}"/>', key)
            return
        if t == "spectrum":
            if "filename" in d:
                self.line(depth, f"<spectrum{n} filename={quoteattr(str(d['filename']))}/>", key)
                return
            v = d.get("value")
            if isinstance(v, numbers.Real) and not isinstance(v, bool):
                text = _num(v)
            else:
                try:
                    text = ", ".join(f"{_num(w)}:{_num(s)}" for w, s in v)
                except (TypeError, ValueError):
                    raise DictError(f"{key}.value", "a 'spectrum' value is a number or a list of (wavelength, value) pairs") from None
            self.line(depth, f"<spectrum{n} value={quoteattr(text)}/>", key)
            return
        if t == "ref":
            ref = d.get("id")
            if not isinstance(ref, str):
                raise DictError(key, "a 'ref' dict needs an 'id' (a string)")
            self.line(depth, f"<ref{n} id={quoteattr(ref)}/>", key)
            return
        tag = _TAG_OF.get(t)
        if tag is None:
            raise DictError(f"{key}.type", f"unknown plugin type '{t}'")
        ident = d.get("id", None if nested else name)
        i = f" id={quoteattr(str(ident))}" if ident is not None else ""
        self.line(depth, f"<{tag} type={quoteattr(t)}{i}{n}>", key)
        for k, v in d.items():
            if k in ("type", "id"):
                continue
            self.value(depth + 1, k, v, f"{key}.{k}", t)
        self.line(depth, f"</{tag}>", key)


def to_xml(d: Dict[str, Any]) -> Tuple[str, Dict[int, str], Dict[str, str]]:
    """The XML of scene dict ``d``, the key path of each 1-based line, and the string values
    by key path."""
    if not isinstance(d, dict):
        raise DictError("<root>", f"expected a dict, got {type(d).__name__}")
    if d.get("type") != "scene":
        raise DictError("type", "arpa renders whole scenes: the top-level dict needs 'type': 'scene'")
    w = _Writer()
    w.line(0, '<scene version="3.0.0">', "<root>")

    def rank(item: Tuple[int, Tuple[str, Any]]) -> Tuple[int, int]:
        i, (_, v) = item
        kind = _TAG_OF.get(v.get("type"), "") if isinstance(v, dict) else ""
        if kind == "shape" and isinstance(v, dict) and v.get("type") == "shapegroup":
            return (2, i)
        return (_ORDER.get(kind, 3), i)

    items = [(k, v) for k, v in d.items() if k != "type"]
    for _, (k, v) in sorted(enumerate(items), key=rank):
        if not isinstance(k, str):
            raise DictError(repr(k), "keys are strings")
        if not isinstance(v, dict):
            raise DictError(k, "top-level entries of a scene are objects (dicts with a 'type')")
        w.obj(1, k, v, k, nested=False)
    w.line(0, "</scene>", "<root>")
    return "\n".join(w.lines) + "\n", w.keys, w.strings
