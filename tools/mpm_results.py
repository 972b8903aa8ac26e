"""Read the snapshots an MPM run writes (``<output directory>/points.h5``).

The file is written by ``mpm::SnapshotWriter`` (mpm_solver/src/output.cpp, which
documents the layout in full). In short::

    /                  attributes dimension, mpm_version, format, format_version
                       (+ grid_origin, grid_dx, grid_dims with grid output)
    /materials         material names; ``material`` indexes this list
    /grid_coordinates  node positions, dims x D (grid output only)
    /frames/NNNNNN     attributes time [s], step; datasets position (N x D, m),
                       velocity (N x D, m/s), mass (N), volume (N), stress
                       (N x D x D Cauchy, Pa, tension positive), pressure (N, Pa,
                       -trace(stress)/D), plastic_strain (N), material (N, uint16)
    /frames/NNNNNN/grid   mass (dims), velocity (dims x D) (grid output only)

Coupled runs (format_version 2) also write, per frame, the points' ``zone``
(int8: 0 discrete, 1 hybrid, 2 continuum) and ``weight`` (N), and the DEM side
in ``/frames/NNNNNN/grains``: id (G, int64), position and velocity (G x 3, also
in 2D), radius, mass (the mass the grain carries), weight (G), zone (G, int8);
see :func:`read_grains`.

In 2D, ``velocity3`` and ``stress3`` are zero-padded copies kept for ParaView
(XDMF); this module does not return them.

Example::

    run = load_run("mpm_output")
    for info in run.frames:
        print(info.time, info.step)
    last = run.frame(-1)
    height = surface_profile(last["position"], bins=50)
    front = runout(last["position"], 0.001)

The module keeps no global state and no file open between calls, so it can
be used on the output of a run that is still writing (see ``Run(live=True)``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple, Union

import h5py
import numpy as np

__all__ = [
    "FrameInfo",
    "Run",
    "load_run",
    "final_frame",
    "read_grains",
    "read_grid",
    "surface_profile",
    "runout",
]

POINTS_FILE = "points.h5"

#: Datasets written only for XDMF/ParaView, identical in content to others.
_XDMF_ONLY = {"velocity3", "stress3"}


@dataclass(frozen=True)
class FrameInfo:
    """One snapshot: its index in :attr:`Run.frames`, group name, time [s] and solver step."""

    index: int
    name: str
    time: float
    step: int


def _decode(value) -> str:
    return value.decode("utf-8") if isinstance(value, (bytes, np.bytes_)) else str(value)


@dataclass
class Run:
    """The snapshots of one run, read from ``<directory>/points.h5``.

    Attributes:
        directory: the run's output directory.
        dimension: 2 or 3.
        version: the mpm release that wrote the file.
        materials: material names; a point's ``material`` value indexes this list.
        frames: the frames in the order written, as :class:`FrameInfo`.
        grid: ``None``, or a dict with ``origin`` (D), ``dx`` and ``dims`` (D)
            when the run wrote grid fields.
        live: open the file without HDF5 file locking, to read a run that is
            still writing. Frames are flushed as they are written, so all
            but possibly the newest are complete.
    """

    directory: str
    live: bool = False
    dimension: int = field(init=False)
    version: str = field(init=False)
    materials: List[str] = field(init=False)
    frames: List[FrameInfo] = field(init=False)
    grid: Optional[Dict[str, np.ndarray]] = field(init=False)

    def __post_init__(self) -> None:
        self.directory = os.fspath(self.directory)
        with self._open() as f:
            self.dimension = int(f.attrs["dimension"])
            self.version = _decode(f.attrs.get("mpm_version", ""))
            self.materials = [_decode(s) for s in f["materials"][()]] if "materials" in f else []
            self.grid = None
            if "grid_dims" in f.attrs:
                self.grid = {
                    "origin": np.asarray(f.attrs["grid_origin"], dtype=float),
                    "dx": float(f.attrs["grid_dx"]),
                    "dims": np.asarray(f.attrs["grid_dims"], dtype=np.int64),
                }
            frames = []
            group = f["frames"] if "frames" in f else {}
            for i, name in enumerate(sorted(group)):
                attrs = group[name].attrs
                frames.append(FrameInfo(i, name, float(attrs["time"]), int(attrs["step"])))
            self.frames = frames

    @property
    def path(self) -> str:
        """Path of the HDF5 file."""
        return os.path.join(self.directory, POINTS_FILE)

    def _open(self) -> h5py.File:
        if self.live:
            return h5py.File(self.path, "r", locking=False)
        return h5py.File(self.path, "r")

    def __len__(self) -> int:
        return len(self.frames)

    def frame(self, i: int, fields: Optional[Sequence[str]] = None) -> Dict[str, np.ndarray]:
        """Read frame ``i`` (negative counts from the end) into a dict of numpy arrays.

        Keys: ``time`` and ``step`` (numpy scalars), every point dataset
        (``position``, ``velocity``, ``mass``, ``volume``, ``stress``,
        ``pressure``, ``plastic_strain``, ``material``), and with grid output
        ``grid_mass`` (dims) and ``grid_velocity`` (dims x D) indexed
        ``[i, j(, k)]`` for the node at ``origin + dx * (i, j(, k))``.

        Args:
            i: frame index.
            fields: read only these datasets (names as above); default all.
        """
        info = self.frames[i]
        out: Dict[str, np.ndarray] = {
            "time": np.float64(info.time),
            "step": np.int64(info.step),
        }
        with self._open() as f:
            group = f["frames"][info.name]
            for name, item in group.items():
                if isinstance(item, h5py.Dataset) and name not in _XDMF_ONLY:
                    if fields is None or name in fields:
                        out[name] = item[()]
            if "grid" in group:
                for name, item in group["grid"].items():
                    key = "grid_" + name
                    if name not in _XDMF_ONLY and (fields is None or key in fields):
                        out[key] = item[()]
        return out

    def grid_coordinates(self) -> Optional[np.ndarray]:
        """Node positions (dims x D), or ``None`` if the run wrote no grid fields."""
        with self._open() as f:
            return f["grid_coordinates"][()] if "grid_coordinates" in f else None


def load_run(directory: Union[str, os.PathLike], live: bool = False) -> Run:
    """Open the run whose output directory is ``directory`` (see :class:`Run`)."""
    return Run(os.fspath(directory), live=live)


def final_frame(directory: Union[str, os.PathLike], live: bool = False) -> Dict[str, np.ndarray]:
    """The last frame of the run in ``directory``, as :meth:`Run.frame` returns it."""
    run = load_run(directory, live=live)
    if not run.frames:
        raise ValueError(f"{run.path} holds no frames")
    return run.frame(-1)


#: Datasets of a frame's ``grains`` group (coupled runs).
GRAIN_FIELDS = ("id", "position", "velocity", "radius", "mass", "weight", "zone")


def _points_file(path: Union[str, os.PathLike]) -> str:
    """``path`` itself if it is a file, else ``path/points.h5``."""
    path = os.fspath(path)
    return os.path.join(path, POINTS_FILE) if os.path.isdir(path) else path


def _frame_group(f: h5py.File, frame: int) -> h5py.Group:
    """Frame ``frame`` (negative counts from the end) of an open points file."""
    names = sorted(f["frames"]) if "frames" in f else []
    if not names:
        raise ValueError(f"{f.filename} holds no frames")
    return f["frames"][names[frame]]


def read_grains(path: Union[str, os.PathLike], frame: int = -1) -> Dict[str, np.ndarray]:
    """The grains of one frame of a coupled run.

    Args:
        path: the run's output directory or its ``points.h5``.
        frame: frame index (negative counts from the end).

    Returns:
        a dict with ``id``, ``position`` and ``velocity`` (G x 3, also in
        2D), ``radius``, ``mass`` (the mass the grain carries, i.e. weight
        times its full mass), ``weight``, ``zone`` (0 discrete, 1 hybrid,
        2 continuum), and the frame's ``time`` and ``step``.

    Raises:
        KeyError: the frame holds no grains (not a coupled run, or a frame
            written without them).
    """
    with h5py.File(_points_file(path), "r") as f:
        group = _frame_group(f, frame)
        if "grains" not in group:
            raise KeyError(f"{f.filename}: frame {group.name} holds no grains")
        grains = group["grains"]
        out: Dict[str, np.ndarray] = {name: grains[name][()] for name in GRAIN_FIELDS}
        out["time"] = np.float64(group.attrs["time"])
        out["step"] = np.int64(group.attrs["step"])
    return out


def read_grid(path: Union[str, os.PathLike], frame: int = -1) -> Dict[str, np.ndarray]:
    """The grid fields of one frame, with the grid's geometry.

    The same values as ``Run.frame(i)``'s ``grid_mass`` and ``grid_velocity``
    together with ``Run.grid``, for when only the grid is wanted.

    Args:
        path: the run's output directory or its ``points.h5``.
        frame: frame index (negative counts from the end).

    Returns:
        a dict with ``mass`` (dims), ``velocity`` (dims x D), indexed
        ``[i, j(, k)]`` for the node at ``origin + dx * (i, j(, k))``,
        ``origin`` (D), ``dx``, ``dims`` (D), and the frame's ``time`` and ``step``.

    Raises:
        KeyError: the run wrote no grid fields.
    """
    with h5py.File(_points_file(path), "r") as f:
        group = _frame_group(f, frame)
        if "grid" not in group or "grid_dims" not in f.attrs:
            raise KeyError(f"{f.filename}: frame {group.name} holds no grid fields")
        return {
            "mass": group["grid"]["mass"][()],
            "velocity": group["grid"]["velocity"][()],
            "origin": np.asarray(f.attrs["grid_origin"], dtype=float),
            "dx": float(f.attrs["grid_dx"]),
            "dims": np.asarray(f.attrs["grid_dims"], dtype=np.int64),
            "time": np.float64(group.attrs["time"]),
            "step": np.int64(group.attrs["step"]),
        }


def _as_points(positions) -> np.ndarray:
    x = np.asarray(positions, dtype=float)
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise ValueError(f"positions must be N x 2 or N x 3, got shape {x.shape}")
    return x


def surface_profile(
    positions, bins: Union[int, Sequence[float], np.ndarray] = 50, return_edges: bool = False
) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
    """Free-surface height per horizontal bin: the highest point in each bin.

    The height is the last coordinate (y in 2D, z in 3D); bins are taken along
    the first coordinate (x), so a 3D run is profiled across its whole width.

    Args:
        positions: N x D point positions.
        bins: number of equal bins spanning the points' x range, or the bin
            edges (increasing, as for ``numpy.histogram``); points outside the
            edges are ignored, a point on the last edge belongs to the last bin.
        return_edges: also return the bin edges.

    Returns:
        heights, an array with one value per bin (NaN for a bin without
        points), or ``(heights, edges)`` when ``return_edges``.
    """
    x = _as_points(positions)
    horizontal, height = x[:, 0], x[:, -1]
    if np.ndim(bins) == 0:
        n = int(bins)
        if n < 1:
            raise ValueError("bins must be at least 1")
        lo, hi = (float(horizontal.min()), float(horizontal.max())) if len(x) else (0.0, 1.0)
        if hi <= lo:
            hi = lo + 1.0
        edges = np.linspace(lo, hi, n + 1)
    else:
        edges = np.asarray(bins, dtype=float)
        if edges.ndim != 1 or len(edges) < 2 or np.any(np.diff(edges) <= 0):
            raise ValueError("bin edges must be a strictly increasing 1-D sequence of at least 2 values")
    nbins = len(edges) - 1
    heights = np.full(nbins, np.nan)
    inside = (horizontal >= edges[0]) & (horizontal <= edges[-1])
    idx = np.clip(np.searchsorted(edges, horizontal[inside], side="right") - 1, 0, nbins - 1)
    np.fmax.at(heights, idx, height[inside])  # fmax: NaN (empty) loses to any value
    return (heights, edges) if return_edges else heights


def runout(positions, threshold_fraction: float = 0.0) -> float:
    """Horizontal runout: the farthest first-axis (x) coordinate the material reaches.

    A few isolated points ejected ahead of the front would otherwise define
    the runout; ``threshold_fraction`` discards that fraction of the points
    farthest along x, i.e. the result is the ``1 - threshold_fraction``
    quantile of x (0 gives the plain maximum, 0.001 ignores the leading 0.1 %).
    Subtract the initial front position to get a runout distance.

    Args:
        positions: N x D point positions.
        threshold_fraction: fraction in [0, 1) of the points to ignore.

    Returns:
        the front position along x (NaN for an empty point set).
    """
    if not 0.0 <= threshold_fraction < 1.0:
        raise ValueError("threshold_fraction must be in [0, 1)")
    x = _as_points(positions)
    if len(x) == 0:
        return float("nan")
    k = int(np.floor((1.0 - threshold_fraction) * (len(x) - 1)))  # the "lower" quantile: an actual point
    return float(np.partition(x[:, 0], k)[k])
