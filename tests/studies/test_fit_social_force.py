from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from predictors.data import Windows
from predictors.social_force_predictor import FIT_FIELDS, SocialForcePredictor
from studies.fit_social_force import FIT_GRID, every_nth, fit
from tests.predictors.test_social_force_predictor import _pair


def test_fit_moves_towards_the_generating_parameters() -> None:
    """Data simulated with weak repulsion: the fit from the default lowers the strength and the error."""
    truth = SocialForcePredictor()
    truth = replace(truth, force=replace(truth.force, base_strength=2.0))
    rng = np.random.default_rng(0)
    trajs = []
    for _ in range(6):
        obs = _pair(float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.4, 0.6)))
        fut = truth.predict(obs, torch.tensor([[0, 2]]))
        trajs.append(torch.cat([obs, fut], dim=1).numpy())
    w = Windows(np.concatenate(trajs), np.array([[2 * i, 2 * i + 2] for i in range(6)], np.int64))
    fitted, ade = fit(SocialForcePredictor(), every_nth(w, 6), sweeps=1)
    assert fitted.force.base_strength < SocialForcePredictor().force.base_strength
    assert ade < 0.05


def test_the_grid_covers_exactly_the_fitted_fields() -> None:
    assert tuple(FIT_GRID) == FIT_FIELDS
    default = SocialForcePredictor().force
    for name, grid in FIT_GRID.items():
        assert getattr(default, name) in grid, name  # the search can always stay at the default
