"""Social-pooling layout: where each pedestrian looks, and which neighbour falls in which of its grid cells.

Why compiled: the layout is index bookkeeping over a few hundred pairs per recurrent step (heading update,
offset, optional rotation into the heading, grid cell, sector test, rank within the cell). As torch ops it
took about forty tiny dispatches per step, the largest cost that every pooling model shares at the batch
sizes used here. Cells are piecewise constant in the positions, so the layout carries no gradient and
computing it outside autograd is exact for training too. The neighbours' states are then pooled in torch
(:meth:`predictors.models.SocialRecurrent.pooled_embedding`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from numba import njit

Layout = tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, int, torch.Tensor]
"""``(i, j, cell, slot, most, used)``: see :func:`_grid_layout`."""


@dataclass(frozen=True)
class PoolingGeometry:
    """The grid and sector a model pools over (from its :class:`~predictors.models.ModelConfig`)."""

    neighborhood: float
    """Side of the square pooling area around each pedestrian, metres."""
    grid: int
    """Cells per side of the grid."""
    fov_deg: float
    """Field-of-view sector, degrees (360: none)."""
    heading_frame: bool
    """Rotate offsets into the pedestrian's heading (else an axis-aligned world-frame grid)."""
    min_speed: float
    """Displacement per step below which a pedestrian keeps its previous heading."""


@njit(cache=True, nogil=True)
def _advance_headings(rel: np.ndarray, heading: np.ndarray, known: np.ndarray, min_speed: float) -> None:
    """In place: a pedestrian that moved more than ``min_speed`` now looks along its displacement."""
    for i in range(rel.shape[0]):
        speed = np.sqrt(rel[i, 0] * rel[i, 0] + rel[i, 1] * rel[i, 1])
        if speed > min_speed:
            heading[i, 0] = rel[i, 0] / speed
            heading[i, 1] = rel[i, 1] / speed
            known[i] = True


@njit(cache=True, nogil=True)
def _grid_layout(
    pos: np.ndarray,
    heading: np.ndarray,
    known: np.ndarray,
    pairs: np.ndarray,
    geometry: np.ndarray,
    grid: int,
    heading_frame: bool,
    sector: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, np.ndarray]:
    """Kept pairs ``(i, j)``, ``j``'s cell in ``i``'s grid, its buffer slot, ``most`` and the used cells.

    ``geometry``: ``[half side, cell side, half field of view]`` in ``pos``'s dtype. In the heading frame
    the offset ``p_j - p_i`` is rotated by ``conj(u_i)`` (real part ``d . u``, imaginary part ``u x d``); a
    pedestrian whose heading is not ``known`` pools over the whole grid. ``used`` lists the cells that
    hold a pair, ascending; ``most`` is the largest number of pairs in one cell; a pair's ``slot`` is
    ``k * most + rank``, with ``k`` its cell's place in ``used`` and ``rank`` the number of earlier kept
    pairs in that cell, so slots index a ``(len(used), most)`` buffer without empty cells.
    """
    count = pairs.shape[1]
    keep_i = np.empty(count, np.int64)
    keep_j = np.empty(count, np.int64)
    cell = np.empty(count, np.int64)
    rank = np.empty(count, np.int64)
    per_cell = np.zeros(grid * grid, np.int64)
    half, side, half_fov = geometry[0], geometry[1], geometry[2]
    top = grid - 1
    kept = 0
    for q in range(count):
        i, j = pairs[0, q], pairs[1, q]
        x = pos[j, 0] - pos[i, 0]
        y = pos[j, 1] - pos[i, 1]
        if heading_frame:
            ux, uy = heading[i, 0], heading[i, 1]
            x, y = x * ux + y * uy, y * ux - x * uy
        cx = np.floor((x + half) / side)
        cy = np.floor((y + half) / side)
        if not (0 <= cx <= top and 0 <= cy <= top):  # also drops NaN offsets
            continue
        if sector and known[i] and not abs(np.arctan2(y, x)) <= half_fov:
            continue
        c = int(cy) * grid + int(cx)
        keep_i[kept], keep_j[kept], cell[kept], rank[kept] = i, j, c, per_cell[c]
        per_cell[c] += 1
        kept += 1
    most = per_cell.max()
    used = np.flatnonzero(per_cell)
    place = np.zeros(grid * grid, np.int64)
    place[used] = np.arange(used.size)
    slot = np.empty(kept, np.int64)
    for q in range(kept):
        slot[q] = place[cell[q]] * most + rank[q]
    return keep_i[:kept], keep_j[:kept], cell[:kept], slot, most, used


def _numpy(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().numpy()


def _packed(g: PoolingGeometry, dtype: np.dtype) -> np.ndarray:
    """``[half side, cell side, half field of view]`` as :func:`_grid_layout` takes it."""
    return np.array([0.5 * g.neighborhood, g.neighborhood / g.grid, math.radians(g.fov_deg) / 2.0], dtype)


def _layout(
    g: PoolingGeometry,
    packed: np.ndarray,
    pos: np.ndarray,
    heading: np.ndarray,
    known: np.ndarray,
    pairs: np.ndarray,
    device: torch.device,
) -> Layout:
    i, j, cell, slot, most, used = _grid_layout(
        pos, heading, known, pairs, packed, g.grid, g.heading_frame, g.fov_deg < 360.0
    )
    i, j, cell, slot, used = (torch.from_numpy(a).to(device) for a in (i, j, cell, slot, used))
    return i, j, cell, slot, int(most), used


def _check_pairs(pairs: torch.Tensor, count: int) -> None:
    """The kernel does no bounds checks: refuse pairs that index outside the ``count`` pedestrians."""
    if pairs.ndim != 2 or pairs.shape[0] != 2:
        raise ValueError(f"pairs must have shape (2, P), got {tuple(pairs.shape)}")
    if pairs.numel() and not (0 <= int(pairs.min()) and int(pairs.max()) < count):
        raise ValueError(f"pairs index pedestrians outside 0..{count - 1}")


def grid_layout(
    geometry: PoolingGeometry,
    pos: torch.Tensor,
    heading: torch.Tensor,
    known: torch.Tensor,
    pairs: torch.Tensor,
) -> Layout:
    """:func:`_grid_layout` for given headings: ``(i, j, cell, slot, most, used)`` on ``pos``'s device.

    Args:
        geometry: the model's grid and sector.
        pos: ``(N, 2)`` positions.
        heading: ``(N, 2)`` unit vectors, where each pedestrian looks.
        known: ``(N,)`` whether a pedestrian's heading is known (else it pools over the whole grid).
        pairs: ``(2, P)`` candidate ordered pairs ``(i, j)`` (same window, ``i != j``).
    """
    _check_pairs(pairs, pos.shape[0])
    p = _numpy(pos)
    arrays = (_numpy(t) for t in (heading, known, pairs))
    return _layout(geometry, _packed(geometry, p.dtype), p, *arrays, pos.device)


class HeadingTracker:
    """Each pedestrian's heading over one rollout, and the pooling layout of every step.

    A plain class holding NumPy state: ``(1, 0)`` and "unknown" until a pedestrian first moves faster
    than ``min_speed`` per step, then the direction of its latest such displacement (prediction.md §3,
    field-of-view pitfall: a standing pedestrian keeps looking where it looked).
    """

    def __init__(
        self, geometry: PoolingGeometry, pairs: torch.Tensor, count: int, dtype: torch.dtype
    ) -> None:
        _check_pairs(pairs, count)
        self.geometry = geometry
        self.pairs = _numpy(pairs)
        npdtype = torch.empty(0, dtype=dtype).numpy().dtype
        self.heading = np.zeros((count, 2), npdtype)
        self.heading[:, 0] = 1.0
        self.known = np.zeros(count, np.bool_)
        self._min_speed = npdtype.type(geometry.min_speed)
        self._packed = _packed(geometry, npdtype)  # per rollout, not per step

    def advance(self, rel: torch.Tensor) -> None:
        """Update the headings with one step's displacements ``rel (N, 2)``."""
        _advance_headings(_numpy(rel), self.heading, self.known, self._min_speed)

    def layout(self, pos: torch.Tensor) -> Layout:
        """The pooling layout at positions ``pos (N, 2)`` with the current headings."""
        return _layout(
            self.geometry, self._packed, _numpy(pos), self.heading, self.known, self.pairs, pos.device
        )
