"""Value rules: the `Rule` type, closed ranges, and the rules of the timed-conflict ranges (`[conflict]`).

`scenarios.validation.VALUE_RULES` is built from these; a range field (`ConflictConfig.ego_speed` and its
kind) is a two-element array `[lo, hi]` whose bounds must both lie in the field's plausible range, in order.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

from scenarios.config import ConflictConfig


@dataclass(frozen=True)
class Rule:
    """A range rule for one field; `None` values (meaning "draw from the population") are not checked."""

    check: Callable[[Any], bool]
    """Predicate the value must satisfy."""
    allowed: str
    """The rule in words, used in the error message."""
    unit: str = ""
    """Unit of a physical quantity (empty for counts, rates and names)."""
    why: str = ""
    """Source of or reason for the bounds (part of `allowed` too, so errors and docs show it)."""


def _between(
    lo: float,
    hi: float,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
    why: str = "",
) -> Rule:
    """A closed (or half-open) range; `unit` and `why` (the bounds' source or reason) go into the message."""
    left, right = ("(" if lo_open else "["), (")" if hi_open else "]")

    def check(v: float) -> bool:
        above = v > lo if lo_open else v >= lo
        below = v < hi if hi_open else v <= hi
        return above and below

    text = f"must be in {left}{lo:g}, {hi:g}{right}" + (f" {unit}" if unit else "")
    return Rule(check, text + (f" ({why})" if why else ""), unit, why)


_PROB = _between(0.0, 1.0)
_NONNEG = Rule(lambda v: v >= 0, "must be >= 0")


def range_rule(lo: float, hi: float, *, unit: str = "", why: str = "", optional: bool = False) -> Rule:
    """A `[low, high]` range field: two numbers in order, both within [`lo`, `hi`] (empty if `optional`)."""

    def check(v: Any) -> bool:
        if optional and len(v) == 0:
            return True
        return len(v) == 2 and lo <= v[0] <= v[1] <= hi

    empty = " or empty" if optional else ""
    text = f"must be a range [low, high]{empty} with {lo:g} <= low <= high <= {hi:g}" + (
        f" {unit}" if unit else ""
    )
    return Rule(check, text + (f" ({why})" if why else ""), unit, why)


def grid_rule(lo: float, hi: float, *, unit: str = "", why: str = "") -> Rule:
    """A list of distinct values, each within [`lo`, `hi`], in increasing order (empty: not used)."""

    def check(v: Any) -> bool:
        return all(lo <= x <= hi for x in v) and all(a < b for a, b in pairwise(v))

    text = f"must be increasing values, each with {lo:g} <= value <= {hi:g}" + (f" {unit}" if unit else "")
    return Rule(check, text + f" (or empty){' (' + why + ')' if why else ''}", unit, why)


CONFLICT_RULES: dict[tuple[type, str], Rule] = {
    (ConflictConfig, "x_offset"): range_rule(
        -50.0, 50.0, unit="m", why="the conflict lies near the crossing the metrics measure against"
    ),
    (ConflictConfig, "ego_speed"): range_rule(
        1.0, 27.8, unit="m/s", why="Euro NCAP sweeps 10-60 km/h; 27.8 = 100 km/h; 50 km/h typed as m/s fails"
    ),
    (ConflictConfig, "ego_speed_grid"): grid_rule(
        1.0, 27.8, unit="m/s", why="Euro NCAP tests at 10-60 km/h in 10 km/h steps; 27.8 = 100 km/h"
    ),
    (ConflictConfig, "pedestrian_speed"): range_rule(
        0.3,
        4.0,
        unit="m/s",
        why="a slow walker to a child's sprint; Euro NCAP's dummies walk 1.39, run 2.22",
    ),
    (ConflictConfig, "impact_offset"): range_rule(
        0.0, 1.0, why="fraction of the car's width: 0 its right edge, 1 its left; Euro NCAP uses 0.1-0.9"
    ),
    (ConflictConfig, "time_to_arrival"): range_rule(
        0.5,
        10.0,
        unit="s",
        why="CARLA triggers at 2.1-3.5 s; below 0.5 s no car can react, above 10 s "
        "the pedestrian would need a 10 m walk or more",
    ),
    (ConflictConfig, "occluder_gap"): range_rule(
        0.0, 10.0, unit="m", optional=True, why="Euro NCAP CPNCO: 1 m between the child's path and the car"
    ),
    (ConflictConfig, "radius"): _between(
        0.15, 0.5, unit="m", why="a toddler to an adult with a pram (as `PedestrianSpawn.radius`)"
    ),
}
"""Rules of `[conflict]`'s fields, merged into `scenarios.validation.VALUE_RULES`."""
