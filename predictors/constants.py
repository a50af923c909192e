"""Constants of the trajectory predictors, in a module of its own so that inference needs no torch import."""

from __future__ import annotations

OBS_LEN = 8
"""Observed positions per pedestrian (0.4 s apart: 3.2 s)."""
PRED_LEN = 12
"""Predicted positions per pedestrian (4.8 s)."""
MODEL_KINDS: tuple[str, ...] = ("s-cgru", "s-gru", "s-lstm", "lstm")
"""The recurrent model kinds (`predictors.models.ModelConfig.kind`)."""
