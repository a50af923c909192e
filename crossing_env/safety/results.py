"""What one episode's safety and efficiency measurement is: `MetricsConfig` in, `EpisodeResult` out.

JSON convention: `EpisodeResult.as_dict()` and `json_safe()` write non-finite floats (inf = "never",
nan = "undefined / not reached") as ``None``; `EpisodeResult.from_dict()` restores them per field.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

__all__ = ["DEFAULT_METRICS", "EpisodeResult", "MetricsConfig", "json_safe"]

_INF = math.inf


# ---------------------------------------------------------------------------------------------------------
# Configuration and per-episode result
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MetricsConfig:
    """Thresholds and the free choices of the operational definitions (SI units)."""

    hard_braking_threshold: float = 3.0
    """Deceleration (m/s², positive) counted as hard braking (crash-risk studies, ITE; `RewardConfig`)."""
    comfort_deceleration: float = 4.05
    """Deceleration (m/s²) beyond nuPlan's comfort bound (`ego_is_comfortable`, a ≥ −4.05)."""
    yield_deceleration: float = 3.0
    """Comfortable deceleration (m/s²) for the yield obligation's stopping distance v² / (2·b)."""
    serious_ttc: float = 1.5
    """TTC (s) below which a step counts as a serious conflict (Sacchi 2016; El-Basyouny 2013)."""
    encounter_ttc: float = 3.0
    """TTC (s) below which a step counts as an encounter (SUMO SSM logging threshold)."""
    critical_pet: float = 1.5
    """PET (s) below which an encounter is critical (Peesapati 2018)."""
    drac_threshold: float = 3.35
    """DRAC (m/s²) above which an encounter is a conflict: the usual threshold (Archer 2005, after Cooper
    and Ferguson 1976); SUMO logs DRAC > 3.0, Huber 2020 uses 3.4."""
    drac_cap: float = 9.81
    """DRAC figures are capped at 1 g (m/s²): no car brakes harder, and near contact the formula grows
    without bound (hundreds of m/s²), which says nothing more than 'unavoidable'."""
    clearance: float = 1.0
    """Footprint distance (m) below which the ego is too close to a pedestrian (1–2 m is typical)."""
    ttc_min_ego_speed: float = 5e-3
    """TTC is not evaluated while the ego is slower than this (m/s), as nuPlan: a stopped car is hit."""
    delay_margin: float = 5.0
    """The delay is measured until the ego centre is this far (m) past the crossing's far edge."""
    pass_trigger_distance: float = 30.0
    """Time to pass starts when the ego front is this close (m) to the crossing's near edge."""
    kerb_margin: float = 1.0
    """A waiting pedestrian counts for yielding if its x is within the crossing ± this margin (m)."""
    far_half_counts: bool = True
    """Pedestrians on the crossing in the opposite half walking towards the ego's half also create an
    obligation (UK rule 195: once a pedestrian has moved onto the crossing)."""
    offer_stop_speed: float = 0.1
    """Ego speed (m/s) regarded as stopped when offering the way."""
    offer_distance: float = 20.0
    """The ego offers the way only when stopped within this distance (m) before the stop line, or past the
    line but before the crossing (a car that crept over the line and stands is still giving way)."""
    offer_timeout: float = 3.0
    """Stopped time (s) after which a still-waiting pedestrian is taken to have declined the offer; the
    obligation then ends as compliant (the car may go)."""
    outrun_margin: float = 1.0
    """An NCAP episode without contact is 'outrun', not 'avoided', when the ego's rear cleared the dummy's
    path less than this (s) before the dummy would reach the car's side (`EpisodeResult.ncap_outcome`)."""
    unneeded_stop_speed: float = 0.5
    """The ego counts as stopping (`EpisodeResult.unneeded_stops`) when its speed falls below this (m/s)."""
    stop_attribution_distance: float = 5.0
    """Pedestrians within this distance (m) of the crossing along the road can be the reason for a stop."""
    stop_attribution_lateral: float = 3.0
    """... and within this distance (m) of a kerb, on the sidewalk."""
    near_miss_distance: float = 2.0
    """A pedestrian on the road closer than this (m) to the ego footprint makes a near miss
    (`EpisodeResult.near_miss`): its proximity rises linearly from 0 here to 1 at contact."""
    near_miss_speed: float = 50.0 / 3.6
    """Ego speed (m/s) at which a near miss counts in full (50 km/h, the urban limit); slower passes count
    in proportion, so a car creeping past a pedestrian is not a near miss however close."""


DEFAULT_METRICS = MetricsConfig()
"""The default thresholds, one shared instance (the env's reward and `EpisodeMetrics` use it when given no
config, so checking that both use the same thresholds is an identity test)."""

# Fields added later, with defaults: older logs without them still load.
_OPTIONAL_FIELDS = frozenset(
    {
        "ncap_impact_speed",
        "stops",
        "unneeded_stops",
        "max_speed_over_limit",
        "time_over_speed_limit",
        "pedestrian_collisions_at_fault",
        "vehicle_collisions_at_fault",
        "static_collisions",
        "yield_unresolved",
        "ncap_outcome",
        "near_miss",
        "target_time",
    }
)

# Fields whose "missing" value means "never happened" (inf) rather than "undefined" (nan).
_INF_FIELDS = frozenset(
    {
        "min_ttc",
        "min_ttc_vehicle",
        "min_separation",
        "min_vehicle_separation",
        "min_pet_pedestrian_first",
        "min_pet_ego_first",
    }
)


@dataclass(frozen=True)
class EpisodeResult:
    """Per-episode safety and efficiency figures. Times in s, distances in m, speeds in m/s, accel. m/s²."""

    scenario: str
    """Scenario name."""
    duration: float
    """Simulation time of the last update."""
    steps: int
    """Number of updates."""
    collision: bool
    """Any ego collision (pedestrian, vehicle or static), at fault or not."""
    pedestrian_collisions: int
    """Number of ego–pedestrian contacts."""
    vehicle_collisions: int
    """Number of ego–vehicle contacts (moving road users' vehicles; static bodies apart)."""
    compliant_pedestrian_collisions: int
    """Contacts with pedestrians crossing legally (`CollisionEvent.compliant`)."""
    noncompliant_pedestrian_collisions: int
    """Contacts with jaywalking / red-light pedestrians."""
    max_impact_speed: float
    """Largest impact speed of an ego–pedestrian collision: the ego's speed when the contact began (as Euro
    NCAP measures it; injury risk follows the car's speed); nan without pedestrian collision."""
    background_collisions: int
    """Contacts between background cars and pedestrians (world health: the ego is not involved)."""
    background_collision_max_speed: float
    """Largest relative speed of a background car–pedestrian contact; nan if none."""
    background_collisions_legal: int
    """Background contacts in which the pedestrian was crossing legally (or off the road)."""
    min_ttc: float
    """Minimum ego–pedestrian TTC (box–disc, constant velocity); inf if never on a collision course."""
    min_ttc_vehicle: float
    """Minimum following TTC to a vehicle ahead in the ego's lane; inf if never closing."""
    serious_conflict_time: float
    """Time with pedestrian TTC < `serious_ttc`."""
    encounter_time: float
    """Time with pedestrian TTC < `encounter_ttc`."""
    min_separation: float
    """Minimum ego–pedestrian footprint distance (negative = overlap); inf without pedestrians."""
    min_vehicle_separation: float
    """Minimum ego–vehicle footprint distance; inf without vehicles."""
    clearance_violation_time: float
    """Time with some pedestrian closer than `clearance` to the ego footprint."""
    max_drac_crossing: float
    """Largest crossing DRAC of the ego against pedestrians occupying the conflict area first; 0 if none."""
    max_drac_following: float
    """Largest following DRAC against vehicles ahead in the ego's lane; 0 if none."""
    min_pet_pedestrian_first: float
    """Smallest PET with the pedestrian leaving the conflict area before the ego enters; inf if none."""
    min_pet_ego_first: float
    """Smallest PET with the ego leaving before a pedestrian enters; inf if none."""
    pets_pedestrian_first: tuple[float, ...]
    """All pedestrian-first PET values (one per pedestrian and ego entry)."""
    pets_ego_first: tuple[float, ...]
    """All ego-first PET values (one per pedestrian entry after the ego left)."""
    simultaneous_occupancies: int
    """Entries into the conflict area while the other party was inside (PET undefined: a conflict)."""
    hard_braking_steps: int
    """Steps with acceleration ≤ −`hard_braking_threshold`."""
    hard_braking_events: int
    """Separate hard-braking manoeuvres (runs of consecutive hard-braking steps)."""
    comfort_violation_steps: int
    """Steps with acceleration ≤ −`comfort_deceleration`."""
    max_deceleration: float
    """Largest deceleration (positive number, SUMO maxBR); 0 if the ego never braked."""
    yield_obligations: int
    """Pedestrians the ego had to give way to (see `EpisodeMetrics`): compliant + violations + unresolved."""
    yield_compliant: int
    """Obligations met: the ego did not enter the conflict area before the pedestrian cleared its half."""
    yield_violations: int
    """Obligations broken."""
    yield_offers_declined: int
    """Compliant obligations ended because a waiting pedestrian did not cross although the ego had stopped."""
    passed_crossing: bool
    """The ego reached the delay target (crossing far edge + `delay_margin`)."""
    delay: float
    """Time to reach the delay target minus free-flow time at the speed limit; nan if not reached."""
    time_to_pass: float
    """From the ego front `pass_trigger_distance` before the crossing until its rear clears it; nan if not."""
    distance_travelled: float
    """Ego progress along x since the start."""
    pedestrian_wait_times: tuple[float, ...]
    """Kerb arrival → stepping off, for each pedestrian who stepped off (0 if it did not stop)."""
    censored_waits: int
    """Pedestrians still waiting at the end of the episode (not in `pedestrian_wait_times`)."""
    stops: int = 0
    """Stops near the crossing with a pedestrian at the kerb as a possible reason (`safety.stops`)."""
    unneeded_stops: int = 0
    """Of those, stops for pedestrians who then did not step onto the road in front of the ego."""
    max_speed_over_limit: float = 0.0
    """Largest ego speed above the scenario's speed limit (`RoadConfig.speed_limit`); 0 if never above."""
    time_over_speed_limit: float = 0.0
    """Time the ego drove faster than the speed limit (steps above it × dt)."""
    pedestrian_collisions_at_fault: int = 0
    """Ego–pedestrian contacts with the ego at fault (nuPlan's rule, `crossing_env.collision_fault`)."""
    vehicle_collisions_at_fault: int = 0
    """Ego–vehicle contacts in which the ego was at fault (a rear-end crash into a car ahead, say)."""
    static_collisions: int = 0
    """Ego contacts with static bodies (always at fault, unless the ego stood still); 0 on the built-in roads,
    where nothing static stands in the ego's lane."""
    ncap_outcome: str = ""
    """For a scenario whose key pedestrian is a test dummy (the `ncap_*` family): 'impact' (the ego hit the
    dummy), 'outrun' (no contact, but the ego's rear cleared the dummy's path less than
    `MetricsConfig.outrun_margin` before the dummy reached the car's side: it got away by speed),
    'not tested' (the dummy was never released: the car never came near) or 'avoided'; '' otherwise."""
    ncap_impact_speed: float = math.nan
    """Impact speed with the test dummy as Euro NCAP scores it (m/s): the ego's speed at the first contact
    less the dummy's speed along the ego's heading (0 for a dummy crossing the road, so the car's speed;
    the walker's 1.39 m/s in CPLA); nan without a contact with a dummy."""
    yield_unresolved: int = 0
    """Obligations still open when the episode ended (the pedestrian had not cleared the ego's half and the
    ego had not entered the conflict area): counted among the obligations, not as compliant."""
    near_miss: float = 0.0
    """Worst near miss in [0, 1]: the largest, over steps and pedestrians on the road, of proximity (1 at
    contact, 0 at `MetricsConfig.near_miss_distance`) × the ego's speed over `near_miss_speed` (capped at
    1). A pass at 0.01 m and 72 km/h is 1; one at 1 m and 10 km/h is 0.1; 0 if none came close."""
    target_time: float = math.nan
    """Time (s) at which the ego reached the delay target (`delay` adds the free-flow time to it); nan if
    not reached. The episode score's progress compares it with a reference driver's."""

    @property
    def yield_compliance(self) -> float:
        """Compliant / obligations (unresolved ones included in the denominator); nan without obligations."""
        return self.yield_compliant / self.yield_obligations if self.yield_obligations else math.nan

    def as_dict(self) -> dict[str, Any]:
        """JSON-safe dict: tuples become lists, inf and nan become None (see the module docstring)."""
        return {f.name: json_safe(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> EpisodeResult:
        """Inverse of `as_dict`: None becomes inf for the min-TTC/PET/separation fields, nan otherwise."""
        kwargs: dict[str, Any] = {}
        for f in fields(cls):
            if f.name not in data and f.name in _OPTIONAL_FIELDS:
                continue  # logs written before the field existed
            if f.name not in data:
                raise ValueError(f"EpisodeResult.from_dict: missing field {f.name!r}")
            value = data[f.name]
            if value is None:
                value = _INF if f.name in _INF_FIELDS else math.nan
            elif isinstance(value, list):
                value = tuple(math.nan if x is None else float(x) for x in value)
            kwargs[f.name] = value
        return cls(**kwargs)


def json_safe(value: Any) -> Any:
    """Recursively convert to JSON-safe Python types: non-finite floats → None, tuples/arrays → lists."""
    if isinstance(value, bool | str) or value is None:
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return [json_safe(x) for x in value.tolist()]
    if isinstance(value, Sequence):
        return [json_safe(x) for x in value]
    return value
