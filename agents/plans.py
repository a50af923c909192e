"""Scoring candidate plans against plan-conditioned forecasts (the PDM-Closed pattern, simplified).

A plan is a constant ego acceleration (m/s²) held over the forecast horizon, the speed kept within
[0, speed limit]. Each plan comes with its own pedestrian forecast (``plan_paths``: the path oracle rolls
the world forward under that plan, so pedestrians react to it). A plan is scored by driving the ego along
its profile against its forecast (closed loop, as PDM-Closed's IDM proposals: the ego brakes for a
pedestrian in its corridor ahead once a stop needs the comfortable deceleration) with the reward's own
terms (`scenarios.config.RewardConfig` weights):

- **progress**: metres covered over the horizon (the time term is the same for every plan: omitted);
- **collision**: the ego's box and a pedestrian's disc overlap (forecast points interpolated);
- **near_miss**: seconds in which a pedestrian in the ego's lane corridor ahead is closer than
  `serious_ttc` in time (gap / ego speed);
- **hard_braking**: a stop (for a pedestrian in the corridor ahead, or at the legal stop) that needs more
  than `hard_braking_threshold` costs the steps of a full stop at the ego's `max_deceleration`.

**Deferred conflicts** (a departure from PDM-Closed, whose agents do not react to the ego): a pedestrian who
waits for the car (a Euro NCAP pedestrian steps off when the car's time to arrival at its current speed falls
to a drawn value) enters the corridor ahead under a faster plan and stays on the kerb under a slower one.
Scored within the horizon alone, the slower plan looks free of conflict: it only moves the conflict beyond
the horizon, and a car that re-plans every step keeps slowing and creeps up to the person, who keeps
waiting (a dev trace, ncap_cpna: 1.7 m/s for 4 s, time to pass 16.0 s against the rules' 5.4 s). So a plan
that neither meets nor has passed a pedestrian whom another plan meets in the corridor ahead is charged the
mildest near-miss and hard-braking cost among the plans that meet that pedestrian (`plan_deferral`): the
conflict is still to come. Near-miss time accrues only while the ego moves, so a plan that stops the car
and lets the person cross meets them at no near-miss cost. A meeting plan's cost is its whole near-miss and
hard-braking cost, not the share due to that one pedestrian (the forecasts do not attribute it), so with
several people about the charge can be too high; the NCAP scenarios it is for have one. The deferring plan
is also charged the time the car will still wait for that person to walk across its corridor after the
horizon, at the progress weight and the speed limit (`plan_deferred_wait`): otherwise a car that has slowed
keeps crawling towards someone who waits for it to stand, since crawling scores more progress than stopping.

The legal-yield rules stay in force whatever the plan, so a plan's ego stops at the rules' legal stop
target (the stop line for a red light or a zebra duty) and cannot run into anyone beyond it.

Left out, and why: failing_to_yield (the legal-yield rules of `YieldingPolicy` stay in force and
override any plan) and speeding (no plan exceeds the limit).
"""

from __future__ import annotations

import numpy as np

from agents.config import PredictiveYieldingConfig
from crossing_env.observation import HISTORY_INTERVAL

SUBSTEPS = 4
"""Ego integration steps per 0.4 s forecast interval."""
WALKING_ACROSS = 0.2
"""Slowest lateral pace (m/s) assumed for a deferred pedestrian's walk across the corridor."""


def score_plans(
    speed: np.ndarray,
    accelerations: np.ndarray,
    plan_paths: np.ndarray,
    present: np.ndarray,
    cfg: PredictiveYieldingConfig,
    stop: np.ndarray | None = None,
    start: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Score (B, P) of each plan (higher is better) and whether it forecasts a hazard (B, P).

    `plan_paths` (B, P, K, T, 2) are positions relative to the ego's current centre (x along the road),
    `start` (B, K, 2) the current ones (default: the first forecast point); `present` (B, K); `stop`
    (B,): the legal stop's distance ahead of the ego's front (inf: none). The ego follows the plan's
    acceleration but, like the rules, brakes for a pedestrian in its lane corridor ahead once a stop needs
    `comfortable_deceleration` (up to its `max_deceleration`), and halts at `stop`. A hazard is a forecast
    collision (near misses are scored but are too common, in every stop for a pedestrian, to lift it).
    """
    w, m = cfg.plan_weights, cfg.plan_metrics
    b, p, _k, steps, _ = plan_paths.shape
    first = (
        plan_paths[:, :, :, 0]
        if start is None
        else np.broadcast_to(start[:, None], plan_paths[..., 0, :].shape)
    )
    pts = np.concatenate([first[:, :, :, None], plan_paths], axis=3)  # (B, P, K, T + 1, 2)
    dt = HISTORY_INTERVAL / SUBSTEPS
    r = cfg.pedestrian_radius
    half_len = cfg.ego_length / 2 + r
    ok = present[:, None, :]
    cap = np.maximum(cfg.speed_limit, speed)[:, None]
    halt = np.full((b, 1), np.inf) if stop is None else np.asarray(stop, np.float64)[:, None]
    v = np.broadcast_to(speed[:, None], (b, p)).astype(np.float64)
    s = np.zeros_like(v)
    collision = np.zeros((b, p), dtype=bool)
    hard = np.zeros((b, p), dtype=bool)
    near_time = np.zeros((b, p))
    meets = np.zeros(plan_paths.shape[:3], dtype=bool)  # (B, P, K): in the corridor ahead at some step
    for n in range(1, steps * SUBSTEPS + 1):
        j, f = divmod(n, SUBSTEPS)
        at = (
            pts[:, :, :, j]
            if f == 0
            else pts[:, :, :, j] + (f / SUBSTEPS) * (pts[:, :, :, j + 1] - pts[:, :, :, j])
        )
        rel_x = at[..., 0] - s[..., None]  # (B, P, K)
        y = np.abs(at[..., 1])
        collision |= (ok & (y <= cfg.ego_width / 2 + r) & (np.abs(rel_x) <= half_len)).any(-1)
        ahead = ok & (y <= cfg.ego_width / 2 + r + cfg.lateral_margin) & (rel_x > half_len)
        meets |= ahead
        gap = np.where(ahead, rel_x - half_len, np.inf)
        gap = np.minimum(gap.min(axis=-1), halt - s)  # nearest obstacle ahead, the legal stop included
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.where(gap > 0.05, v * v / (2.0 * np.maximum(gap, 0.05)), np.where(v > 0.0, np.inf, 0.0))
            near_time += np.where((v > 0.1) & (gap - (halt - s) < 0.0) & (gap < v * m.serious_ttc), dt, 0.0)
        brake = need >= cfg.comfortable_deceleration
        hard |= brake & (need > m.hard_braking_threshold)
        acc = np.where(brake, -np.minimum(need, cfg.ego.max_deceleration), accelerations[None, :])
        nxt = np.clip(v + acc * dt, 0.0, cap)
        s = np.minimum(s + 0.5 * (v + nxt) * dt, np.maximum(halt, s))
        v = np.where(s >= halt, 0.0, nxt)
    hard_steps = np.ceil(np.maximum(speed, 0.0) / cfg.ego.max_deceleration / cfg.dt)[:, None]
    conflict = w.near_miss * near_time + w.hard_braking * hard_steps * hard  # (B, P), ≤ 0
    end = pts[:, :, :, -1]  # (B, P, K, 2)
    rel_end = end[..., 0] - s[..., None]
    # Pedestrian k is deferred by plan p if another plan meets it and p neither meets nor passes it.
    deferred = ~meets & (rel_end > -half_len) & meets.any(axis=1, keepdims=True)  # (B, P, K)
    if cfg.plan_deferral:
        conflict = conflict + _deferred_cost(conflict, meets, deferred)
    score = w.progress * s + w.collision * collision + conflict
    if cfg.plan_deferred_wait:
        band = cfg.ego_width / 2 + r + cfg.lateral_margin
        wait = _deferred_wait(pts[..., 1], rel_end - half_len, deferred, band, cfg.speed_limit)
        score = score - w.progress * cfg.speed_limit * wait
    return score, collision


def _deferred_wait(
    y: np.ndarray, gap: np.ndarray, deferred: np.ndarray, band: float, speed_limit: float
) -> np.ndarray:
    """(B, P) seconds the ego will still wait, after the horizon, for the pedestrians a plan defers.

    `y` (B, P, K, T + 1) are the forecast lateral positions, `gap` (B, P, K) each pedestrian's distance
    ahead of the ego's front at the horizon's end, `deferred` (B, P, K) as in `score_plans`. Someone
    deferred will still walk across the whole corridor (half-width `band`) from where this plan leaves
    them, at the fastest lateral pace any plan's forecast shows for them; the wait is that walk (at most
    one horizon) less the time the ego needs to drive there at the speed limit, and the longest one
    counts. Without it a plan that crawls towards a person who waits for the car keeps scoring more
    progress than stopping and letting them cross (a dev trace, ncap_cpna: 2.7 m/s held for 4 s, then
    0.5 m/s for 9 s).
    """
    horizon = (y.shape[-1] - 1) * HISTORY_INTERVAL
    pace = np.abs(np.diff(y, axis=-1)).max(axis=(1, 3), keepdims=True)[..., 0] / HISTORY_INTERVAL  # (B,1,K)
    walk = (np.abs(y[..., -1]) + band) / np.maximum(pace, WALKING_ACROSS)
    wait = np.clip(np.minimum(walk, horizon) - np.maximum(gap, 0.0) / speed_limit, 0.0, None)
    return np.where(deferred, wait, 0.0).max(axis=-1, initial=0.0)


def _deferred_cost(conflict: np.ndarray, meets: np.ndarray, deferred: np.ndarray) -> np.ndarray:
    """(B, P) cost of the conflicts a plan only defers (see the module docstring; 0 where none).

    `conflict` (B, P) is each plan's own near-miss and hard-braking cost (≤ 0), `meets` (B, P, K) whether
    the plan's ego has pedestrian k in its corridor ahead at some step, `deferred` (B, P, K) whether the
    plan only defers k. A plan is charged the mildest cost among the plans that meet a pedestrian it
    defers (the worst over its deferred pedestrians).
    """
    mildest = np.where(meets, conflict[..., None], -np.inf).max(axis=1, keepdims=True)  # (B, 1, K)
    return np.where(deferred, mildest, 0.0).min(axis=-1)


def choose_plans(
    score: np.ndarray,
    hazard: np.ndarray,
    current: np.ndarray,
    held: np.ndarray,
    cfg: PredictiveYieldingConfig,
) -> np.ndarray:
    """Plan index (B,) to follow, with hysteresis.

    The current plan (`current`, −1 for none yet) is kept unless another scores at least
    `plan_switch_margin` higher and it has been held (`held`, seconds) for `plan_min_hold`; a current
    plan that forecasts a collision gives way at once to any better-scoring plan (safety is not held back).
    """
    best = np.argmax(score, axis=1)
    rows = np.arange(score.shape[0])
    cur = np.maximum(current, 0)
    gain = score[rows, best] - score[rows, cur]
    switch = (
        (current < 0)
        | ((gain >= cfg.plan_switch_margin) & (held >= cfg.plan_min_hold - 1e-9))
        | (hazard[rows, cur] & (gain > 0.0))
    )
    return np.where(switch, best, cur)
