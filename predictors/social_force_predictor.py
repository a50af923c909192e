"""The simulator's social-force pedestrians run as a trajectory predictor on real windows (seed Case 2).

Song et al. (2022, Case 2) predict with a social-force model whose pedestrian intensity (0.42) is updated by
the QLB curve when others behave irrationally, and claim AVG ETH/UCY 0.32/0.63. This module runs *our*
simulator's model (:func:`crossing_env.pedestrians.social_force.walk_step`, the same compiled kernel the
environment steps) on each 8-step observation: the observed pedestrians of a window are simulated together,
each walking towards a goal straight ahead of its last observed heading at a desired speed equal to its mean
observed speed of the last ``speed_steps`` steps; pedestrians slower than ``STAND_SPEED`` stand still. The
window's other pedestrians are its only neighbours (no vehicles, no kerbs in the recordings). The same
run is therefore a realism score of the simulator's pedestrian motion against real data.

QLB variant: each pedestrian's intensity is
:func:`crossing_env.pedestrians.force_update.updated_ped_intensity` of the fraction of its neighbours
within 10 m who look irrational in the observation. The recordings carry no "irrational" labels, so we
use a proxy: running (last speed above ``RUN_SPEED``) or an abrupt turn (more than ``TURN_DEG`` between
the last two displacements while walking). This proxy is our choice.

Samples: each sample rotates a pedestrian's initial velocity and goal by one ``N(0, heading_std)`` angle
(CVM-S's perturbation, pushed through the interacting model); ``heading_std`` is tuned on val.

Fitted parameters per scene (:func:`load_fit`, file :data:`FIT_FILE`) are written by the fitting script,
``python -m studies.fit_social_force``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from crossing_common.cadence import HISTORY_INTERVAL
from crossing_env.pedestrians.force_update import irrational_neighbour_fraction, updated_ped_intensity
from crossing_env.pedestrians.social_force import model_parameters, walk_step
from predictors.data import PRED_LEN
from scenarios.config import SocialForceConfig

STEP_S = HISTORY_INTERVAL
"""Seconds between dataset frames (the ETH/UCY cadence)."""
STAND_SPEED = 0.15
"""m/s: below this mean observed speed a pedestrian is simulated standing (desired speed 0)."""
RUN_SPEED = 2.0
"""m/s: observed speed above which a neighbour counts as irrational (running) for the QLB update."""
TURN_DEG = 45.0
"""Heading change between the last two displacements above which a walking neighbour counts as irrational."""
WINDOW_GAP = 1000.0
"""Metres between windows laid side by side in one kernel call, far beyond the force's reach."""


@dataclass(frozen=True)
class SocialForcePredictor:
    """Social-force predictor settings (the force parameters are the simulator's own config)."""

    force: SocialForceConfig = field(default_factory=SocialForceConfig)
    """Force parameters; the default is the simulator's default pedestrian model."""
    qlb: bool = False
    """Update each pedestrian's intensity by the QLB curve from its irrational-looking neighbours."""
    radius: float = 0.28
    """Body radius, metres (the simulator's population default)."""
    substeps: int = 4
    """Euler steps per 0.4 s frame (dt = 0.1 s, the simulator's step)."""
    speed_steps: int = 1
    """Observed displacements averaged for the desired speed (1: the last one, as CVM; 4 was worse on val)."""
    heading_std_deg: float = 15.0
    """Per-sample heading perturbation of velocity and goal, degrees."""

    def _setup(self, obs: np.ndarray, sse: np.ndarray) -> tuple[np.ndarray, ...]:
        n = obs.shape[0]
        group = np.repeat(np.arange(len(sse)), sse[:, 1] - sse[:, 0])
        offset = np.zeros((n, 2))
        offset[:, 0] = WINDOW_GAP * group
        pos = obs[:, -1].astype(np.float64) + offset
        disp = np.diff(obs[:, -self.speed_steps - 1 :].astype(np.float64), axis=1)
        speed = np.linalg.norm(disp, axis=-1).mean(axis=1) / STEP_S
        last = disp[:, -1]
        vel = last / STEP_S
        norm = np.linalg.norm(last, axis=-1)
        heading = np.where(norm[:, None] > 1e-6, last / np.maximum(norm, 1e-9)[:, None], 0.0)
        desired = np.where(speed >= STAND_SPEED, speed, 0.0)
        if self.qlb:
            frac = self._irrational_fraction(pos, np.diff(obs[:, -3:].astype(np.float64), axis=1))
            k_p = updated_ped_intensity(self.force.ped_intensity, frac)
        else:
            k_p = np.full(n, self.force.ped_intensity)
        return pos, vel, heading, desired, np.ascontiguousarray(k_p, dtype=np.float64), offset

    @staticmethod
    def _irrational_fraction(pos: np.ndarray, disp: np.ndarray) -> np.ndarray:
        """Per pedestrian, the fraction of window neighbours within 10 m that look irrational (proxy)."""
        speed_last = np.linalg.norm(disp[:, -1], axis=-1) / STEP_S
        a, b = disp[:, -2], disp[:, -1]
        na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
        cos = (a * b).sum(-1) / np.maximum(na * nb, 1e-12)
        walking = (na > 0.1 * STEP_S) & (nb > 0.1 * STEP_S)
        turn = walking & (cos < math.cos(math.radians(TURN_DEG)))
        irrational = (speed_last > RUN_SPEED) | turn
        return irrational_neighbour_fraction(pos, np.ones(len(pos), bool), irrational)

    def _simulate(
        self, pos: np.ndarray, vel: np.ndarray, heading: np.ndarray, desired: np.ndarray, k_p: np.ndarray
    ) -> np.ndarray:
        """``(N, 12, 2)`` positions after each frame, from the given state."""
        n = pos.shape[0]
        pos, vel = pos.copy(), vel.copy()
        reach = np.maximum(desired * PRED_LEN * STEP_S * 2.0, 10.0)
        goals = pos + heading * reach[:, None]
        rows = np.arange(n)
        radii = np.full(n, self.radius)
        stay = np.zeros(n, bool)
        boxes = np.zeros((0, 4))
        params = model_parameters(self.force)
        dt = STEP_S / self.substeps
        out = np.empty((n, PRED_LEN, 2))
        for t in range(PRED_LEN):
            for _ in range(self.substeps):
                walk_step(
                    rows, pos, vel, goals, desired, radii, stay, boxes, 0.0, 0.0, k_p, dt,
                    self.force.max_speed_factor, params,
                )  # fmt: skip
                pos += vel * dt
            out[:, t] = pos
        return out

    def predict(self, obs: torch.Tensor, seq_start_end: torch.Tensor) -> torch.Tensor:
        """Most-likely future ``(N, 12, 2)`` (the deterministic simulation)."""
        o, s = obs.double().numpy(), seq_start_end.numpy()
        pos, vel, heading, desired, k_p, offset = self._setup(o, s)
        fut = self._simulate(pos, vel, heading, desired, k_p) - offset[:, None]
        return torch.as_tensor(fut, dtype=obs.dtype)

    def sample(
        self, obs: torch.Tensor, seq_start_end: torch.Tensor, num_samples: int, generator: torch.Generator
    ) -> torch.Tensor:
        """``(S, N, 12, 2)``: every sample simulates the whole window with perturbed headings."""
        o, s = obs.double().numpy(), seq_start_end.numpy()
        pos, vel, heading, desired, k_p, offset = self._setup(o, s)
        n = pos.shape[0]
        ang = torch.randn((num_samples, n), generator=generator, dtype=torch.float64).numpy()
        ang = ang * math.radians(self.heading_std_deg)
        c, si = np.cos(ang)[..., None], np.sin(ang)[..., None]

        def rot(v: np.ndarray) -> np.ndarray:
            x, y = v[None, :, :1], v[None, :, 1:]
            return np.concatenate([c * x - si * y, si * x + c * y], -1)

        # All samples in one kernel call, sample k's windows laid out after sample k - 1's along x (the
        # kernel scans neighbours in x order, so copies stacked in y would all be scanned).
        shift = np.zeros((num_samples, 1, 2))
        shift[:, 0, 0] = WINDOW_GAP * (len(s) + 1) * np.arange(num_samples)
        fut = self._simulate(
            (pos[None] + shift).reshape(-1, 2),
            rot(vel).reshape(-1, 2),
            rot(heading).reshape(-1, 2),
            np.tile(desired, num_samples),
            np.tile(k_p, num_samples),
        ).reshape(num_samples, n, PRED_LEN, 2)
        return torch.as_tensor(fut - shift[:, :, None] - offset[None, :, None], dtype=obs.dtype)


FIT_FIELDS: tuple[str, ...] = ("relaxation_time", "base_strength", "ped_range", "anisotropy")
"""The force parameters fitted per scene (the rest keep the simulator's defaults)."""
FIT_FILE = Path(__file__).resolve().parent / "social_force_fit.json"
"""Per-scene ``default`` and ``fit`` parameters, written by ``python -m studies.fit_social_force``."""


def load_fit(path: str | Path, scene: str, which: str) -> SocialForcePredictor:
    """The ``default`` or ``fit`` predictor of ``scene`` from a file like :data:`FIT_FILE`."""
    entry = json.loads(Path(path).read_text())["scenes"][scene][which]
    force = replace(SocialForceConfig(), **{f: float(entry[f]) for f in FIT_FIELDS})
    return SocialForcePredictor(force=force, heading_std_deg=float(entry["heading_std_deg"]))
