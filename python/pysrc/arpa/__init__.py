"""arpa: photon mapping with photon differentials (ARPA) for Mitsuba 3 scenes.

    import arpa
    scene = arpa.load_file("scene.xml", spp=64)      # like mitsuba.load_file
    image = arpa.render(scene, seconds=10)            # float32 (H, W, 3), linear

``load_dict`` takes the dict format of ``mitsuba.load_dict``. ``Renderer`` renders
progressively (``step``, ``image``, ``stats``, ``save``) and checkpoints / resumes through the
CLI's state files. Ctrl-C during a render stops it after the current iteration and returns
the image so far (with a warning). Errors are ``SceneError`` (the loader's message, with
``file`` and ``line``; ``key`` for dicts) and ``RenderError``.
"""

from __future__ import annotations

import os
import warnings
from typing import Any, Callable, Dict, Optional, Union

from . import _dict
from ._arpa import RenderError, Renderer, Scene, SceneError, backends_compiled, load_string, read_exr
from ._arpa import load_file as _load_file

__all__ = ["load_file", "load_dict", "render", "Renderer", "Scene", "SceneError", "RenderError", "backends_compiled", "read_exr"]

#: Iterations of ``render`` given neither ``iterations`` nor ``seconds`` (the CLI's default).
DEFAULT_ITERATIONS = 64


def load_file(path: Union[str, os.PathLike], **defines: Any) -> Scene:
    """Loads a Mitsuba 3 XML scene file (or glTF 2.0); keyword arguments override its
    ``<default>`` parameters, as in ``mitsuba.load_file(path, spp=64)``."""
    return _load_file(os.fspath(path), [(k, str(v)) for k, v in defines.items()])


def load_dict(d: Dict[str, Any]) -> Scene:
    """Loads a scene given as a ``mitsuba.load_dict`` dict (``{'type': 'scene', ...}``), for
    the plugins the loader supports. Transforms may be Mitsuba transforms or 4x4 arrays;
    relative file names are resolved against the current directory, as Mitsuba does.
    Errors name the dict key path."""
    try:
        xml, keys, strings = _dict.to_xml(d)
    except _dict.DictError as e:
        err = SceneError(str(e))
        err.file, err.line, err.key = None, None, e.key
        raise err from None
    where = os.path.join(os.getcwd(), "<dict>.xml")
    try:
        return load_string(xml, where)
    except SceneError as e:
        line = getattr(e, "line", None)
        key = keys.get(line) if line is not None else None
        message = str(e)
        for prefix in (f"{where}:{line}: ", f"{where}: "):
            message = message.replace(prefix, "")
        message = message.replace(where, "<dict>")
        if key is None:
            # Errors about a file (a mesh, a texture) name the file, not a line.
            key = next((k for k, v in strings.items() if v and (f"'{v}'" in message or f"'{os.path.join(os.getcwd(), v)}'" in message)), None)
        err = SceneError(f"scene dict, key '{key}': {message}" if key else f"scene dict: {message}")
        err.file, err.line, err.key = None, None, key
        raise err from None


def _progress_adapter(progress: Any, iterations: Optional[int], seconds: Optional[float]):
    """The per-iteration callback for ``progress``: a callable as given, ``True`` a tqdm
    bar when tqdm is installed, otherwise nothing. Returns (callback, close)."""
    if callable(progress):
        return progress, lambda: None
    if not progress:
        return None, lambda: None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None, lambda: None
    if seconds is not None:
        bar = tqdm(total=round(seconds, 1), unit="s", desc="arpa", leave=False)

        def update(it: int, secs: float) -> None:
            bar.n = min(round(secs, 1), bar.total)
            bar.set_postfix_str(f"{it} it", refresh=False)
            bar.refresh()
    else:
        bar = tqdm(total=iterations, unit="it", desc="arpa", leave=False)

        def update(it: int, secs: float) -> None:
            bar.n = it
            bar.refresh()

    return update, bar.close


def render(
    scene: Scene,
    backend: str = "cpu",
    method: str = "arpa",
    photons: int = 250_000,
    iterations: Optional[int] = None,
    seconds: Optional[float] = None,
    seed: int = 0,
    progress: Union[bool, Callable[[int, float], None]] = True,
    **options: Any,
) -> Any:
    """Renders ``scene`` and returns a NumPy ``float32`` array ``(H, W, 3)`` of linear
    radiance. ``iterations`` (default 64) or ``seconds`` is the budget; ``photons`` are
    emitted per iteration. The same seed, settings and backend give the same image bit for
    bit, equal to ``arpa render`` with the same options. ``progress``: ``True`` shows a tqdm
    bar when tqdm is installed, a callable is called as ``progress(iterations, seconds)``
    after each iteration. ``options`` are those of ``Renderer`` (``max_depth``,
    ``smoothing``, ``bandwidth``, ``checkpoint``, ``resume``, ...). With ``resume``,
    ``iterations`` counts the whole render, as the CLI's ``--iterations`` does.

    Ctrl-C stops the render after the current iteration and returns the image so far,
    with a ``RuntimeWarning``.
    """
    if iterations is not None and seconds is not None:
        raise ValueError("give iterations or seconds, not both")
    if iterations is not None and iterations < 1:
        raise ValueError(f"iterations must be at least 1, got {iterations}")
    r = Renderer(scene, backend=backend, method=method, photons=photons, seed=seed, **options)
    if seconds is None:
        total = DEFAULT_ITERATIONS if iterations is None else iterations
        todo = total - r.iterations
        if todo < 0:
            raise ValueError(f"the resumed state already holds {r.iterations} iterations, beyond iterations={total}")
    callback, close = _progress_adapter(progress, None if seconds is not None else todo, seconds)
    try:
        if seconds is not None:
            finished = r.step(seconds=seconds, progress=callback)
        else:
            finished = r.step(todo, progress=callback)
    finally:
        close()
    if not finished:
        warnings.warn(f"arpa: render interrupted after {r.iterations} iterations; returning the image so far", RuntimeWarning, stacklevel=2)
    return r.image()
