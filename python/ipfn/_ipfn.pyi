"""Type stubs of the compiled part of ipfn (`ipfn._ipfn`); `ipfn` re-exports `Model`."""

from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class Model:
    """A trained generator or a fitted tile, read once from its file by `ipfn.load`."""

    @property
    def kind(self) -> str:
        """What it paints: "image", "map_set", "solid", "volume" or "tile"."""
    @property
    def channels(self) -> int:
        """Channels painted (every map's together for a map set)."""
    @property
    def map_names(self) -> List[str]:
        """A map set's maps, in order (the keys of `paint`'s dict); empty otherwise."""
    @property
    def map_roles(self) -> List[Optional[str]]:
        """Each map's part in a material, from its file's name: "color", "normal", "height",
        "roughness", "ambient_occlusion", "metalness", or None; in `map_names` order."""
    @property
    def period(self) -> List[float]:
        """The pattern's period in pixels, rows then columns (depth first in 3D)."""
    @property
    def iteration(self) -> Optional[int]:
        """The training iteration the file was written at (None: imported, or a tile)."""
    @property
    def description(self) -> str:
        """Where the model came from, as `ipfn synth` prints it."""
    @property
    def path(self) -> Optional[str]:
        """The file or run folder it was read from (None for the shipped honeycomb)."""
    def paint(
        self,
        width: int,
        height: int,
        *,
        seed: int = 0,
        offset: Tuple[int, int] = (0, 0),
        zoom: float = 1.0,
        noise_scale: float = 1.0,
        tile: bool = False,
        mirror: bool = False,
        device: str = "auto",
        depth: Optional[int] = None,
        slice: Optional[Tuple[str, int]] = None,
        guide: Optional[str] = None,
        density: Optional[Tuple[float, float]] = None,
        lod: Optional[float] = None,
    ) -> Union[npt.NDArray[np.float32], Dict[str, npt.NDArray[np.float32]]]:
        """Paint `width` x `height` pixels, equal value for value to
        `ipfn synth --size WxH ... --out x.npy` with the same arguments.

        Returns a float32 array `[height, width, channels]` with values in [-1, 1] (a fitted
        tile's and a volume's may stray slightly outside); a map set gives a dict of one array
        per map (normal maps renormalised); a volume (`depth=D`) `[D, height, width, C]`; a
        solid texture its z = 0 plane unless `depth` or `slice` asks otherwise.

        seed: the latent field's seed: each seed paints a different sample.
        offset: the output's top-left pixel (x, y) in the infinite plane.
        zoom: 2 paints the pattern twice as large.
        noise_scale: above 1, structure varies over larger regions.
        tile: make the output tile seamlessly (K snapped to whole periods).
        mirror: a mirror-symmetric tile.
        device: "auto" (the best present: CUDA, a wgpu GPU, else the CPU), "cpu", "flex",
            "wgpu" or "cuda".
        slice: ("z", 0) paints one plane of a 3D model's volume.
        guide: a guided model's guidance: "x", "y", "-x", "-y", "a,b,c", or a grayscale
            image's path.
        density: a density-controlled volume's density, as (from, to) across its width.
        lod: a fitted tile's level of detail, in stages.
        """

def load(path: Optional[str] = None) -> Model: ...
def write_image(path: str, values: npt.NDArray[np.float32], bits: int = 8) -> None: ...
def train(
    *,
    exemplar: Optional[str] = None,
    maps: Optional[Sequence[str]] = None,
    config: Optional[str] = None,
    settings: Optional[str] = None,
    out: Optional[str] = None,
    resume: Optional[str] = None,
    device: str = "auto",
    on_progress: Optional[Callable[[Dict[str, Any]], Optional[bool]]] = None,
) -> str: ...
def fit(
    *,
    photo: Optional[str] = None,
    maps: Optional[Sequence[str]] = None,
    period: Optional[Tuple[int, int]] = None,
    time: Optional[str] = None,
    iterations: Optional[int] = None,
    run: Optional[str] = None,
    out: Optional[str] = None,
    resume: Optional[str] = None,
    mask: Optional[str] = None,
    bits: Optional[int] = None,
    device: str = "auto",
    seed: Optional[int] = None,
) -> str: ...
def evaluate(
    model: Model, exemplar: str, *, samples: int = 8, seed: int = 0, device: str = "cpu"
) -> str: ...
def compare_images(a: str, b: str) -> str: ...
