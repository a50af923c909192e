"""Aggregation of per-episode results across episodes: the figures of the evaluation table.

The per-episode accumulator (`crossing_env.safety.EpisodeMetrics`) belongs to the env; summarising
many episodes (confidence intervals, percentiles of episode minima) is the evaluator's job.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from crossing_env.safety import EpisodeResult, MetricsConfig

__all__ = [
    "aggregate",
    "censored_delay",
    "finite_percentiles",
    "newcombe_difference",
    "t_interval",
    "wilson_interval",
]


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion (95% for z = 1.96).

    Preferred over the normal approximation because it stays inside [0, 1] and is sensible at 0 or n
    successes, the usual case for collision rates. Returns (0, 1) for n = 0 (nothing is known).
    """
    if n < 0 or successes < 0 or successes > n:
        raise ValueError(f"wilson_interval: need 0 <= successes <= n, got successes={successes}, n={n}")
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    z2 = z * z
    denom = 1.0 + z2 / n
    centre = (p + z2 / (2 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z2 / (4 * n * n)) / denom
    # At 0 or n successes the bound is exactly 0 or 1; rounding could put it a hair inside (then the
    # interval would not contain the estimate, and matplotlib refuses the negative error bar).
    lo = 0.0 if successes == 0 else max(0.0, centre - half)
    hi = 1.0 if successes == n else min(1.0, centre + half)
    return lo, hi


def finite_percentiles(values: ArrayLike, qs: Sequence[float]) -> list[float]:
    """Percentiles (0–100) of the finite values only (inf = "never" is ignored); nan if none is finite."""
    arr = np.asarray(values, dtype=np.float64).ravel()
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return [math.nan for _ in qs]
    return [float(x) for x in np.percentile(arr, list(qs))]


def _mean(values: Sequence[float] | np.ndarray) -> float:
    arr = np.asarray(values, dtype=np.float64)
    arr = arr[~np.isnan(arr)]
    return float(arr.mean()) if arr.size else math.nan


def aggregate(results: Sequence[EpisodeResult], config: MetricsConfig | None = None) -> dict[str, Any]:
    """Summarise episodes for the evaluation table.

    Keys (floats may be nan when undefined; pass through `json_safe` before writing JSON):
    episodes; collision_rate and collision_ci95 (any collision, Wilson); pedestrian_collision_rate and
    pedestrian_collision_ci95; pedestrian_at_fault_collision_rate and _ci95 (episodes with an at-fault
    pedestrian collision, `crossing_env.collision_fault`); vehicle_collision_rate,
    vehicle_at_fault_collision_rate and _ci95; static_collisions (contacts);
    compliant/noncompliant_pedestrian_collisions; mean_impact_speed;
    min_ttc_p5/p50 (episode minima, inf ignored), min_ttc_finite_fraction (episodes with a finite minimum
    TTC, to read the percentiles against) and serious_conflict_rate (episodes with min TTC <
    `serious_ttc`); min_separation_min/p5/p50 (episode minima, the smallest over episodes first) and
    close_pass_rate (episodes with a minimum separation < `clearance`); pet_pedestrian_first_p5/p50,
    pet_ego_first_p5/p50 and
    critical_pet_rate (episodes with a PET < `critical_pet`); simultaneous_occupancies; drac_conflict_rate
    (episodes whose maximum crossing DRAC exceeds `drac_threshold`), drac_crossing_p95 (95th percentile of
    the episode maxima, each capped at `drac_cap`), drac_crossing_mean / _max (uncapped: near contact they
    run to hundreds of m/s², so the table shows the two before) and drac_following_max;
    hard_brakes_per_episode (events), comfort_violations_per_episode (steps),
    max_deceleration_mean; speeding_rate (episodes with any time over the speed limit),
    max_speed_over_limit_max/_mean (the episodes' largest excess, m/s) and time_over_speed_limit_mean
    (s per episode); yield_obligations, yield_compliance (= compliant / obligations, obligations still
    open at the end included) and yield_compliance_ci95, yield_unresolved (obligations open at the end);
    unneeded_stops_per_episode; pass_rate, mean_delay and mean_time_to_pass
    (episodes that passed); mean_pedestrian_wait; mean_distance; world health, which the ego is not part of:
    background_collisions (car–pedestrian contacts), background_collisions_legal (with a legal pedestrian),
    background_collision_rate and _ci95 (episodes with one, Wilson), background_collision_max_speed.
    """
    cfg = config if config is not None else MetricsConfig()
    n = len(results)
    if n == 0:
        raise ValueError("aggregate: no episode results given")

    def col(name: str) -> np.ndarray:
        return np.array([getattr(r, name) for r in results], dtype=np.float64)

    collisions = sum(r.collision for r in results)
    ped_coll = sum(r.pedestrian_collisions > 0 for r in results)
    ped_fault = sum(r.pedestrian_collisions_at_fault > 0 for r in results)
    veh_coll = sum(r.vehicle_collisions > 0 for r in results)
    veh_fault = sum(r.vehicle_collisions_at_fault > 0 for r in results)
    min_ttc = col("min_ttc")
    pet_p = col("min_pet_pedestrian_first")
    pet_e = col("min_pet_ego_first")
    obligations = sum(r.yield_obligations for r in results)
    compliant = sum(r.yield_compliant for r in results)
    ttc5, ttc50 = finite_percentiles(min_ttc, (5, 50))
    min_sep = col("min_separation")
    sep0, sep5, sep50 = finite_percentiles(min_sep, (0, 5, 50))
    over = col("max_speed_over_limit")
    over_time = col("time_over_speed_limit")
    pp5, pp50 = finite_percentiles(pet_p, (5, 50))
    pe5, pe50 = finite_percentiles(pet_e, (5, 50))
    passed = np.array([r.passed_crossing for r in results])
    drac = col("max_drac_crossing")
    waits = [w for r in results for w in r.pedestrian_wait_times]
    bg_episodes = sum(r.background_collisions > 0 for r in results)
    bg_speed = col("background_collision_max_speed")
    bg_any = bool(np.isfinite(bg_speed).any())
    return {
        "episodes": n,
        "collision_rate": collisions / n,
        "collision_ci95": wilson_interval(collisions, n),
        "pedestrian_collision_rate": ped_coll / n,
        "pedestrian_collision_ci95": wilson_interval(ped_coll, n),
        "pedestrian_at_fault_collision_rate": ped_fault / n,
        "pedestrian_at_fault_collision_ci95": wilson_interval(ped_fault, n),
        "vehicle_collision_rate": veh_coll / n,
        "vehicle_at_fault_collision_rate": veh_fault / n,
        "vehicle_at_fault_collision_ci95": wilson_interval(veh_fault, n),
        "static_collisions": sum(r.static_collisions for r in results),
        "compliant_pedestrian_collisions": sum(r.compliant_pedestrian_collisions for r in results),
        "noncompliant_pedestrian_collisions": sum(r.noncompliant_pedestrian_collisions for r in results),
        "mean_impact_speed": _mean(col("max_impact_speed")),
        "min_ttc_p5": ttc5,
        "min_ttc_p50": ttc50,
        "min_ttc_finite_fraction": float(np.mean(np.isfinite(min_ttc))),
        "serious_conflict_rate": float(np.mean(min_ttc < cfg.serious_ttc)),
        "min_separation_min": sep0,
        "min_separation_p5": sep5,
        "min_separation_p50": sep50,
        "close_pass_rate": float(np.mean(min_sep < cfg.clearance)),
        "pet_pedestrian_first_p5": pp5,
        "pet_pedestrian_first_p50": pp50,
        "pet_ego_first_p5": pe5,
        "pet_ego_first_p50": pe50,
        "critical_pet_rate": float(np.mean(np.minimum(pet_p, pet_e) < cfg.critical_pet)),
        "simultaneous_occupancies": sum(r.simultaneous_occupancies for r in results),
        "drac_conflict_rate": float(np.mean(drac > cfg.drac_threshold)),
        "drac_crossing_p95": finite_percentiles(np.minimum(drac, cfg.drac_cap), (95,))[0],
        "drac_crossing_mean": float(drac[np.isfinite(drac)].mean()) if np.isfinite(drac).any() else math.nan,
        "drac_crossing_max": float(drac.max()),
        "drac_following_max": float(col("max_drac_following").max()),
        "hard_brakes_per_episode": float(col("hard_braking_events").mean()),
        "comfort_violations_per_episode": float(col("comfort_violation_steps").mean()),
        "max_deceleration_mean": float(col("max_deceleration").mean()),
        "speeding_rate": float(np.mean(over_time > 0.0)),
        "max_speed_over_limit_max": float(over.max()),
        "max_speed_over_limit_mean": float(over.mean()),
        "time_over_speed_limit_mean": float(over_time.mean()),
        "yield_obligations": obligations,
        "yield_compliance": compliant / obligations if obligations else math.nan,
        "yield_compliance_ci95": wilson_interval(compliant, obligations),
        "yield_unresolved": sum(r.yield_unresolved for r in results),
        "unneeded_stops_per_episode": float(col("unneeded_stops").mean()),
        "pass_rate": float(passed.mean()),
        "mean_delay": _mean(col("delay")),
        "mean_time_to_pass": _mean(col("time_to_pass")),
        "mean_pedestrian_wait": _mean(waits),
        "mean_distance": float(col("distance_travelled").mean()),
        "background_collisions": sum(r.background_collisions for r in results),
        "background_collisions_legal": sum(r.background_collisions_legal for r in results),
        "background_collision_rate": bg_episodes / n,
        "background_collision_ci95": wilson_interval(bg_episodes, n),
        "background_collision_max_speed": float(np.nanmax(bg_speed)) if bg_any else math.nan,
    }


def censored_delay(delays: ArrayLike, passed: ArrayLike, horizons: ArrayLike) -> dict[str, float]:
    """Delay with the episodes that never pass counted: pass rate plus the censored mean delay.

    The plain mean delay covers passing episodes only, so a policy that never passes looks prompt. Here an
    episode that did not pass counts with a delay equal to its scenario's duration (`horizons`, s): a fixed
    penalty, not an estimate of its true delay (it can exceed a time-limited episode's delay by up to the
    free-flow time, and a collision before the crossing costs it in full), chosen so that never passing is
    never cheaper than passing late. Returns pass_rate, censored_mean_delay and censored_episodes (the
    exact rule: ``docs/results.md``).
    """
    d = np.asarray(delays, dtype=np.float64).ravel()
    ok = np.asarray(passed, dtype=bool).ravel()
    h = np.broadcast_to(np.asarray(horizons, dtype=np.float64), d.shape)
    if d.size == 0:
        raise ValueError("censored_delay: no episodes given")
    values = np.where(ok & np.isfinite(d), d, h)
    return {
        "pass_rate": float(ok.mean()),
        "censored_mean_delay": float(values.mean()),
        "censored_episodes": int(np.count_nonzero(~ok)),
    }


def newcombe_difference(
    successes_a: int, n_a: int, successes_b: int, n_b: int, z: float = 1.96
) -> tuple[float, float, float]:
    """Difference of two proportions b − a with Newcombe's hybrid score interval (from Wilson intervals).

    Used by ``crossing-eval compare`` for collision and pass rates: like Wilson's interval it stays sensible
    at 0 or n events, where the normal approximation collapses to a zero-width interval.
    """
    if n_a == 0 or n_b == 0:
        return math.nan, -1.0, 1.0
    pa, pb = successes_a / n_a, successes_b / n_b
    la, ua = wilson_interval(successes_a, n_a, z)
    lb, ub = wilson_interval(successes_b, n_b, z)
    diff = pb - pa
    low = diff - math.sqrt((pb - lb) ** 2 + (ua - pa) ** 2)
    high = diff + math.sqrt((ub - pb) ** 2 + (pa - la) ** 2)
    return diff, max(-1.0, low), min(1.0, high)


def t_interval(values: ArrayLike, confidence: float = 0.95) -> tuple[float, float, float]:
    """Mean and its Student-t interval; nan without values.

    One value, or values that do not vary beyond rounding, give the mean as both bounds: nothing measured
    a spread. Used for episode scores (`crossing_eval.scoring.mean_interval`) and paired differences.
    """
    x = np.asarray(values, dtype=np.float64)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    sem = float(stats.sem(x)) if x.size > 1 else 0.0
    if not sem > 1e-12:
        return mean, mean, mean
    lo, hi = stats.t.interval(confidence, x.size - 1, loc=mean, scale=sem)
    return mean, float(lo), float(hi)
