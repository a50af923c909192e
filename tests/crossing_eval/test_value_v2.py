"""Value of prediction v2: paired differences, value captured per metric, the dominant-scenario check."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from crossing_eval.value_v2 import analyse, plot_curve, render_body


def _result(
    delay: float, brakes: int, ttc: float, compliant: int = 2, obligations: int = 2
) -> dict[str, Any]:
    return {
        "passed_crossing": True,
        "delay": delay,
        "duration": 40.0,
        "collision": False,
        "yield_compliant": compliant,
        "yield_obligations": obligations,
        "hard_braking_events": brakes,
        "min_ttc": ttc,
        "max_drac_crossing": 1.0,
        "min_separation": 2.0,
        "unneeded_stops": 0,
    }


def _row(
    delays: list[float], brakes: list[int], ttc: list[float], scenario: str = "zebra_case1"
) -> list[dict]:
    return [
        {"scenario": scenario, "episode": e, "seed": 100 + e, "result": _result(d, b, t)}
        for e, (d, b, t) in enumerate(zip(delays, brakes, ttc, strict=True))
    ]


def _records() -> dict[tuple[str, str], list[dict[str, Any]]]:
    rng = np.random.default_rng(0)
    n = 40
    base = list(10.0 + rng.normal(0, 1, n))
    brakes = [1] * n
    ttc = list(1.0 + rng.normal(0, 0.1, n))
    return {
        ("none", "none"): _row(base, brakes, ttc),
        ("oracle", "none"): _row([d - 4.0 for d in base], brakes, ttc),  # 4 s faster, same margins
        ("learned", "none"): _row([d - 1.0 for d in base], brakes, ttc),  # a quarter of it
        ("none", "oracle"): _row(base, [0] * n, [t + 0.5 for t in ttc]),  # safer, not faster
        ("none", "cvm"): _row(base, [1 if e % 2 else 0 for e in range(n)], ttc),
    }


def test_differences_and_value_captured_follow_the_rows() -> None:
    data = analyse(_records(), {"intent": {"learned": {"brier": 0.1}}}, {"policy": "p"}, n_resamples=200)
    rows = {(r["intention"], r["predictor"]): r for r in data["rows"]}
    learned = rows[("learned", "none")]["metrics"]
    assert learned["mean_delay"]["diff"] == pytest.approx(-1.0)
    assert learned["mean_delay"]["captured"] == pytest.approx(0.25)
    lo, hi = learned["mean_delay"]["captured_ci"]
    assert lo == pytest.approx(0.25) and hi == pytest.approx(0.25)  # a constant shift: a point interval
    assert rows[("learned", "none")]["accuracy"] == {"brier": 0.1}
    # The intent oracle brings no safety margin: no share of it is reported.
    assert math.isnan(learned["hard_brakes"]["captured"])
    cvm = rows[("none", "cvm")]["metrics"]
    assert cvm["hard_brakes"]["captured"] == pytest.approx(0.5)  # half the oracle's removed brakes
    assert math.isnan(cvm["mean_delay"]["captured"])  # the path oracle is not faster
    assert rows[("none", "oracle")]["metrics"]["min_ttc_p5"]["diff"] == pytest.approx(0.5)


def test_a_scenario_holding_most_obligations_is_left_out_of_the_check() -> None:
    records = _records()
    for key, recs in records.items():
        busy = [dict(r, scenario="busy_zebra") for r in recs]
        for r in busy:
            r["result"] = dict(r["result"], yield_obligations=20, yield_compliant=20)
        records[key] = recs + busy
    data = analyse(records, {}, {"policy": "p"}, n_resamples=200)
    assert data["dominant"] == ["busy_zebra"]
    assert data["obligation_share"]["busy_zebra"] == pytest.approx(20 / 22)
    without = {(r["intention"], r["predictor"]): r for r in data["without_dominant"]}
    assert without[("none", "none")]["episodes"] == 40


def test_render_states_targets_and_the_figure_draws() -> None:
    data = analyse(_records(), {}, {"policy": "p"}, n_resamples=200)
    data.update(
        commit="abc123def456",
        wall_seconds=1.0,
        settings={
            "command": "python -m studies.value_of_prediction",
            "policy": "predictive_yielding",
            "scenarios": ["zebra_case1"],
            "episodes": 40,
            "flip_episodes": 10,
            "path_episodes": 8,
            "path_sweep_episodes": 4,
            "accuracy_episodes": 2,
            "seed": 2024,
        },
    )
    text = render_body(data)
    base = np.mean([r["result"]["delay"] for r in _records()[("none", "none")]])
    assert f"Oracle intention vs the remembering baseline: censored delay {-4.0 / base:+.1%}" in text
    assert "**met**" in text and "**missed**" in text  # oracle targets met, learned's 25 % < 30 % missed
    assert "**learned** captures 25 %" in text
    assert "| intent: learned | 40 |" in text
    assert plot_curve(data)[:8] == b"\x89PNG\r\n\x1a\n"


def test_delay_per_scenario_shows_the_scenario_that_carries_a_row() -> None:
    """A row slower on one scenario only: the pooled mean hides it, the per-scenario cells show it."""
    records = _records()
    for key, recs in list(records.items()):
        extra = [dict(r, scenario="ncap_cpna") for r in recs]
        if key == ("none", "oracle"):
            extra = [dict(r, result=dict(r["result"], delay=r["result"]["delay"] + 8.0)) for r in extra]
        records[key] = recs + extra
    data = analyse(records, {}, {"policy": "p"}, n_resamples=200)
    rows = {(r["intention"], r["predictor"]): r for r in data["rows"]}
    per = rows[("none", "oracle")]["delay_by_scenario"]
    assert per["ncap_cpna"]["diff"] == pytest.approx(8.0) and per["ncap_cpna"]["episodes"] == 40
    assert per["ncap_cpna"]["diff_ci"] == pytest.approx([8.0, 8.0])  # a constant shift: a point interval
    assert per["zebra_case1"]["diff"] == pytest.approx(0.0)
    assert rows[("none", "oracle")]["metrics"]["mean_delay"]["diff"] == pytest.approx(4.0)
    assert rows[("oracle", "none")]["delay_by_scenario"]["ncap_cpna"]["diff"] == pytest.approx(-4.0)
    data.update(
        commit="abc123def456",
        wall_seconds=1.0,
        settings={
            "command": "c", "policy": "p", "scenarios": ["ncap_cpna", "zebra_case1"], "episodes": 40,
            "flip_episodes": 10, "path_episodes": 40, "path_sweep_episodes": 4, "accuracy_episodes": 2,
            "seed": 2024,
        },
    )  # fmt: skip
    text = render_body(data)
    line = next(x for x in text.splitlines() if x.startswith("| ncap_cpna |") and "+8.00 [+8.00, +8.00]" in x)
    assert line.count("|") == 2 + len(rows)  # the scenario and one cell per row
