"""The prediction-aware yielding policy: predictions may release the car as well as hold it back.

`YieldingPolicy` only ever adds caution from a prediction, so no prediction can make it faster. This
variant lets a confident prediction *release* it, within the law, and trusts predicted paths:

- **Release.** A pedestrian by the kerb whom the intention estimate gives at most `release_threshold`
  is not yielded to as "waiting to cross" and is not assumed to walk in, unless the legal duty is visible
  in the observation: the pedestrian is on the zebra (or the road), or is stepping towards the road
  (speed towards it above `stepping_speed` within `kerb_distance` of the kerb). The duty of UK rule 195 /
  StVO §26 is to people who (recognisably) want to cross; a bystander at a bus stop is not one.
- **Caution where it is due.** A pedestrian the estimate expects to cross is treated as waiting (and
  anticipated to walk in) only near the kerb (within `kerb_distance`): an intent to cross somewhere
  later does not stop the car for someone still walking up the sidewalk.
- **Paths instead of constant velocity.** Where ``predicted_paths`` exist, the conflict check uses them
  alone; a pedestrian walking along the kerb is no longer extrapolated into the road when the predictor
  says otherwise.

With no predictor (no ``crossing_intention``, no ``predicted_paths``) it is exactly `YieldingPolicy`:
conservative, as today. Registered as ``predictive_yielding`` next to ``yielding`` rather than replacing
it, so the value-of-prediction table can compare the two on the same seeds and the established policy's
figures stay what they were.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from agents.config import PredictiveYieldingConfig
from agents.view import View
from agents.yielding import YieldingPolicy


class PredictiveYielding(YieldingPolicy):
    """Yielding that predictions can release (see the module docstring)."""

    name: ClassVar[str] = "predictive_yielding"
    uses_predictors: ClassVar[bool] = True
    paths_replace_constant_velocity: ClassVar[bool] = True

    def __init__(self, config: PredictiveYieldingConfig | None = None) -> None:
        super().__init__(config or PredictiveYieldingConfig())
        self.config: PredictiveYieldingConfig

    def _visible_duty(self, view: View, kerb_gap: np.ndarray) -> np.ndarray:
        """(B, K) pedestrians whose wish to cross the car can see: on the road, or stepping towards it."""
        cfg = self.config
        towards = np.where(view.py > 0.5 * (cfg.road_right + cfg.road_left), -view.vy, view.vy)
        stepping = (towards > cfg.stepping_speed) & (kerb_gap <= cfg.kerb_distance)
        return view.on_road | view.on_crossing | stepping

    def _likely_to_cross(self, view: View, kerb_gap: np.ndarray) -> np.ndarray:
        near_kerb = kerb_gap <= self.config.kerb_distance
        return super()._likely_to_cross(view, kerb_gap) & near_kerb

    def _yield_waiting(
        self, view: View, waiting: np.ndarray, likely: np.ndarray | None, kerb_gap: np.ndarray
    ) -> np.ndarray:
        waiting = super()._yield_waiting(view, waiting, likely, kerb_gap)
        if view.intention is None or not self.config.use_predictions:
            return waiting
        released = (view.intention <= self.config.release_threshold) & ~self._visible_duty(view, kerb_gap)
        return waiting & ~released
