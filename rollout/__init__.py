"""Running episodes: the one assembly of env, wrappers and policy, and the one episode loop.

This layer sits above `agents` and `predictors` and below the applications (`crossing_eval`,
`crossing_replay`, `examples`, `benchmarks`), which all run episodes through it:

    from rollout import RolloutSpec, build, run_episode

    run = build(RolloutSpec(scenario="busy_zebra", policy="predictive_yielding"))
    episode = run_episode(run.env, seed=0, policy=run.policy)
    print(episode.result["collision"], run.wrappers)
"""

from __future__ import annotations

from rollout.build import Rollout, RolloutSpec, build, build_policy, make_env, run_spec, wrappers_for
from rollout.episode import (
    ActionError,
    Episode,
    Frame,
    checked_action,
    dynamics_digest,
    frames,
    run_episode,
    run_episodes,
    slot_ids,
)
from rollout.wrappers import (
    DEFAULT_INTENTION,
    DEFAULT_PREDICTOR,
    INTENTION_WRAPPERS,
    NONE,
    TRAJECTORY_WRAPPERS,
    WrapperError,
    intention_names,
    predictor_names,
    wrap,
)

__all__ = [
    "DEFAULT_INTENTION",
    "DEFAULT_PREDICTOR",
    "INTENTION_WRAPPERS",
    "NONE",
    "TRAJECTORY_WRAPPERS",
    "ActionError",
    "Episode",
    "Frame",
    "Rollout",
    "RolloutSpec",
    "WrapperError",
    "build",
    "build_policy",
    "checked_action",
    "dynamics_digest",
    "frames",
    "intention_names",
    "make_env",
    "predictor_names",
    "run_episode",
    "run_episodes",
    "run_spec",
    "slot_ids",
    "wrap",
    "wrappers_for",
]
