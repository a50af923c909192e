"""Non-learned baselines: constant velocity (CVM), CVM with sampled headings (CVM-S), linear Kalman filter.

All take observed absolute positions ``(N, 8, 2)`` (metres, 0.4 s apart) and return futures ``(N, 12, 2)``
(most likely) or samples ``(S, N, 12, 2)``. They are deterministic given a ``torch.Generator``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from predictors.data import PRED_LEN


def cvm(obs: torch.Tensor, pred_len: int = PRED_LEN) -> torch.Tensor:
    """Constant velocity from the last observed displacement (backward difference, no future leak)."""
    vel = obs[:, -1] - obs[:, -2]
    steps = torch.arange(1, pred_len + 1, dtype=obs.dtype, device=obs.device)
    return obs[:, -1, None] + steps[None, :, None] * vel[:, None]


def cvm_samples(
    obs: torch.Tensor,
    num_samples: int,
    generator: torch.Generator,
    sigma_deg: float = 25.0,
    pred_len: int = PRED_LEN,
) -> torch.Tensor:
    """CVM-S (Schöller et al. 2020): one heading perturbation ``N(0, sigma)`` per sample and pedestrian.

    The first sample is not special: every sample is perturbed, as in the authors' script.
    """
    vel = obs[:, -1] - obs[:, -2]
    ang = torch.randn((num_samples, obs.shape[0]), generator=generator, dtype=obs.dtype)
    ang = ang.to(obs.device) * math.radians(sigma_deg)
    c, s = torch.cos(ang), torch.sin(ang)
    v = torch.stack([c * vel[:, 0] - s * vel[:, 1], s * vel[:, 0] + c * vel[:, 1]], dim=-1)  # (S, N, 2)
    steps = torch.arange(1, pred_len + 1, dtype=obs.dtype, device=obs.device)
    return obs[None, :, -1, None] + steps[None, None, :, None] * v[:, :, None]


@dataclass(frozen=True)
class KalmanConfig:
    """Constant-velocity Kalman filter noise levels (time unit: one 0.4 s step)."""

    accel_std: float = 0.05
    """White-noise acceleration standard deviation, metres per step²."""
    meas_std: float = 0.05
    """Position measurement noise standard deviation, metres."""
    init_vel_std: float = 1.0
    """Prior standard deviation of the initial velocity, metres per step."""


def _kalman_matrices(
    cfg: KalmanConfig, dtype: torch.dtype
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    f = torch.eye(4, dtype=dtype)
    f[0, 2] = f[1, 3] = 1.0
    q1 = torch.tensor([[0.25, 0.5], [0.5, 1.0]], dtype=dtype) * cfg.accel_std**2
    q = torch.zeros(4, 4, dtype=dtype)
    q[0::2, 0::2] = q1
    q[1::2, 1::2] = q1
    h = torch.zeros(2, 4, dtype=dtype)
    h[0, 0] = h[1, 1] = 1.0
    return f, q, h


def kalman_filter(obs: torch.Tensor, cfg: KalmanConfig = KalmanConfig()) -> tuple[torch.Tensor, torch.Tensor]:
    """Filter the observed positions; return the final state mean ``(N, 4)`` and covariance ``(N, 4, 4)``."""
    dt = torch.float64
    f, q, h = _kalman_matrices(cfg, dt)
    z = obs.to(dt)
    n = z.shape[0]
    x = torch.zeros(n, 4, dtype=dt)
    x[:, :2] = z[:, 0]
    p = torch.diag(torch.tensor([cfg.meas_std**2] * 2 + [cfg.init_vel_std**2] * 2, dtype=dt)).expand(n, 4, 4)
    r = torch.eye(2, dtype=dt) * cfg.meas_std**2
    for t in range(1, z.shape[1]):
        x = x @ f.T
        p = f @ p @ f.T + q
        s = h @ p @ h.T + r
        k = p @ h.T @ torch.linalg.inv(s)
        innov = z[:, t] - x[:, :2]
        x = x + (k @ innov[:, :, None])[:, :, 0]
        p = (torch.eye(4, dtype=dt) - k @ h) @ p
    return x, p


def kalman_predict(
    obs: torch.Tensor, cfg: KalmanConfig = KalmanConfig(), pred_len: int = PRED_LEN
) -> torch.Tensor:
    """Most-likely future of the constant-velocity Kalman filter."""
    x, _ = kalman_filter(obs, cfg)
    steps = torch.arange(1, pred_len + 1, dtype=x.dtype)
    return (x[:, None, :2] + steps[None, :, None] * x[:, None, 2:]).to(obs.dtype)


def kalman_samples(
    obs: torch.Tensor,
    num_samples: int,
    generator: torch.Generator,
    cfg: KalmanConfig = KalmanConfig(),
    pred_len: int = PRED_LEN,
) -> torch.Tensor:
    """Trajectories drawn from the filter's predictive distribution.

    The filtered state is sampled from its posterior, then propagated with sampled process noise, so each
    sample is a coherent trajectory of the linear-Gaussian model (not independent per-step draws).
    """
    x, p = kalman_filter(obs, cfg)
    f, q, _ = _kalman_matrices(cfg, x.dtype)
    n = x.shape[0]
    lp = torch.linalg.cholesky(p + 1e-9 * torch.eye(4, dtype=x.dtype))
    lq = torch.linalg.cholesky(q + 1e-12 * torch.eye(4, dtype=x.dtype))
    eps = torch.randn((num_samples, n, 4), generator=generator, dtype=x.dtype)
    state = x[None] + (lp[None] @ eps[..., None])[..., 0]
    out = []
    noise = torch.randn((pred_len, num_samples, n, 4), generator=generator, dtype=x.dtype)
    for t in range(pred_len):
        state = state @ f.T + noise[t] @ lq.T
        out.append(state[..., :2])
    return torch.stack(out, dim=2).to(obs.dtype)
