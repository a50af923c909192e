"""Per-pedestrian episode state of `EpisodeMetrics`, one row per pedestrian id, looked up vectorised."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

__all__ = ["NO_STATE", "PedestrianTable"]

_INF = math.inf


NO_STATE = -1


class PedestrianTable:
    """Rows of per-pedestrian episode state, keyed by id; lookups are vectorised (sorted ids)."""

    _FLOAT_COLS: ClassVar[tuple[str, ...]] = (
        "last_entry",
        "last_exit",
        "wait_start",
    )
    _FILL: ClassVar[dict[str, float]] = {
        "last_entry": -_INF,
        "last_exit": -_INF,
        "wait_start": math.nan,
    }

    def __init__(self) -> None:
        self.ids = np.empty(0, dtype=np.int64)
        self.in_ca = np.empty(0, dtype=bool)
        self.prev_state = np.empty(0, dtype=np.int64)
        for name in self._FLOAT_COLS:
            setattr(self, name, np.empty(0, dtype=np.float64))

    def rows(self, ids: np.ndarray) -> np.ndarray:
        """Row index of every id, adding rows for ids seen for the first time."""
        n = self.ids.shape[0]
        pos = np.searchsorted(self.ids, ids)
        if n == 0 or np.count_nonzero(self.ids[np.minimum(pos, n - 1)] != ids):
            self._add(ids)
            pos = np.searchsorted(self.ids, ids)
        return pos

    def _add(self, ids: np.ndarray) -> None:
        new = np.setdiff1d(np.unique(ids), self.ids)
        all_ids = np.concatenate([self.ids, new])
        order = np.argsort(all_ids, kind="stable")
        k = new.shape[0]
        self.ids = all_ids[order]
        self.in_ca = np.concatenate([self.in_ca, np.zeros(k, dtype=bool)])[order]
        self.prev_state = np.concatenate([self.prev_state, np.full(k, NO_STATE, dtype=np.int64)])[order]
        for name in self._FLOAT_COLS:
            col = np.concatenate([getattr(self, name), np.full(k, self._FILL[name])])[order]
            setattr(self, name, col)
