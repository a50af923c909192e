"""crossing_eval.statistics: Wilson intervals, finite percentiles and the aggregation of episode results."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from crossing_env.safety import EpisodeResult, json_safe
from crossing_eval.statistics import aggregate, finite_percentiles, wilson_interval
from tests.crossing_env.safety.snapshots import make_gt, metrics


def _result(**kw: object) -> EpisodeResult:
    m = metrics()
    m.update(make_gt(0.1))
    return dataclasses.replace(m.result(), **kw)  # type: ignore[arg-type]


def test_wilson_interval() -> None:
    # 0/10: centre = (0 + 1.96²/20) / (1 + 1.96²/10) = 0.19208 / 1.38416 = 0.138771; half width equal
    lo, hi = wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.277541, abs=1e-6)
    # 5/10: centre 0.5; half = 1.96 sqrt(0.025 + 0.009604) / 1.38416 = 1.96 * 0.1860215 / 1.38416 = 0.263410
    lo, hi = wilson_interval(5, 10)
    assert lo == pytest.approx(0.236590, abs=1e-6) and hi == pytest.approx(0.763410, abs=1e-6)
    assert wilson_interval(0, 0) == (0.0, 1.0)
    # At 0 or n successes the bound is exactly the estimate: rounding put it a hair inside for n = 27
    # (0/27), which made crossing-eval's safety-vs-efficiency plot fail on a negative error bar.
    assert all(wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0 for n in range(1, 500))
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(11, 10)


def test_finite_percentiles() -> None:
    assert finite_percentiles([1.0, 2.0, 3.0, math.inf], [50]) == [2.0]
    assert finite_percentiles([1.0, 3.0], [0, 100]) == [1.0, 3.0]
    assert all(math.isnan(x) for x in finite_percentiles([math.inf, math.inf], [5, 50]))


def test_aggregate() -> None:
    results = [
        _result(collision=True, pedestrian_collisions=1, min_ttc=0.0, hard_braking_events=2,
                yield_obligations=2, yield_compliant=1, delay=4.0, passed_crossing=True),
        _result(min_ttc=1.0, hard_braking_events=0, yield_obligations=1, yield_compliant=1, delay=2.0,
                passed_crossing=True),
        _result(min_ttc=2.0, hard_braking_events=1, yield_obligations=1, yield_compliant=1),
        _result(min_ttc=math.inf, hard_braking_events=1, min_pet_pedestrian_first=1.2),
    ]  # fmt: skip
    agg = aggregate(results)
    assert agg["episodes"] == 4 and agg["collision_rate"] == 0.25
    assert agg["collision_ci95"] == pytest.approx(wilson_interval(1, 4))
    assert agg["pedestrian_collision_rate"] == 0.25
    assert agg["min_ttc_p50"] == pytest.approx(1.0)  # median of (0, 1, 2); inf ignored
    assert agg["min_ttc_finite_fraction"] == 0.75
    assert agg["serious_conflict_rate"] == 0.5  # 0.0 and 1.0 are below 1.5 s
    assert agg["hard_brakes_per_episode"] == 1.0  # (2 + 0 + 1 + 1) / 4
    assert agg["yield_compliance"] == 0.75 and agg["yield_obligations"] == 4  # (1 + 1 + 1) / (2 + 1 + 1)
    assert agg["mean_delay"] == 3.0 and agg["pass_rate"] == 0.5  # nan delays of unfinished episodes ignored
    assert agg["critical_pet_rate"] == 0.25 and agg["pet_pedestrian_first_p50"] == pytest.approx(1.2)
    json.dumps(json_safe(agg), allow_nan=False)
    with pytest.raises(ValueError, match="no episode"):
        aggregate([])
