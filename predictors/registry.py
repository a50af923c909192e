"""Names of the predictor wrappers, so scripts and benchmarks can build them without knowing modules.

Each entry maps a name to a callable `wrap(env) -> env`. Wrappers batch over the K pedestrian slots of one
env; with `gym.make_vec` each sub-env gets its own wrapper instance (pass `wrappers=[...]`), so they do not
batch across envs.
"""

from __future__ import annotations

from collections.abc import Callable

import gymnasium as gym

Wrap = Callable[[gym.Env], gym.Env]


def available_wrappers() -> dict[str, Wrap]:
    """Wrapper name → constructor."""
    from predictors.intention import ClassicalIntention, QLBIntention
    from predictors.trajectory_wrapper import TrajectoryPrediction

    return {
        "qlb-intention": QLBIntention,
        "classical-intention": ClassicalIntention,
        "s-cgru-paths": TrajectoryPrediction,
        "cvm-paths": lambda env: TrajectoryPrediction(env, model="cvm"),
    }
