"""Type stubs of the arpa package (see arpa/__init__.py for the documentation)."""

import os
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

DEFAULT_ITERATIONS: int

class SceneError(ValueError):
    """A scene that cannot be loaded; the loader's message."""

    file: Optional[str]
    line: Optional[int]
    key: Optional[str]

class RenderError(RuntimeError):
    """A render that failed (backend, state file, output file)."""

class Scene:
    """A loaded scene (immutable)."""

    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def source(self) -> str: ...
    @property
    def max_depth(self) -> Optional[int]: ...

ProgressCallback = Callable[[int, float], None]

class Renderer:
    """A progressive render of one scene with fixed settings."""

    def __init__(
        self,
        scene: Scene,
        *,
        backend: str = "cpu",
        method: str = "arpa",
        photons: int = 250_000,
        seed: int = 0,
        max_depth: Optional[int] = None,
        smoothing: Optional[Tuple[float, float]] = None,
        bandwidth: str = "per-pixel",
        projection: bool = True,
        caustic_photons: Optional[int] = None,
        direct: bool = True,
        radius_caustic: Optional[float] = None,
        radius_global: Optional[float] = None,
        adapter: Optional[str] = None,
        resume: Optional[Union[str, os.PathLike]] = None,
        checkpoint: Optional[Union[str, os.PathLike]] = None,
        checkpoint_every: Optional[Union[int, str]] = None,
    ) -> None: ...
    def step(self, n: Optional[int] = None, *, seconds: Optional[float] = None, progress: Optional[ProgressCallback] = None) -> bool:
        """Renders n more iterations (default 1) or for `seconds`; False if Ctrl-C stopped it."""
    def image(self) -> npt.NDArray[np.float32]:
        """The image so far, float32 (H, W, 3), linear."""
    @property
    def iterations(self) -> int: ...
    def stats(self) -> Dict[str, Any]: ...
    def save(self, path: Union[str, os.PathLike], exposure: float = 1.0) -> None:
        """Saves .exr (linear), .png (sRGB) or .arpastate (the render's state)."""

def load_file(path: Union[str, os.PathLike], **defines: Any) -> Scene: ...
def load_dict(d: Dict[str, Any]) -> Scene: ...
def load_string(xml: str, path: Union[str, os.PathLike]) -> Scene: ...
def backends_compiled() -> List[str]: ...
def read_exr(path: Union[str, os.PathLike]) -> npt.NDArray[np.float32]: ...
def render(
    scene: Scene,
    backend: str = "cpu",
    method: str = "arpa",
    photons: int = 250_000,
    iterations: Optional[int] = None,
    seconds: Optional[float] = None,
    seed: int = 0,
    progress: Union[bool, ProgressCallback] = True,
    *,
    max_depth: Optional[int] = ...,
    smoothing: Optional[Tuple[float, float]] = ...,
    bandwidth: str = ...,
    projection: bool = ...,
    caustic_photons: Optional[int] = ...,
    direct: bool = ...,
    radius_caustic: Optional[float] = ...,
    radius_global: Optional[float] = ...,
    adapter: Optional[str] = ...,
    resume: Optional[Union[str, os.PathLike]] = ...,
    checkpoint: Optional[Union[str, os.PathLike]] = ...,
    checkpoint_every: Optional[Union[int, str]] = ...,
) -> npt.NDArray[np.float32]: ...
