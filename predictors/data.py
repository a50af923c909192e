"""ETH/UCY and SDD trajectory loading, Social-GAN 20-frame windows and batching.

The windowing follows the Social-GAN protocol (Gupta et al., CVPR 2018, and its data loader): a window
starts at every distinct frame (skip 1), spans 20 consecutive distinct frames (8 observed + 12 predicted,
0.4 s apart), keeps a pedestrian only if it is present in all 20 frames, and keeps a window only if it holds
at least 2 such pedestrians. Batches concatenate windows and carry ``seq_start_end`` index ranges.

The same windowing runs on any dense ``(T, P, 2)`` track array with a presence mask, so simulated episodes
from the environment become training windows through :func:`windows_from_tracks`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from predictors.constants import OBS_LEN, PRED_LEN

SEQ_LEN = OBS_LEN + PRED_LEN
SCENES: tuple[str, ...] = ("eth", "hotel", "univ", "zara1", "zara2")
SPLITS: tuple[str, ...] = ("train", "val", "test")


def default_data_root() -> Path:
    """Return the shared data folder: ``$CROSSING_DATA`` if set, else ``<repo>/../shared/data``."""
    env = os.environ.get("CROSSING_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1].parent / "shared" / "data"


def read_trajectory_file(path: str | Path) -> np.ndarray:
    """Read a 4-column ``frame ped x y`` text file (tab or space separated) into an ``(N, 4)`` float64 array.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: a line does not hold exactly four numeric fields (message names file and line).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"trajectory file not found: {path}")
    rows: list[list[float]] = []
    with path.open() as fh:
        for lineno, line in enumerate(fh, start=1):
            fields = line.split()
            if not fields:
                continue
            if len(fields) != 4:
                raise ValueError(f"{path}:{lineno}: expected 4 fields (frame ped x y), got {len(fields)}")
            try:
                rows.append([float(f) for f in fields])
            except ValueError as exc:
                raise ValueError(f"{path}:{lineno}: non-numeric field in {line.strip()!r}") from exc
    if not rows:
        return np.zeros((0, 4))
    data = np.asarray(rows, dtype=np.float64)
    if not np.isfinite(data).all():
        bad = int(np.argwhere(~np.isfinite(data))[0, 0]) + 1
        raise ValueError(f"{path}: non-finite value in data row {bad}")
    return data


@dataclass
class Windows:
    """A set of 20-frame windows, pedestrians concatenated across windows.

    Attributes:
        traj: ``(N, 20, 2)`` float32 absolute positions in metres, observed then future.
        seq_start_end: ``(W, 2)`` int64 ranges ``[start, end)`` into the pedestrian axis, one per window.
    """

    traj: np.ndarray
    seq_start_end: np.ndarray

    @property
    def num_windows(self) -> int:
        """Number of windows."""
        return int(self.seq_start_end.shape[0])

    @property
    def num_peds(self) -> int:
        """Number of pedestrian instances over all windows."""
        return int(self.traj.shape[0])

    @staticmethod
    def concat(parts: Sequence[Windows]) -> Windows:
        """Concatenate window sets, shifting the index ranges."""
        parts = [p for p in parts if p.num_windows > 0]
        if not parts:
            return Windows(np.zeros((0, SEQ_LEN, 2), np.float32), np.zeros((0, 2), np.int64))
        offsets = np.cumsum([0] + [p.num_peds for p in parts[:-1]])
        return Windows(
            np.concatenate([p.traj for p in parts]),
            np.concatenate([p.seq_start_end + o for p, o in zip(parts, offsets, strict=True)]),
        )

    def subset(self, window_idx: np.ndarray) -> Windows:
        """Windows selected by index, in the given order."""
        sse = self.seq_start_end[window_idx]
        sizes = sse[:, 1] - sse[:, 0]
        if len(sse) == 0:
            return Windows(self.traj[:0], sse.copy())
        ped_idx = np.concatenate([np.arange(s, e) for s, e in sse])
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        return Windows(self.traj[ped_idx], np.stack([starts, starts + sizes], axis=1).astype(np.int64))


def windows_from_tracks(
    positions: np.ndarray, present: np.ndarray, seq_len: int = SEQ_LEN, min_peds: int = 2
) -> Windows:
    """Social-GAN windows from a dense track array (vectorised over window starts).

    Args:
        positions: ``(T, P, 2)`` positions per consecutive sample (0.4 s apart) and track slot, metres.
        present: ``(T, P)`` bool, whether the track is observed at that sample.
        seq_len: window length in samples.
        min_peds: minimum number of complete tracks for a window to be kept.
    """
    t_len = positions.shape[0]
    if t_len < seq_len:
        return Windows(np.zeros((0, seq_len, 2), np.float32), np.zeros((0, 2), np.int64))
    csum = np.concatenate([np.zeros((1, present.shape[1]), np.int64), np.cumsum(present, axis=0)])
    count = csum[seq_len:] - csum[:-seq_len]  # (T - seq_len + 1, P)
    full = count == seq_len
    n_per = full.sum(axis=1)
    starts_keep = np.flatnonzero(n_per >= min_peds)
    if len(starts_keep) == 0:
        return Windows(np.zeros((0, seq_len, 2), np.float32), np.zeros((0, 2), np.int64))
    win_idx, ped_idx = np.nonzero(full[starts_keep])  # row-major: grouped by window, peds ascending
    t_idx = starts_keep[win_idx][:, None] + np.arange(seq_len)[None, :]
    traj = positions[t_idx, ped_idx[:, None]].astype(np.float32)
    sizes = n_per[starts_keep]
    ends = np.cumsum(sizes)
    sse = np.stack([ends - sizes, ends], axis=1).astype(np.int64)
    return Windows(traj, sse)


def windows_from_rows(data: np.ndarray, seq_len: int = SEQ_LEN, min_peds: int = 2) -> Windows:
    """Social-GAN windows from ``(N, 4)`` rows ``frame ped x y``.

    Consecutive *distinct* frame ids form the time axis, exactly as Social-GAN does; tracks have no gaps,
    so a pedestrian present in 20 consecutive distinct frames is sampled every 0.4 s.
    """
    if len(data) == 0:
        return Windows(np.zeros((0, seq_len, 2), np.float32), np.zeros((0, 2), np.int64))
    frames, f_idx = np.unique(data[:, 0], return_inverse=True)
    peds, p_idx = np.unique(data[:, 1], return_inverse=True)
    positions = np.zeros((len(frames), len(peds), 2))
    present = np.zeros((len(frames), len(peds)), bool)
    positions[f_idx, p_idx] = data[:, 2:4]
    present[f_idx, p_idx] = True
    return windows_from_tracks(positions, present, seq_len, min_peds)


def load_files(paths: Sequence[Path]) -> Windows:
    """Windows of several files, each windowed on its own (windows never span two files)."""
    return Windows.concat([windows_from_rows(read_trajectory_file(p)) for p in sorted(paths)])


def split_files(data_root: Path, scene: str, split: str) -> list[Path]:
    """Files of an ETH/UCY leave-one-out split, or of SDD when ``scene == "sdd"``."""
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")
    if scene == "sdd":
        folder = Path(data_root) / "sdd" / split
    elif scene in SCENES:
        folder = Path(data_root) / "eth_ucy" / scene / split
    else:
        raise ValueError(f"scene must be one of {(*SCENES, 'sdd')}, got {scene!r}")
    files = sorted(folder.glob("*.txt"))
    if not files:
        raise FileNotFoundError(f"no .txt files in {folder} (set CROSSING_DATA or --data)")
    return files


def load_split(data_root: str | Path, scene: str, split: str) -> Windows:
    """Windows of one split (``train``/``val``/``test``) of an ETH/UCY leave-one-out scene or SDD."""
    return load_files(split_files(Path(data_root), scene, split))


def relative(traj: torch.Tensor) -> torch.Tensor:
    """Backward displacements along time (axis 1), first step zero: no future leak (prediction.md §4.2)."""
    rel = torch.zeros_like(traj)
    rel[:, 1:] = traj[:, 1:] - traj[:, :-1]
    return rel


@dataclass
class Batch:
    """A torch batch of windows.

    Attributes:
        obs: ``(N, 8, 2)`` observed absolute positions, metres.
        fut: ``(N, 12, 2)`` future absolute positions, metres.
        seq_start_end: ``(W, 2)`` int64 index ranges.
    """

    obs: torch.Tensor
    fut: torch.Tensor
    seq_start_end: torch.Tensor


def to_batch(w: Windows, device: torch.device | str = "cpu") -> Batch:
    """Convert windows to a torch :class:`Batch`."""
    traj = torch.as_tensor(w.traj, device=device)
    return Batch(traj[:, :OBS_LEN], traj[:, OBS_LEN:], torch.as_tensor(w.seq_start_end, device=device))


def iterate_batches(
    w: Windows,
    max_peds: int,
    rng: np.random.Generator | None = None,
    rotate: bool = False,
    device: torch.device | str = "cpu",
) -> Iterator[Batch]:
    """Yield batches of whole windows with at most ``max_peds`` pedestrians each (one window may exceed it).

    Args:
        w: windows.
        max_peds: pedestrian budget per batch.
        rng: if given, windows are shuffled and (with ``rotate``) each batch is rotated by a random angle
            about the origin, an augmentation that the protocol allows (prediction.md §1).
        rotate: random-rotation augmentation (needs ``rng``).
        device: torch device.
    """
    order = rng.permutation(w.num_windows) if rng is not None else np.arange(w.num_windows)
    sizes = (w.seq_start_end[:, 1] - w.seq_start_end[:, 0])[order]
    start = 0
    while start < len(order):
        csum = np.cumsum(sizes[start:])
        stop = start + max(1, int(np.searchsorted(csum, max_peds, side="right")))
        sub = w.subset(order[start:stop])
        if rotate and rng is not None:
            a = rng.uniform(0.0, 2.0 * math.pi)
            rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]], np.float32)
            sub = Windows(sub.traj @ rot, sub.seq_start_end)
        yield to_batch(sub, device)
        start = stop
