"""A sampling planner in the PDM-Closed family that scores speed proposals against any forecast.

`proposals` (the speed profiles), `forecasts` (weighted hypotheses of each pedestrian's future, with the
conservative prior when no predictor is on), `scorer` (roll-out and expected episode score, the chance
constraint) and `policy` (the registered `SamplingPlanner`). Method and limits: docs/planner.md.
"""

from agents.planner.policy import SamplingPlanner

__all__ = ["SamplingPlanner"]
