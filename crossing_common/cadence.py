"""The pedestrian history cadence, shared by the scenario checks, the simulator, predictors and policies."""

from __future__ import annotations

from typing import Final

HISTORY_INTERVAL: Final[float] = 0.4
"""Seconds between two pedestrian history samples, and between two points of a predicted path: the 2.5 Hz
ETH/UCY cadence the trajectory predictors are trained on. The env's ``dt`` must divide it."""
