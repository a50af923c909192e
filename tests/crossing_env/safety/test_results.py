"""Tests of crossing_env.safety.results (`EpisodeResult`, JSON) and of the aggregation of results."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from crossing_env.safety import EpisodeResult, json_safe
from tests.crossing_env.safety.snapshots import make_gt, metrics

# ---------------------------------------------------------------------------------------------------------
# Results, JSON and aggregation
# ---------------------------------------------------------------------------------------------------------


def _result(**kw: object) -> EpisodeResult:
    m = metrics()
    m.update(make_gt(0.1))
    return dataclasses.replace(m.result(), **kw)  # type: ignore[arg-type]


def test_as_dict_is_json_safe_and_round_trips() -> None:
    r = _result(pets_pedestrian_first=(1.5, 2.0), delay=3.25)
    d = r.as_dict()
    text = json.dumps(d, allow_nan=False)  # raises on inf / nan
    assert d["min_ttc"] is None and d["delay"] == 3.25 and d["pets_pedestrian_first"] == [1.5, 2.0]
    back = EpisodeResult.from_dict(json.loads(text))
    assert back.min_ttc == math.inf and math.isnan(back.max_impact_speed)
    assert back.pets_pedestrian_first == (1.5, 2.0) and back.delay == 3.25
    with pytest.raises(ValueError, match="missing field 'delay'"):
        EpisodeResult.from_dict({k: v for k, v in d.items() if k != "delay"})
    assert json_safe({"a": (math.inf, np.float64(2.0), np.int64(3), np.bool_(True))}) == {
        "a": [None, 2.0, 3, True]
    }
