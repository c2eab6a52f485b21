"""ipfn: the Implicit Periodic Field Network (Chen et al., CVPR 2022) from Python.

Learn a pattern from one exemplar, then paint new, varied, seamless versions of it at any
size, as numpy arrays::

    import ipfn
    model = ipfn.load()                    # the shipped honeycomb (or a .ipfn file, a run folder)
    image = model.paint(512, 512, seed=3)  # float32 [512, 512, 3], values in [-1, 1]
    run = ipfn.train("wall.jpg", time="5m")   # a Model, read from the run folder
    ipfn.evaluate(run, "wall.jpg")["sifid"]["mean"]

Every call is the command line's (`ipfn synth`, `ipfn train`, `ipfn fit`, `ipfn eval`) with
the same arguments and the same pixels; bad input raises `InputError` (a `ValueError`),
anything else `IpfnError`, each with the command line's one-line message.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable, Dict, Mapping, Optional, Sequence, Union

import numpy as np

from . import _ipfn
from ._errors import InputError, IpfnError
from ._ipfn import Model, __version__

__all__ = [
    "InputError",
    "IpfnError",
    "Model",
    "compare_images",
    "evaluate",
    "fit",
    "load",
    "train",
    "write_image",
    "__version__",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Callable[[Dict[str, Any]], Optional[bool]]



class _Default(str):
    """A default argument's value, told apart from the same value given by the caller."""


_DEFAULT_TIME = _Default("15m")


def load(path: Optional[PathLike] = None) -> Model:
    """Read a model: a `.ipfn` file of any kind (image, map set, solid texture, volume,
    fitted tile) or a run folder (its `tile.ipfn`, `best.ipfn` or `latest.ipfn`).

    With no path, the shipped honeycomb (the IPFN authors' pretrained generator).
    """
    return _ipfn.load(None if path is None else os.fspath(path))


def train(
    exemplar: Union[PathLike, np.ndarray, None] = None,
    *,
    time: Optional[str] = _DEFAULT_TIME,
    out: Optional[PathLike] = None,
    seed: int = 0,
    on_progress: Optional[Progress] = None,
    resume: Optional[PathLike] = None,
    maps: Optional[Sequence[PathLike]] = None,
    config: Optional[PathLike] = None,
    device: str = "auto",
    **overrides: Any,
) -> Model:
    """Train a generator on `exemplar`, as `ipfn train` does; returns the run's model.

    exemplar: an image file, or an image array `[H, W, C]` (`uint8`, `uint16`, or floats in
        [0, 1]), which is written to the run folder as `exemplar.png` (16-bit) and trained
        from there, so that the run can be resumed.
    time: the time budget ("15m", "90s", "1h30m"). With `iterations=N` and no `time`, the run
        trains N iterations instead.
    out: the run folder (default `runs/<exemplar name>`, or `runs/exemplar` for an array).
    seed: the seed of every random draw.
    on_progress: called after every iteration with a dict: `iteration`, `iterations` (the
        planned total), `wasserstein`, `penalty`, `generator_loss`, `k`,
        `iterations_per_second`, at checkpoints `sifid`, `structure` and `repeat` (else
        None), `map_structure` (a map set's structure distance per map at checkpoints, else
        an empty list), `run_dir`, and `preview` (the preview image written at this iteration, a float32
        array in [-1, 1], else None). Returning `False` stops the run after a checkpoint.
    resume: a run folder to continue exactly where it stopped (give `time` or `iterations` for
        its new length; settings that shape the model cannot change).
    maps: a material map set (aligned images) instead of `exemplar`.
    config: a TOML config file; `overrides` apply over it.
    device: "auto" (the best present: CUDA, a wgpu GPU, else the CPU), "cpu", "wgpu", "cuda".
    overrides: any config key of `ipfn train` (see `configs/default.toml`), e.g. `batch=4`,
        `crop=32`, `iterations=500`, `critic_widths=[32, 64, 128, 256]`.

    Ctrl-C stops the run after a checkpoint and raises KeyboardInterrupt; `resume=` continues.
    """
    settings: Dict[str, Any] = dict(overrides)
    budget = time
    if time is _DEFAULT_TIME and "iterations" in overrides:
        budget = None
    if budget is not None:
        settings["time"] = budget
    image = None
    if resume is None:
        settings["seed"] = seed
        if isinstance(exemplar, np.ndarray):
            image, exemplar = exemplar, None
            out = Path(out if out is not None else Path("runs") / "exemplar")
            out.mkdir(parents=True, exist_ok=True)
            exemplar = out / "exemplar.png"
            _ipfn.write_image(os.fspath(exemplar), _to_unit_range(image), bits=16)
    run_dir = _ipfn.train(
        exemplar=None if exemplar is None else os.fspath(exemplar),
        maps=None if maps is None else [os.fspath(m) for m in maps],
        config=None if config is None else os.fspath(config),
        settings=_toml(settings) if settings else None,
        out=None if out is None else os.fspath(out),
        resume=None if resume is None else os.fspath(resume),
        device=device,
        on_progress=on_progress,
    )
    return load(run_dir)


def fit(
    photo: Optional[PathLike] = None,
    *,
    maps: Optional[Sequence[PathLike]] = None,
    period: Optional[Sequence[int]] = None,
    time: Optional[str] = None,
    iterations: Optional[int] = None,
    run: Optional[PathLike] = None,
    out: Optional[PathLike] = None,
    resume: Optional[PathLike] = None,
    mask: Optional[PathLike] = None,
    bits: Optional[int] = None,
    device: str = "auto",
    seed: Optional[int] = None,
) -> Dict[str, Any]:
    """Fit a seamless tile to `photo` (or a map set), as `ipfn fit` does.

    Returns the report `ipfn eval --json` gives for the tile (`psnr`, `psnr_interior`,
    `seam_tile`, `seam_photo`, `seam_photo_lines`), with `model` (the tile's `.ipfn`, for
    `ipfn.load`) and `images` (the tile image files written). `period` is (width, height) in
    photo pixels; `time` defaults to 10 minutes unless `iterations` is given.
    """
    report = _ipfn.fit(
        photo=None if photo is None else os.fspath(photo),
        maps=None if maps is None else [os.fspath(m) for m in maps],
        period=None if period is None else (int(period[0]), int(period[1])),
        time=time,
        iterations=iterations,
        run=None if run is None else os.fspath(run),
        out=None if out is None else os.fspath(out),
        resume=None if resume is None else os.fspath(resume),
        mask=None if mask is None else os.fspath(mask),
        bits=bits,
        device=device,
        seed=seed,
    )
    return json.loads(report)


def evaluate(
    model: Union[Model, PathLike],
    exemplar: PathLike,
    *,
    samples: int = 8,
    seed: int = 0,
    device: str = "cpu",
) -> Dict[str, Any]:
    """Score a model against its exemplar: the dict `ipfn eval --json` prints.

    A generator: `sifid` and `structure` (mean, std and values over `samples` samples at the
    exemplar's size), `structure_floor`, `seam_model_tile`, `period_model`, `repeat_model`,
    and the exemplar's own figures. A fitted tile: `psnr`, `psnr_interior`, `seam_tile`.
    """
    if not isinstance(model, Model):
        model = load(model)
    return json.loads(
        _ipfn.evaluate(model, os.fspath(exemplar), samples=samples, seed=seed, device=device)
    )


def write_image(path: PathLike, image: np.ndarray, *, bits: int = 8) -> None:
    """Write an array as `ipfn synth` writes images: `[H, W, C]` float values in [-1, 1] (what
    `Model.paint` returns) to a .png (8 or 16 `bits`), .exr or .npy, atomically."""
    if image.ndim == 2:
        image = image[:, :, None]
    _ipfn.write_image(os.fspath(path), np.ascontiguousarray(image, dtype=np.float32), bits=bits)


def compare_images(a: PathLike, b: PathLike) -> Dict[str, Any]:
    """SIFID of image `a` to image `b`, and `b`'s structure distance to `a` (with `a`'s floor),
    as `ipfn eval --images A B --json` prints them."""
    return json.loads(_ipfn.compare_images(os.fspath(a), os.fspath(b)))


def _to_unit_range(image: np.ndarray) -> np.ndarray:
    """An image array as float32 `[H, W, C]` in [-1, 1]."""
    if image.ndim == 2:
        image = image[:, :, None]
    if image.ndim != 3 or not 1 <= image.shape[2] <= 4:
        raise InputError(
            f"exemplar array of shape {image.shape}: expected [H, W, C] with 1 to 4 channels"
        )
    if image.dtype == np.uint8:
        unit = image.astype(np.float32) / 255.0
    elif image.dtype == np.uint16:
        unit = image.astype(np.float32) / 65535.0
    elif np.issubdtype(image.dtype, np.floating):
        unit = image.astype(np.float32)
        if unit.size and (unit.min() < 0.0 or unit.max() > 1.0):
            raise InputError("exemplar array: float values must lie in [0, 1]")
    else:
        raise InputError(f"exemplar array of {image.dtype}: expected uint8, uint16 or floats")
    return np.ascontiguousarray(unit * 2.0 - 1.0, dtype=np.float32)


def _toml(settings: Mapping[str, Any]) -> str:
    """Config keys as TOML text (numbers, strings, booleans and lists of them)."""

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, np.integer)):
            return str(int(v))
        if isinstance(v, (float, np.floating)):
            return repr(float(v))
        if isinstance(v, (str, os.PathLike)):
            return json.dumps(os.fspath(v))
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        raise InputError(f"setting value {v!r}: expected a number, string, boolean or list")

    return "".join(f"{key} = {value(v)}\n" for key, v in settings.items())
