"""The sampling planner as a driving policy: legal duties from the rules, speed from the scored proposals.

Each step (`SamplingPlanner._acceleration`): the legal-yield rules of `PredictiveYielding` give the stop
that binds every proposal (a zebra duty, a red light; released only as those rules release it); the
forecast becomes weighted hypotheses per pedestrian (`agents.planner.forecasts`); every proposal is rolled
out against them and scored by the expected episode score (`agents.planner.scorer`); the best one meeting
the chance constraint is followed, with hysteresis. Its acceleration is then capped by what the rules ask
regardless of pedestrians: following the vehicle ahead (IDM), passing an occluder slowly, not overtaking
before a zebra, and the legal stop itself. The rules' own conflict check is not used: the proposals' roll-
out against the forecast replaces it.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from agents.config import PlannerConfig
from agents.planner.forecasts import build_hypotheses
from agents.planner.proposals import make_proposals
from agents.planner.scorer import choose, score_proposals
from agents.predictive import PredictiveYielding
from agents.view import ObsLike, View, follow, stop_acceleration


class SamplingPlanner(PredictiveYielding):
    """Samples speed proposals, rolls them against the forecast, follows the best expected episode score."""

    name: ClassVar[str] = "sampling_planner"
    uses_predictors: ClassVar[bool] = True
    batched: ClassVar[bool] = True

    def __init__(self, config: PlannerConfig | None = None) -> None:
        super().__init__(config or PlannerConfig())
        self.config: PlannerConfig
        self.proposals = make_proposals(self.config)
        """The speed proposals scored every step."""
        self._obs: ObsLike = {}

    def reset(self, seed: int | None = None) -> None:
        """Forget the yielding state and the proposal being followed."""
        super().reset(seed)
        self._proposal = np.zeros(0, dtype=np.int64)
        self._proposal_to_stop = np.zeros(0)
        self.proposal_history: list[np.ndarray] = []
        """Chosen proposal index (B,) per call since `reset` (for tests and diagnostics)."""

    def _read_bound(self, obs: ObsLike) -> None:
        super()._read_bound(obs)
        self._obs = obs  # the forecast keys the hypotheses read

    def _acceleration(self, view: View) -> np.ndarray:
        cfg = self.config
        b = view.speed.shape[0]
        legal, _conflict = self._targets(view)  # the legal duty (and the rules' timers and memory)
        if self._proposal.shape != (b,):
            self._proposal = np.full(b, -1, dtype=np.int64)
            self._proposal_to_stop = np.full(b, np.inf)
        # A vector env restarted this element's episode. Its own record: the rules' `_last_to_stop` has
        # already been updated by `_targets` this step.
        fresh = view.to_stop > self._proposal_to_stop + 0.5
        self._proposal_to_stop = view.to_stop.copy()
        self._proposal[fresh] = -1
        hyp = build_hypotheses(view, self._obs, cfg, self._kerb_gap(view), self._towards_road(view))
        scores = score_proposals(view.speed, legal, view.present, self.proposals, hyp, cfg)
        chosen = choose(scores, self._proposal, cfg)
        self._proposal = chosen
        self.proposal_history.append(chosen.copy())
        a = scores.first[np.arange(b), chosen]
        a_legal = stop_acceleration(
            view, legal, cfg.comfortable_deceleration, cfg.stop_gain, cfg.ego.max_deceleration
        )
        caps = np.minimum(follow(view, cfg), np.minimum(self._occlusion_cap(view), self._no_overtaking(view)))
        return np.minimum(np.minimum(a, a_legal), caps)
