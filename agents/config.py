"""Configuration of the driving policies: one frozen dataclass per policy, each field documented.

Quantities the observation does not carry (speed limit, lateral extent of the ego's half of the road, the
action scaling) live here; `agents.make_policy(name, scenario=...)` fills them from a `ScenarioConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from crossing_env.safety.results import MetricsConfig
from crossing_env.safety.score import ScoreConfig
from scenarios.config import EgoConfig, RewardConfig


@dataclass(frozen=True)
class DrivingConfig:
    """Settings shared by every policy: vehicle, road and car-following parameters (SI units)."""

    ego: EgoConfig = field(default_factory=EgoConfig)
    """The ego's limits; its `max_acceleration` / `max_deceleration` scale the normalised action."""
    speed_limit: float = 13.9
    """Cruising speed (m/s); set from `RoadConfig.speed_limit` by `make_policy(scenario=...)`."""
    ego_length: float = 4.5
    """Ego length (m), needed to turn the observed front/rear distances into centre coordinates."""
    ego_width: float = 1.8
    """Ego width (m)."""
    lane_width: float = 3.5
    """Lane width (m); vehicles with |dy| below half of it are in the ego's lane."""
    half_right: float = -1.75
    """Lateral offset (m, ego frame, negative = right) of the outer edge of the ego's half of the road."""
    half_left: float = 1.75
    """Lateral offset (m) of the inner edge of the ego's half of the road (centre line on two-way roads)."""
    stop_line_offset: float = 3.0
    """Distance (m) from the stop line to the crossing's near edge (`CrosswalkConfig.stop_line_offset`)."""
    road_right: float = -1.75
    """Lateral offset (m, ego frame) of the right-hand (south) kerb."""
    road_left: float = 5.25
    """Lateral offset (m, ego frame) of the left-hand (north) kerb."""
    cruise_gain: float = 0.8
    """Proportional gain (1/s) of the speed controller towards the cruising speed."""
    cruise_acceleration: float = 2.0
    """Largest acceleration (m/s²) used when speeding up to the cruising speed."""
    idm_time_headway: float = 1.2
    """IDM desired time headway T (s) to a vehicle ahead in the ego's lane."""
    idm_min_gap: float = 2.5
    """IDM jam distance s0 (m)."""
    idm_comfortable_deceleration: float = 2.5
    """IDM comfortable deceleration b (m/s²)."""
    pedestrian_radius: float = 0.3
    """Assumed pedestrian body radius (m); the observation carries centres only."""


@dataclass(frozen=True)
class ConstantSpeedConfig(DrivingConfig):
    """Constant speed: the ego holds its initial speed whatever happens (never yields, never brakes)."""


@dataclass(frozen=True)
class YieldingConfig(DrivingConfig):
    """Parameters of `YieldingPolicy` (see its docstring for the decision rules)."""

    comfortable_deceleration: float = 2.5
    """Deceleration (m/s²) of a planned stop; the car brakes as late as this allows (−2…−3 m/s² is
    comfortable)."""
    yield_max_deceleration: float = 4.0
    """A legal yield (zebra, red light) is attempted only if stopping before the line needs at most this
    (m/s²); beyond it the car cannot stop in time and only the conflict check below applies."""
    stop_buffer: float = 0.5
    """Stop this far (m) before the stop line."""
    pedestrian_gap: float = 2.0
    """When stopping for a pedestrian away from the stop line, keep this gap (m) to its body."""
    lateral_margin: float = 0.6
    """Margin (m) added to half the ego's width and the pedestrian radius to form the ego's lane corridor."""
    time_buffer: float = 1.5
    """A conflict exists if the pedestrian's time in the corridor and the ego's passage overlap within this
    margin (s)."""
    horizon: float = 6.0
    """Only pedestrians entering the corridor within this time (s) are considered."""
    go_acceleration: float = 1.5
    """Acceleration (m/s²) assumed when asking "if I go now, when do I pass?" from a low speed."""
    kerb_margin: float = 1.5
    """A waiting pedestrian is yielded to if it stands within the crossing's extent ± this margin (m)."""
    kerb_distance: float = 2.0
    """A slow pedestrian on the sidewalk this close (m) to a kerb at the crossing counts as waiting, even
    when the observation's stricter `waiting` flag (1.2 m, 0.3 m/s) is off: people waiting shuffle about."""
    leaving_speed: float = 0.5
    """A pedestrian on the sidewalk within `kerb_distance` of a kerb at the crossing counts as waiting unless
    walking away from the road faster than this (m/s): standing, shuffling, stepping towards the road or
    walking along the kerb all count. With no prediction the car cannot tell someone about to cross from
    someone passing by, so it is ready to give way to both (UK rule 195: "be ready to slow down or stop");
    the ground truth showed pedestrians in the waiting state who move at 1 m/s (shuffling, walking the
    last metre to the zebra), which a speed test missed."""
    intention_threshold: float = 0.5
    """With `crossing_intention` in the observation, a pedestrian off the road with at least this
    probability is treated as about to cross: at the crossing it is yielded to like a waiting one, elsewhere
    it is assumed to step towards the ego's lane at `assumed_walking_speed` in the conflict check. Waiting
    pedestrians are yielded to whatever the estimate (the legal duty does not depend on it)."""
    assumed_walking_speed: float = 1.4
    """Speed (m/s) at which a pedestrian predicted to cross is assumed to walk into the road."""
    use_predictions: bool = True
    """Use `crossing_intention` / `predicted_paths` when the observation has them."""
    stop_gain: float = 2.0
    """Gain (1/s) pulling the speed down onto the braking profile sqrt(2·b·s)."""
    occlusion_speed: float = 3.0
    """Speed (m/s) at which the car passes a stationary vehicle standing beside it near a crossing, which
    may hide a pedestrian (UK Highway Code rule 191: do not overtake a vehicle stopped at a crossing;
    StVO §26: approach at moderate speed). At 3 m/s the car stops within about a metre."""
    offer_timeout: float = 3.5
    """After standing still at the line this long (s) for pedestrians who keep waiting at the kerb, the car
    takes the offer as declined and goes (pedestrians on the crossing are still given way); half a second
    more than `MetricsConfig.offer_timeout` (3 s), so the car never leaves before an offer counts as made."""
    dt: float = 0.1
    """Time between calls (s), the env's `EnvConfig.dt`; used by the offer timer and the track memory."""
    decline_match_radius: float = 0.5
    """After an offer times out, the pedestrians then waiting are remembered by position (tracked step to
    step within this radius, m); only they count as having declined. Someone who arrives at the kerb later
    gets an offer of their own, as the law gives them one."""
    still_speed: float = 0.5
    """A waiting pedestrian's offer timer runs only while they stand (below this speed, m/s): someone still
    walking up to the kerb has not declined anything yet."""
    remember_tracks: bool = True
    """With ``pedestrian_tracks`` in the observation, remember each track (per batch element): someone who
    has crossed, or who keeps walking along the kerb away from the crossing, is not waiting to cross."""
    returning_speed: float = 0.3
    """A pedestrian remembered as having crossed (seen on the road, now off it on the other side than where
    first seen) counts as waiting again only while stepping towards the road faster than this (m/s)."""
    along_kerb_speed: float = 0.8
    """Speed (m/s) along the road, away from the crossing's centre, above which a pedestrian by the kerb
    walks away along it; after `along_kerb_time` of that (same track) it is not waiting to cross."""
    along_kerb_time: float = 0.5
    """How long (s) a track must keep walking away along the kerb before it is released: someone waiting
    who shuffles a step sideways is not."""
    track_forget: float = 3.0
    """A remembered track not seen for this long (s) is forgotten (a tracker re-issues ids after an
    occlusion anyway; `ObservationConfig.track_memory`)."""
    no_overtaking_zone: float = 30.0
    """At a zebra, a moving vehicle in an adjacent lane of the ego's direction whose front is within this
    distance (m) before the crossing (or on it) is not overtaken: the ego follows it (IDM, at most
    comfortable braking). UK Highway Code rule 191: do not overtake the moving vehicle nearest the
    crossing; it may be slowing for a pedestrian it hides. A stopped one is passed at `occlusion_speed`."""
    moving_speed: float = 0.5
    """Speed (m/s) above which an adjacent-lane vehicle counts as moving for `no_overtaking_zone`."""
    occlusion_window: float = 15.0
    """A stationary vehicle counts as an occluder if its front is within this distance (m) before the
    crossing's near edge (or on the crossing)."""


@dataclass(frozen=True)
class PredictiveYieldingConfig(YieldingConfig):
    """Parameters of `PredictiveYielding` (the yielding rules plus release by prediction)."""

    release_threshold: float = 0.2
    """A pedestrian off the road whose ``crossing_intent`` (the intent to cross at all) is at most this is
    confidently not crossing: not yielded to as waiting, unless stepping towards the road or on it. The
    near-term ``crossing_intention`` never releases: it is low for a pedestrian who waits *because* the car
    comes, to whom the car owes the way."""
    stepping_speed: float = 0.3
    """Speed (m/s) towards the road, near the kerb, at which a pedestrian visibly steps out (legal duty
    whatever the prediction)."""
    anticipation_kerb_distance: float = 1.0
    """A pedestrian predicted to cross (``crossing_intention`` ≥ `intention_threshold`) is treated as waiting
    and anticipated to walk in only this close (m) to the kerb: standing at it, not walking up the
    sidewalk (whose walking line is 1.65 m from the kerb)."""
    constant_velocity_guard: float = 2.0
    """Predicted paths replace constant velocity in the conflict check, except that a pedestrian whom
    constant velocity puts in the ego's lane corridor within this time (s) still counts: the paths come
    from 0.4 s histories and lag a sudden run."""
    use_plans: bool = True
    """With ``plan_paths`` in the observation (the path oracle's plan-conditioned futures), choose a plan
    each step by scoring the candidates against their own forecasts (`agents.plans`), check conflicts on
    the chosen plan's paths, and cap the acceleration at a keep or slow plan's. The legal rules still hold."""
    plan_weights: RewardConfig = field(default_factory=RewardConfig)
    """Weights of the reward terms that score a plan (progress, collision, near_miss, hard_braking: the
    env's own reward weights by default)."""
    plan_metrics: MetricsConfig = field(default_factory=MetricsConfig)
    """Thresholds of the scored terms: `serious_ttc` (near miss) and `hard_braking_threshold`, the
    evaluation's own by default."""
    plan_deferral: bool = True
    """Charge a plan that only defers a conflict (it neither meets nor passes a pedestrian whom another
    plan meets in the corridor ahead: someone waiting for the car) the mildest cost of meeting that person
    (`agents.plans`); without it the car creeps up to a pedestrian who waits for it to come close."""
    plan_deferred_wait: bool = True
    """Also charge a plan that defers someone the time the ego will still wait, after the horizon, for them
    to walk across its corridor (at the progress weight and the speed limit: the progress that time would
    have bought); without it a slowed car crawls towards a pedestrian who waits for it to stand."""
    plan_arrival: bool = True
    """Under a slowing plan, time the conflict check's arrival at each pedestrian on the plan's braking
    profile (`agents.predictive`); without it the check assumes the car drives on, brakes for people the
    plan's forecast has crossing well ahead of it, a little harder than the plan, and so can keep a
    pedestrian who waits for the car on the kerb (a self-defeating forecast)."""
    plan_switch_margin: float = 0.1
    """Hysteresis: switch to a better plan only if it scores at least this much higher (reward units; 0.1
    = 2 m of progress at the default weights)."""
    plan_min_hold: float = 1.0
    """Hysteresis: keep a plan at least this long (s) before switching to a better one, unless the plan
    held forecasts a collision (then any better plan takes over at once)."""


@dataclass(frozen=True)
class PlannerConfig(PredictiveYieldingConfig):
    """Parameters of `agents.planner.SamplingPlanner` (proposals, forecast hypotheses, scorer).

    The legal-yield rules and their parameters are `PredictiveYielding`'s (inherited): they set the stop
    every proposal must keep. The scorer's weights and anchors are the episode score's (`score`).
    """

    target_fractions: tuple[float, ...] = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)
    """Target speeds of the proposals as shares of the speed limit (PDM-Closed: 20 % to 100 %; 0 adds the
    comfortable stop)."""
    speed_gain: float = 1.0
    """Proportional gain (1/s) with which a proposal tracks its target speed, between
    −`comfortable_deceleration` and `go_acceleration`."""
    emergency_proposal: bool = True
    """Also propose a stop at the ego's full `max_deceleration` (chosen only when no comfortable proposal
    meets the chance constraint: the PDM-Closed emergency brake)."""
    step_off_prior: float = 0.1
    """Probability that a pedestrian at the kerb, not walking away, steps off now, when no predictor says
    otherwise (the conservative prior: anyone at the kerb may step off)."""
    signal_step_off_prior: float = 0.02
    """The same at a signalised crossing that shows the car green, where people at the kerb wait for their
    own signal (a red-light walker still may)."""
    clearance: float = 0.5
    """Room (m) before and behind the car's box that a forecast pedestrian must keep, as they cross its line,
    for a proposal not to count as a collision: forecasts and the car's response are not exact to the
    centimetre (a dev run with the path oracle passed 0.1 s ahead of a running adult, who ran into the car's
    side). Not at the sides (the car passes people standing at the kerb), nor for the step-off hypothesis
    (someone who steps off reacts to the car)."""
    collision_chance: float = 0.05
    """Chance constraint: a proposal whose forecast probability of a collision exceeds this is not taken
    while another meets it (otherwise the least likely to collide is)."""
    switch_margin: float = 0.01
    """Hysteresis: the proposal followed last step is kept unless another scores this much higher (score
    units, [0, 1]) or it no longer meets the chance constraint."""
    score: ScoreConfig = field(default_factory=ScoreConfig)
    """Weights and anchors of the terms scored (progress, TTC, comfort): the episode score's own."""


@dataclass(frozen=True)
class TTCBrakeConfig(DrivingConfig):
    """Parameters of `TTCEmergencyBrake`."""

    ttc_threshold: float = 1.5
    """Full braking when the time to collision with a pedestrian falls below this (s) (serious conflict)."""
    lateral_margin: float = 0.3
    """Margin (m) added to half the ego's width and the pedestrian radius for the collision corridor."""


@dataclass(frozen=True)
class CautiousConfig(YieldingConfig):
    """Parameters of `AlwaysCautious` (it also stops for pedestrians in its path, like `YieldingPolicy`)."""

    crawl_speed: float = 2.0
    """Speed (m/s) at which the car passes every crossing."""
    approach_deceleration: float = 1.5
    """Deceleration (m/s²) with which it slows down to the crawl before the stop line."""
    clear_distance: float = 2.0
    """It keeps the crawl until its rear is this far (m) past the crossing."""


@dataclass(frozen=True)
class HighwayRuleConfig(DrivingConfig):
    """Parameters of `HighwayEnvRule` (highway-env's priority rule transferred to pedestrians)."""

    horizon: float = 2.0
    """Prediction horizon (s) of the collision check (highway-env: 2 s)."""
    step: float = 0.25
    """Time step (s) of the constant-speed prediction."""
    brake_gain: float = 1.0 / 0.6
    """Speed-controller gain (1/s) towards a target speed of 0 when yielding (highway-env: KP_A = 1/0.6)."""
    lateral_margin: float = 0.0
    """Margin (m) added to the footprints in the collision check."""


@dataclass(frozen=True)
class AdversaryConfig(DrivingConfig):
    """Parameters of the adversaries (`agents.adversaries`): lazy or reckless drivers no score may reward."""

    crawl_speed: float = 2.0
    """Speed (m/s) at which `crawl` drives the whole road."""
    far_stop_distance: float = 70.0
    """How far (m) before the stop line `stop_far` stops for good."""
    stop_deceleration: float = 3.0
    """Deceleration (m/s²) with which the stopping adversaries plan their stop."""
    stop_gain: float = 2.0
    """Gain (1/s) pulling the speed down onto the braking profile sqrt(2·b·s)."""
    stop_time: float = 2.0
    """How long (s) `stop_and_go` stands at the stop line before it drives on, whoever is there."""
    dt: float = 0.1
    """Time between calls (s), the env's `EnvConfig.dt` (`stop_and_go`'s timer)."""


@dataclass(frozen=True)
class BrakeLateConfig(TTCBrakeConfig):
    """Parameters of `brake_late`: it holds its speed and brakes fully only below a short TTC."""

    ttc_threshold: float = 1.0
    """Full braking when the time to collision with a pedestrian falls below this (s)."""
