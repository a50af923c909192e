"""Frozen, documented configuration objects for the crossing world and the environment.

Every physical quantity is in SI units (metres, seconds, m/s, m/s²). Variants are made with
`dataclasses.replace`; scenario files (see `scenarios/`) are parsed into `ScenarioConfig`.

Coordinate frame: the road runs along +x from x = 0 to x = `RoadConfig.length`; lanes are stacked
along +y starting at y = 0 (the "south" kerb). Forward lanes (traffic towards +x, the ego's direction)
come first, backward lanes (towards −x) above them. Sidewalks lie beyond both kerbs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from crossing_common.cadence import HISTORY_INTERVAL

CrossingKind = Literal["zebra", "signalised", "none"]
PhaseDistribution = Literal["classical", "uniform", "normal"]
ConflictSide = Literal["near", "far", "either", "ahead"]


@dataclass(frozen=True)
class RoadConfig:
    """Straight urban road with sidewalks on both sides."""

    num_lanes: int = 2
    """Number of traffic lanes, 1–4."""
    two_way: bool = True
    """If true, the upper `num_lanes // 2` lanes carry traffic towards −x; otherwise all lanes go +x."""
    lane_width: float = 3.5
    """Lane width in metres."""
    length: float = 240.0
    """Road length in metres; the episode terminates when the ego passes its end."""
    speed_limit: float = 13.9
    """Speed limit in m/s (13.9 m/s = 50 km/h)."""
    sidewalk_width: float = 3.0
    """Width of each sidewalk in metres."""
    parking_strip: float = 0.0
    """Width (m) of a parking strip between the south kerb and the south sidewalk (0: none). Parked
    vehicles stand in it; pedestrians walk on the sidewalk beyond it and step through it only to cross
    (at the zebra the strip is a kerb build-out: no parking there, as in the zig-zag zone)."""

    @property
    def num_forward_lanes(self) -> int:
        """Lanes carrying traffic towards +x (the ego's direction)."""
        return self.num_lanes - self.num_lanes // 2 if self.two_way else self.num_lanes

    @property
    def road_width(self) -> float:
        """Kerb-to-kerb width in metres."""
        return self.num_lanes * self.lane_width


@dataclass(frozen=True)
class SignalConfig:
    """Fixed-time pedestrian signal at a signalised crossing."""

    pedestrian_green: float = 12.0
    """Duration of the pedestrian green (walk) phase in seconds; cars have red meanwhile."""
    pedestrian_red: float = 25.0
    """Duration of the pedestrian red phase in seconds; cars have green meanwhile."""
    offset: float = 0.0
    """Time into the cycle at t = 0, in seconds (lets scenarios start mid-cycle)."""


@dataclass(frozen=True)
class CrosswalkConfig:
    """The marked crossing placed on the road."""

    kind: CrossingKind = "zebra"
    """'zebra' (pedestrians have priority), 'signalised' (follow the signal) or 'none' (unmarked)."""
    position: float = 120.0
    """x coordinate of the crossing's centre line in metres."""
    width: float = 4.0
    """Width of the crossing along x in metres."""
    stop_line_offset: float = 3.0
    """Distance from the crossing edge to the stop line in metres."""
    signal: SignalConfig = field(default_factory=SignalConfig)
    """Signal timing; used only when `kind == 'signalised'`."""


@dataclass(frozen=True)
class IDMConfig:
    """Intelligent Driver Model parameters (Treiber et al. 2000) for background cars."""

    max_acceleration: float = 1.5
    """Maximum acceleration a in m/s²."""
    comfortable_deceleration: float = 2.0
    """Comfortable deceleration b in m/s²."""
    max_deceleration: float = 8.0
    """Physical braking limit in m/s²; IDM's output is clipped to it."""
    time_headway: float = 1.5
    """Desired time headway T in seconds."""
    min_gap: float = 2.0
    """Jam distance s0 in metres."""
    delta: float = 4.0
    """Acceleration exponent."""


@dataclass(frozen=True)
class VehicleSpawn:
    """One background vehicle placed at the start of an episode."""

    lane: int
    """Lane index (0 = southmost forward lane)."""
    x: float
    """Longitudinal position of the vehicle centre in metres."""
    speed: float
    """Initial speed in m/s."""
    desired_speed: float | None = None
    """IDM desired speed in m/s; None means the road's speed limit."""
    yields: bool | None = None
    """Whether the driver yields to pedestrians at the crossing; None draws from `yield_probability`."""
    parked: bool = False
    """A parked vehicle never moves (an occluder at the kerb)."""


@dataclass(frozen=True)
class TrafficConfig:
    """Background traffic: explicit spawns plus random arrivals at the road ends."""

    spawns: tuple[VehicleSpawn, ...] = ()
    """Vehicles present at t = 0."""
    flow_per_lane: float = 300.0
    """Arrival rate per moving lane in vehicles per hour (Poisson); 0 disables arrivals."""
    desired_speed_std: float = 1.0
    """Standard deviation of drivers' desired speed around the speed limit, m/s."""
    yield_probability: float = 0.5
    """Probability that a background driver yields to pedestrians at a zebra (literature: 16–75%)."""
    offer_timeout: float = 3.0
    """Seconds a yielding driver stands at the stop line for pedestrians who keep waiting before it takes the
    offer as declined and drives on (as the ego's `yielding` policy and `MetricsConfig.offer_timeout` do);
    someone who starts waiting later gets a new offer."""
    max_vehicles: int = 16
    """Capacity of the vehicle pool, ego excluded."""
    idm: IDMConfig = field(default_factory=IDMConfig)
    """Car-following parameters."""
    length: float = 4.5
    """Vehicle length in metres."""
    width: float = 1.8
    """Vehicle width in metres."""


@dataclass(frozen=True)
class EgoConfig:
    """The controlled car."""

    lane: int = 0
    """Lane index of the ego (a forward lane)."""
    x: float = 30.0
    """Initial position of the ego centre in metres."""
    speed: float = 11.0
    """Initial speed in m/s."""
    max_acceleration: float = 3.0
    """Upper bound of the action in m/s²."""
    max_deceleration: float = 8.0
    """Magnitude of the lower bound of the action in m/s² (emergency braking on dry asphalt)."""
    max_speed: float = 20.0
    """Speed cap in m/s."""


@dataclass(frozen=True)
class PedestrianSpawn:
    """One explicitly placed pedestrian."""

    x: float
    """Start x in metres."""
    side: Literal["south", "north"] = "south"
    """Sidewalk the pedestrian starts on."""
    time: float = 0.0
    """Spawn time in seconds."""
    crosses: bool = True
    """Whether the pedestrian intends to cross."""
    crossing_x: float | None = None
    """Where the pedestrian wants to cross; None means the crossing (or the start x if there is none)."""
    desired_speed: float | None = None
    """Desired walking speed in m/s; None draws from the population distribution."""
    group: int = -1
    """Group id (members walk and decide together); −1 for none."""
    phase: float | None = None
    """Rationality phase θ in radians (π/2 = classical); None draws from the population distribution."""
    distracted: bool | None = None
    """Force distraction on or off; None draws from `BehaviourConfig.distraction_rate`."""
    runs: bool | None = None
    """Force a run across the road on or off (children running out); None draws from `running_rate`."""
    radius: float | None = None
    """Body radius in metres (children ≈ 0.2); None uses the population radius."""
    critical_gap: float | None = None
    """Critical gap in seconds; None draws from the population distribution (0 = does not look)."""


@dataclass(frozen=True)
class BehaviourConfig:
    """Bounded-rational crossing behaviour: decision model and irrational acts (rates per pedestrian)."""

    decision_model: Literal["gap", "qlb"] = "gap"
    """'gap': classical gap acceptance; 'qlb': gap acceptance bent by quantum-like interference."""
    phase_distribution: PhaseDistribution = "normal"
    """How each pedestrian's rationality phase θ is drawn ('classical' gives θ = π/2 for everyone)."""
    phase_mean: float = 1.5707963267948966
    """Mean of θ in radians for 'normal'; π/2 gives cos θ = 0, the classical pedestrian."""
    phase_std: float = 0.4
    """Standard deviation of θ for 'normal'; half-width for 'uniform'."""
    critical_gap_mean: float = 5.5
    """Mean critical gap in seconds (calibration: lognormal, mean 5.5 s, SD 1.2 s, floor 3 s)."""
    critical_gap_std: float = 1.2
    """Standard deviation of the critical gap in seconds."""
    critical_gap_floor: float = 3.0
    """Hard floor of the critical gap in seconds."""
    distraction_rate: float = 0.05
    """Fraction of pedestrians on the phone: slower, longer reaction, shorter gap check."""
    running_rate: float = 0.03
    """Probability per crossing of a sudden run (speed × 2)."""
    hesitation_rate: float = 0.03
    """Probability per crossing of stopping mid-crossing for a moment."""
    turn_back_rate: float = 0.01
    """Probability per crossing of turning back to the start kerb."""
    jaywalk_rate: float = 0.05
    """Fraction of crossing pedestrians who cross away from the zebra."""
    red_light_rate: float = 0.08
    """Probability that a pedestrian facing a red signal crosses anyway when the gap allows."""
    update_force_intensity: bool = False
    """Use the QLB-updated ped–ped intensities (seed Case 2) for pedestrians who see others misbehave."""


@dataclass(frozen=True)
class SocialForceConfig:
    """Helbing & Molnár (1995) social force model parameters."""

    relaxation_time: float = 0.5
    """Time τ in seconds over which a pedestrian adapts to its desired velocity."""
    ped_intensity: float = 0.42
    """Intensity of pedestrian–pedestrian repulsion (seed paper calibration)."""
    vehicle_intensity: float = 0.71
    """Intensity of vehicle–pedestrian repulsion (seed paper calibration)."""
    base_strength: float = 25.0
    """Strength at contact for intensity 1 (m/s²): intensity × base × exp((R − d)/B); 2000 N / 80 kg."""
    ped_range: float = 0.3
    """Range B of pedestrian repulsion in metres."""
    vehicle_range: float = 0.5
    """Range B of vehicle repulsion in metres."""
    kerb_strength: float = 5.0
    """Repulsion of non-crossing pedestrians from the kerb edge, m/s² at the edge."""
    kerb_range: float = 0.2
    """Range of the kerb repulsion in metres."""
    anisotropy: float = 0.5
    """Weight λ of interactions behind the pedestrian (1 = isotropic)."""
    max_speed_factor: float = 1.3
    """Speed cap as a multiple of the desired speed."""


@dataclass(frozen=True)
class WaitingPlace:
    """A place by the kerb where bystanders stand without crossing: a bus stop, a shop front, a corner."""

    x: float
    """Centre of the place along the road (m)."""
    side: Literal["south", "north"] = "south"
    """Sidewalk the place is on."""
    kind: Literal["bus_stop", "shop_front", "corner"] = "bus_stop"
    """What the place is (for logs and replay; the behaviour is the same: stand, then walk on)."""
    spread: float = 4.0
    """Length (m) along the kerb over which the people there stand."""
    kerb_distance: float = 0.8
    """Distance (m) from the kerb line at which they stand (a shop front: near the building line)."""
    initial: int = 0
    """People standing there at t = 0 (a corner's talking group: one group of this size)."""
    weight: float = 1.0
    """Relative share of the random waiting arrivals that come to this place."""


@dataclass(frozen=True)
class BystanderConfig:
    """Pedestrians near the crossing who do not intend to cross, besides those walking past.

    Walking past is `PedestrianConfig.cross_fraction`'s complement; this table adds people who stand at
    waiting places by the kerb, which look like pedestrians waiting to cross to a car's sensors.
    """

    places: tuple[WaitingPlace, ...] = ()
    """Bus stops, shop fronts and corners near the crossing."""
    arrival_rate: float = 0.0
    """Random arrivals per minute at the waiting places (they step off a bus or out of a shop there)."""
    dwell_mean: float = 60.0
    """Mean time (s) a bystander stands at its place before walking on (exponential)."""


@dataclass(frozen=True)
class ConflictConfig:
    """A key pedestrian timed to the ego's arrival, as in Euro NCAP's AEB pedestrian tests (CPNA, CPFA, CPNC).

    Per episode the env draws, from its seeded generator, one value from each range (`[lo, hi]`, uniform;
    `lo == hi` fixes it). The pedestrian stands on the sidewalk at the conflict point (hidden behind the
    occluder if there is one) and steps off when the ego's time to arrive there, at its current speed, falls
    to the drawn `time_to_arrival`. Its start is set back from the ego's path so that, walking at the drawn
    speed, it would meet the ego's front at `impact_offset` of the car's width if the car held its speed: a
    car that never brakes hits it. The set-back is limited to the walkway; where the walkway is too narrow
    (or too wide) for the drawn time, the time becomes what the walkway allows, the collision course being
    kept. A car that stands still within 60 m of the point for 1 s also releases the pedestrian (someone
    given the way takes it).
    """

    side: ConflictSide = "near"
    """Sidewalk the pedestrian steps off from: 'near' (the ego's kerb, south), 'far' (across the road) or
    'either' (drawn per episode, even odds); or 'ahead': it stands in the ego's lane at the conflict point
    (its centre at `impact_offset` of the car's width) and, released, walks the ego's way along the lane
    (Euro NCAP CPLA; a test dummy only)."""
    x_offset: tuple[float, ...] = (0.0, 0.0)
    """Range of the conflict point along the road relative to `crossing.position` (m; + is further on)."""
    ego_speed: tuple[float, ...] = (8.3, 13.9)
    """Range of the ego's initial speed (m/s; replaces `ego.speed`), 30-50 km/h by default."""
    ego_speed_grid: tuple[float, ...] = ()
    """Test speeds (m/s): when given, each episode draws one of them, with equal odds, instead of a speed
    from `ego_speed` (Euro NCAP tests on a grid, 10-60 km/h in 10 km/h steps)."""
    pedestrian_speed: tuple[float, ...] = (1.1, 1.7)
    """Range of the pedestrian's walking speed (m/s; Euro NCAP: 1.39 walking, 2.22 running)."""
    impact_offset: tuple[float, ...] = (0.25, 0.75)
    """Range of the impact point as a fraction of the ego's width, 0 = its right (south) edge, 1 its left."""
    time_to_arrival: tuple[float, ...] = (2.0, 3.5)
    """Range of the ego's time to arrive at the conflict point when the pedestrian steps off (s)."""
    occluder_gap: tuple[float, ...] = ()
    """Range of the gap (m) between the pedestrian's path and the front of the first parked vehicle in
    `traffic.spawns`, which is moved there (Euro NCAP CPNCO: 1 m); empty: the spawn stays where it is."""
    distracted: bool = False
    """The pedestrian looks at a phone (walks 20 % slower than drawn, as distracted pedestrians do)."""
    radius: float | None = None
    """Body radius (m; a child about 0.2); None uses the population radius."""
    dummy: bool = False
    """The key pedestrian is a test dummy, as on a Euro NCAP track: it stands still until released, then
    moves along its crossing line at the drawn speed from the first step and reacts to nothing (no social
    force from cars or people, no detour). False: it walks by social force like everyone else."""


@dataclass(frozen=True)
class PedestrianConfig:
    """Pedestrian population: spawns, speeds, body size and behaviour."""

    spawns: tuple[PedestrianSpawn, ...] = ()
    """Explicitly placed pedestrians."""
    spawn_rate: float = 6.0
    """Random arrivals per minute (both sidewalks together); 0 disables them."""
    cross_fraction: float = 0.7
    """Fraction of random arrivals who intend to cross (the rest walk along the sidewalk)."""
    group_probability: float = 0.1
    """Probability that a random arrival brings a companion (a group of two)."""
    spawn_extent: float = 30.0
    """Random arrivals start within this distance (m) of the crossing along the sidewalk."""
    desired_speed_mean: float = 1.35
    """Mean desired walking speed in m/s (calibration: N(1.35, 0.2²) truncated to [0.9, 1.9])."""
    desired_speed_std: float = 0.2
    """Standard deviation of the desired speed in m/s."""
    desired_speed_min: float = 0.9
    """Lower truncation of the desired speed in m/s."""
    desired_speed_max: float = 1.9
    """Upper truncation of the desired speed in m/s."""
    radius: float = 0.28
    """Body radius in metres."""
    max_pedestrians: int = 32
    """Capacity of the pedestrian pool."""
    behaviour: BehaviourConfig = field(default_factory=BehaviourConfig)
    """Crossing decisions and irrational acts."""
    bystanders: BystanderConfig = field(default_factory=BystanderConfig)
    """People standing by the kerb who do not cross (bus stops, shop fronts, corners)."""
    social_force: SocialForceConfig = field(default_factory=SocialForceConfig)
    """Walking dynamics."""


@dataclass(frozen=True)
class ScenarioConfig:
    """Everything that describes a situation, independent of the seed."""

    name: str = "default"
    """Short identifier."""
    description: str = "Two-lane two-way road with a zebra crossing and moderate traffic."
    """One-line description shown by `crossing_env.scenarios()`."""
    road: RoadConfig = field(default_factory=RoadConfig)
    """Road geometry."""
    crossing: CrosswalkConfig = field(default_factory=CrosswalkConfig)
    """Crossing geometry and control."""
    ego: EgoConfig = field(default_factory=EgoConfig)
    """The controlled car."""
    traffic: TrafficConfig = field(default_factory=TrafficConfig)
    """Background vehicles."""
    pedestrians: PedestrianConfig = field(default_factory=PedestrianConfig)
    """Pedestrians."""
    duration: float = 40.0
    """Episode time limit in seconds."""
    night: bool = False
    """Night-time: the ego sees pedestrians at half the perception range, and pedestrians walk 10% slower."""
    conflict: ConflictConfig | None = None
    """A key pedestrian timed to the ego's arrival (`[conflict]`); None: no timed conflict."""


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the named reward terms reported in `info['rewards']` (their sum is the step's reward).

    The terms use the ground-truth definitions of `crossing_env.safety` (the same code as `crossing-eval`'s
    metrics): yield obligations, TTC and hard braking are not re-implemented for the reward.
    """

    progress: float = 0.05
    """Reward per metre travelled along the road."""
    time: float = -0.2
    """Reward per second of simulated time (a cost of time: waiting longer than needed loses return)."""
    collision: float = -100.0
    """Reward on any ego collision (terminates the episode)."""
    failing_to_yield: float = -10.0
    """Reward per yield obligation violated in the step (`crossing-eval`'s yield-compliance rule: the ego
    enters the conflict area while a pedestrian on the crossing or waiting at the kerb has right of way)."""
    near_miss: float = -1.0
    """Reward per second in which the ego–pedestrian TTC is below `MetricsConfig.serious_ttc` (1.5 s)."""
    hard_braking: float = -0.02
    """Reward per step with deceleration beyond `MetricsConfig.hard_braking_threshold` (3 m/s²)."""
    speeding: float = -0.1
    """Reward per step per m/s above the speed limit (progress alone would reward driving ever faster)."""


@dataclass(frozen=True)
class ObservationConfig:
    """Size and content of the fixed-size observation."""

    max_pedestrians: int = 16
    """Number of pedestrian slots K (padded, sorted by relevance)."""
    max_vehicles: int = 8
    """Number of vehicle slots M (padded, sorted by distance)."""
    perception_range: float = 80.0
    """Objects farther than this from the ego are not observed, metres."""
    history_length: int = 8
    """Number of 0.4 s history samples per pedestrian slot (trajectory predictors need 8)."""
    track_memory: float = 1.0
    """Longest occlusion (s, from the last observation to the next) through which a pedestrian keeps its
    track id (``pedestrian_tracks``); after a longer one it gets a new id, as a tracker that coasts a lost
    track this long would issue: identity never leaks through a long occlusion."""

    def __post_init__(self) -> None:
        for name in ("max_pedestrians", "max_vehicles", "history_length"):
            if not isinstance(getattr(self, name), int) or getattr(self, name) < 1:
                raise ValueError(
                    f"ObservationConfig.{name} must be an integer >= 1, got {getattr(self, name)!r}"
                )
        if not self.perception_range > 0:
            raise ValueError(f"ObservationConfig.perception_range must be > 0, got {self.perception_range!r}")
        if not (isinstance(self.track_memory, int | float) and 0.0 <= self.track_memory < math.inf):
            raise ValueError(
                f"ObservationConfig.track_memory must be a finite number >= 0 (s), got {self.track_memory!r}"
            )


@dataclass(frozen=True)
class EnvConfig:
    """Environment-level settings (the scenario describes the world)."""

    dt: float = 0.1
    """Policy step in seconds; must divide the 0.4 s history cadence."""
    max_substep_displacement: float = 0.5
    """Physics substeps are chosen so no body moves further than this per substep (no tunnelling)."""
    reward: RewardConfig = field(default_factory=RewardConfig)
    """Reward weights."""
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    """Observation layout."""
    render_size: tuple[int, int] = (800, 300)
    """Width and height of rendered frames in pixels."""
    render_extent: float = 80.0
    """Metres of road shown across the rendered frame, centred on the ego."""

    def __post_init__(self) -> None:
        steps = HISTORY_INTERVAL / self.dt if self.dt > 0 else 0.0
        if not (self.dt > 0 and abs(steps - round(steps)) < 1e-9):
            raise ValueError(
                f"EnvConfig.dt must be > 0 and divide {HISTORY_INTERVAL} s (e.g. 0.05, 0.1, 0.2),"
                f" got {self.dt!r}"
            )
        if not self.max_substep_displacement > 0:
            raise ValueError(
                f"EnvConfig.max_substep_displacement must be > 0, got {self.max_substep_displacement!r}"
            )
        if len(self.render_size) != 2 or min(self.render_size) < 16 or not self.render_extent > 0:
            raise ValueError(
                f"EnvConfig.render_size/render_extent invalid: {self.render_size!r}, {self.render_extent!r}"
            )
