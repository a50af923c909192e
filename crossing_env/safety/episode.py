"""Safety and efficiency of one episode, accumulated from the world's ground truth, never from observations.

Definitions follow the surrogate safety measures of SUMO's SSM device (Eclipse SUMO documentation,
"Simulation/Output/SSM Device"), with its names and defaults where they exist: time to collision (TTC),
post-encroachment time (PET), deceleration rate to avoid a crash (DRAC), minimum separation, hard braking,
yield compliance at the crossing, ego delay, time to pass, pedestrian waiting time and collisions. Safety
and efficiency are reported together: a car that never moves is "safe".

`EpisodeMetrics` is a per-step accumulator fed with `GroundTruth` snapshots, returning an `EpisodeResult`
(`crossing_env.safety.results`); the geometry is in `crossing_env.safety.geometry`, the ego–vehicle
measures in `crossing_env.safety.following`, the quantities shared with the env's reward in
`crossing_env.safety.step`; aggregation across episodes lives in `crossing_eval.statistics`.
"""

from __future__ import annotations

import math

import numpy as np

from crossing_env.safety.following import vehicle_measures
from crossing_env.safety.geometry import _crossing_drac_scalar, _slabs
from crossing_env.safety.pedestrian_table import PedestrianTable
from crossing_env.safety.results import DEFAULT_METRICS, EpisodeResult, MetricsConfig
from crossing_env.safety.step import StepSafety, min_pedestrian_separation
from crossing_env.safety.stops import UnneededStops
from crossing_env.safety.yielding import (
    YieldTracker,
    ego_in_conflict_area,
    is_hard_braking,
    min_pedestrian_ttc,
)
from crossing_env.types import ConflictArea, ConflictTruth, FloatArray, GroundTruth, PedState
from scenarios.config import ScenarioConfig

__all__ = ["EpisodeMetrics"]

_INF = math.inf
_APPROACHING, _WAITING, _CROSSING = int(PedState.APPROACHING), int(PedState.WAITING), int(PedState.CROSSING)


# ---------------------------------------------------------------------------------------------------------
# Episode accumulator
# ---------------------------------------------------------------------------------------------------------


class EpisodeMetrics:
    """Accumulates safety and efficiency metrics over one episode from `GroundTruth` snapshots.

    Call `update(gt)` after every environment step (cheap, vectorised over pedestrians and vehicles) and
    `result()` at the end. Conventions and simplifications:

    - TTC to pedestrians: exact box–disc TTC (`box_circle_ttc`), not evaluated while the ego is stopped
      (nuPlan). TTC to vehicles: following TTC to vehicles ahead whose footprint overlaps the ego's
      laterally (same lane); vehicles behind the ego and oncoming traffic are not scored.
    - Conflict area (CA) = `GroundTruth.conflict_area` (ego lane × crossing). The ego occupies it when its
      box overlaps the rectangle, a pedestrian when its centre is on the carriageway (`on_road`, so people
      at the kerb do not count) and its disc's bounding square overlaps the rectangle (conservative by at
      most r·(√2 − 1) ≈ 0.12 m at the rectangle's corners; it shares the slab test with the DRAC).
      Entry and exit times have the resolution of one step.
    - PET: at each ego entry, one pedestrian-first PET per pedestrian that left the CA since the ego's
      previous entry; at each pedestrian entry, one ego-first PET if the ego left the CA since that
      pedestrian's previous entry. Entering while the other is inside counts as a simultaneous occupancy.
    - Crossing DRAC: for each pedestrian whose constant-velocity disc (rectangle grown by its radius) will
      occupy the CA before the ego front reaches it and still occupy it then, `crossing_drac` of the ego
      with t_A = the pedestrian's exit time; pedestrians are never asked to brake (ego-first case unscored).
    - Yield compliance (UK Highway Code rule 195, German StVO §26; simplified): only at a zebra, or at a
      signalised crossing while the pedestrian signal is green. A pedestrian creates one obligation per
      episode when, with the ego front farther than v²/(2·`yield_deceleration`) from the stop line, it is
      on the crossing in the ego's half
      (or, with `far_half_counts`, in the other half walking towards it) or waiting at the kerb within
      `kerb_margin` of the crossing. The obligation is violated if the ego footprint is in the CA while it
      is open; it ends compliant when the pedestrian, having entered the ego's half, is outside it again
      (crossed or turned back), or when the ego has stood still within `offer_distance` of the stop line
      (or past it, before the crossing) for `offer_timeout` while the pedestrian kept waiting (declined
      offer); it is dropped (not counted)
      if the pedestrian leaves the kerb without crossing (state neither `WAITING` nor `CROSSING`, centre
      off the road) before entering the ego's half (waived). A declined or waived obligation opens
      again when its pedestrian steps onto the crossing after all (on the zebra, in the ego's half or
      walking towards it as above) while the ego can still stop comfortably before the crossing; the
      declined one stays counted as met, the new one is judged by the same rules. Only pedestrians who
      intend to cross (`GroundTruth.intends_to_cross`) open obligations, as the law's duty is to them.
      Obligations still open at the end are unresolved: they count among the obligations but not as
      met, so compliance = met / (met + violated + unresolved). The German "influenced" test
      (pedestrian forced to slow down) is not applied: it would need the pedestrian's desired speed,
      which the ground truth does not carry.
    - Collisions: counted by kind (pedestrian, vehicle, static) and, apart, those in which the ego was at
      fault (`crossing_env.collision_fault`: nuPlan's rule, decided when the contact began).
    - NCAP outcome (a scenario whose key pedestrian is a test dummy): impact, not tested (never released),
      outrun (the rear cleared the dummy's path less than `outrun_margin` before the dummy, on its fixed
      path at its fixed speed, would reach the car's side) or avoided.
    - Delay: from t = 0 at `EgoConfig.x` until the ego centre passes `conflict_area.x_max + delay_margin`
      (linear interpolation between steps), minus that distance at the speed limit.
    - Speeding: each step's ego speed along the road minus `RoadConfig.speed_limit` (as the reward's
      ``speeding`` term); the largest positive excess and the time (steps × dt) with a positive one.
    - Pedestrian waiting time: first step seen `WAITING` → first step seen `CROSSING`; 0 for pedestrians
      that step off straight from `APPROACHING`.
    """

    def __init__(self, scenario: ScenarioConfig, dt: float, config: MetricsConfig | None = None) -> None:
        """Create an accumulator for one episode of `scenario` stepped every `dt` seconds."""
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"EpisodeMetrics: dt must be a positive finite number of seconds, got {dt!r}")
        self.scenario = scenario
        self.dt = float(dt)
        self.config = config if config is not None else DEFAULT_METRICS
        self.reset()

    def reset(self) -> None:
        """Forget everything (reuse the accumulator for a new episode of the same scenario)."""
        self.step_ttc = _INF
        """Minimum ego–pedestrian TTC of the latest update (inf if none or the ego stands), for plots."""
        self.step_separation = _INF
        """Minimum ego–pedestrian footprint distance of the latest update (inf without pedestrians)."""
        self.step_drac = 0.0
        """Crossing DRAC of the latest update (0 if no pedestrian holds the conflict area first)."""
        self._steps = 0
        self._time = 0.0
        self._start_x = float(self.scenario.ego.x)
        self._last_x = self._start_x
        self._last_front = math.nan
        self._last_rear = math.nan
        self._last_t = 0.0
        # collisions
        self._ped_collisions = 0
        self._veh_collisions = 0
        self._ped_at_fault = 0
        self._veh_at_fault = 0
        self._static_collisions = 0
        # a timed conflict's test dummy (NCAP outcome)
        self._dummy: ConflictTruth | None = None
        self._dummy_impact = math.nan
        """Relative impact speed of the first contact with the test dummy (nan: no contact)."""
        self._path_clear_time = math.nan
        self._ego_y = math.nan
        self._ego_width = math.nan
        self._compliant_collisions = 0
        self._max_impact = math.nan
        self._bg_collisions = 0
        self._bg_legal = 0
        self._bg_max_speed = math.nan
        # TTC / separation / DRAC
        self._min_ttc = _INF
        self._min_ttc_veh = _INF
        self._serious_time = 0.0
        self._encounter_time = 0.0
        self._min_sep = _INF
        self._min_sep_veh = _INF
        self._clearance_time = 0.0
        self._near_miss = 0.0
        self._max_drac_cross = 0.0
        self._max_drac_follow = 0.0
        # PET
        self._ego_in_ca = False
        self._ego_last_entry = -_INF
        self._ego_last_exit = -_INF
        self._pets_ped_first: list[float] = []
        self._pets_ego_first: list[float] = []
        self._simultaneous = 0
        # braking
        self._hard_steps = 0
        self._hard_events = 0
        self._was_hard = False
        self._comfort_steps = 0
        self._max_decel = 0.0
        # speeding
        self._max_over = 0.0
        self._over_time = 0.0
        # efficiency
        self._target_x = math.nan
        self._reach_time = math.nan
        self._trigger_time = math.nan
        self._clear_time = math.nan
        self._waits: list[float] = []
        self._peds = PedestrianTable()
        self._yield = YieldTracker(self.scenario.crossing.kind, self.dt, self.config)
        self._ca: ConflictArea | None = None
        self._ca_arrays: tuple[np.ndarray, np.ndarray] = (np.zeros(2), np.zeros(2))
        self._size: tuple[float, float] = (math.nan, math.nan)
        self._half: np.ndarray | None = None
        self._stops = UnneededStops(self.config, self.scenario.road.road_width)

    # -- per step -------------------------------------------------------------------------------------

    def update(self, gt: GroundTruth) -> None:
        """Add one ground-truth snapshot (call once per environment step, in time order).

        The step's TTC, separation, conflict-area and braking tests and yield obligations are taken from
        `gt.safety` (computed once by the env for its reward) when that was computed with these thresholds
        from the obligations this accumulator holds; otherwise they are computed here, by the same code.
        """
        cfg = self.config
        shared: StepSafety | None = gt.safety
        if shared is not None and not shared.usable_by(self._yield):
            shared = None
        t = float(gt.time)
        if t < self._last_t:
            raise ValueError(f"EpisodeMetrics.update: GroundTruth.time went backwards ({t} < {self._last_t})")
        ca = gt.conflict_area
        ego_p = gt.ego_position
        ego_v = gt.ego_velocity
        ex = float(ego_p[0])
        evx = float(ego_v[0])
        speed = math.hypot(evx, float(ego_v[1]))
        length, width = gt.ego_size
        front, rear = ex + 0.5 * length, ex - 0.5 * length
        self._steps += 1
        if self._steps == 1:
            self._target_x = ca.x_max + cfg.delay_margin
            self._last_front = self._start_x + 0.5 * length
            self._last_rear = self._start_x - 0.5 * length

        # Braking and comfort.
        acc = float(gt.ego_acceleration)
        hard = shared.hard_braking if shared is not None else is_hard_braking(gt, cfg)
        self._hard_steps += hard
        self._hard_events += hard and not self._was_hard
        self._was_hard = hard
        self._comfort_steps += acc <= -cfg.comfort_deceleration
        if -acc > self._max_decel:
            self._max_decel = -acc

        # Speeding (the reward's definition: speed along the road above the limit).
        over = evx - self.scenario.road.speed_limit
        if over > 0.0:
            self._over_time += self.dt
            if over > self._max_over:
                self._max_over = over

        # Efficiency: interpolated crossing times of the delay target, the pass trigger and the clearing.
        t0 = self._last_t
        if math.isnan(self._reach_time) and ex >= self._target_x:
            self._reach_time = _cross_time(t0, t, self._last_x, ex, self._target_x)
        trig = ca.x_min - cfg.pass_trigger_distance
        if math.isnan(self._trigger_time) and front >= trig:
            self._trigger_time = _cross_time(t0, t, self._last_front, front, trig)
        if math.isnan(self._clear_time) and rear >= ca.x_max:
            self._clear_time = _cross_time(t0, t, self._last_rear, rear, ca.x_max)
        dummy = gt.extras.get("conflict")
        if dummy is not None and dummy.dummy:
            self._dummy, self._ego_y, self._ego_width = dummy, float(ego_p[1]), width
            path = dummy.x + dummy.radius
            if math.isnan(self._path_clear_time) and rear >= path:
                self._path_clear_time = _cross_time(t0, t, self._last_rear, rear, path)
        self._last_t, self._last_x, self._last_front, self._last_rear = t, ex, front, rear

        # Ego occupancy of the conflict area.
        ego_in = shared.ego_in_conflict_area if shared is not None else ego_in_conflict_area(gt)
        ego_entered = ego_in and not self._ego_in_ca
        if not ego_in and self._ego_in_ca:
            self._ego_last_exit = t
        prev_ego_entry = self._ego_last_entry
        if ego_entered:
            self._ego_last_entry = t
        self._ego_in_ca = ego_in

        # Collisions.
        for ev in gt.collisions:
            if ev.kind == "pedestrian":
                self._ped_collisions += 1
                if (
                    self._dummy is not None
                    and ev.other_id == self._dummy.pedestrian_id
                    and math.isnan(self._dummy_impact)
                ):
                    # Euro NCAP's relative impact speed: the car's, less the dummy's along the car's heading
                    # (a crossing dummy's longitudinal speed is taken as 0).
                    self._dummy_impact = max(float(ev.car_speed) - self._dummy.along_speed, 0.0)
                self._ped_at_fault += bool(ev.at_fault)
                self._compliant_collisions += bool(ev.compliant)
                if not ev.car_speed <= self._max_impact:  # also replaces the initial nan
                    self._max_impact = float(ev.car_speed)
            elif ev.kind == "static":
                self._static_collisions += 1
            else:
                self._veh_collisions += 1
                self._veh_at_fault += bool(ev.at_fault)
        for ev in gt.extras.get("background_collisions", ()):
            self._bg_collisions += 1
            self._bg_legal += bool(ev.compliant)
            if not ev.relative_speed <= self._bg_max_speed:  # also replaces the initial nan
                self._bg_max_speed = float(ev.relative_speed)

        if self._half is None or self._size != (length, width):
            self._size = (length, width)
            self._half = np.array([0.5 * length, 0.5 * width])
        self.step_ttc, self.step_separation, self.step_drac = _INF, _INF, 0.0
        if gt.vehicle_ids.shape[0]:
            self._update_vehicles(gt, evx, self._half)
        if gt.pedestrian_ids.shape[0]:
            self._update_pedestrians(
                gt, t, ego_in, ego_entered, prev_ego_entry, front, speed, self._half, shared
            )
        self._stops.update(gt, speed, front, rear)
        self._time = t

    def _update_vehicles(self, gt: GroundTruth, evx: float, half: np.ndarray) -> None:
        """Following TTC / DRAC against vehicles ahead in the ego's lane, and box–box separation."""
        min_sep, following = vehicle_measures(gt, evx, half)
        if min_sep < self._min_sep_veh:
            self._min_sep_veh = min_sep
        if following is not None:
            ttc, drac = following
            self._min_ttc_veh = min(self._min_ttc_veh, ttc)
            self._max_drac_follow = max(self._max_drac_follow, drac)

    def _conflict_arrays(self, ca: ConflictArea) -> tuple[np.ndarray, np.ndarray]:
        """Low and high corners of the conflict area as arrays, cached across steps."""
        if ca != self._ca:
            self._ca = ca
            self._ca_arrays = (np.array([ca.x_min, ca.y_min]), np.array([ca.x_max, ca.y_max]))
        return self._ca_arrays

    def _update_pedestrians(
        self,
        gt: GroundTruth,
        t: float,
        ego_in: bool,
        ego_entered: bool,
        prev_ego_entry: float,
        front: float,
        speed: float,
        half: np.ndarray,
        shared: StepSafety | None,
    ) -> None:
        """Per-pedestrian TTC, separation, DRAC, PET, yielding and waiting, vectorised over pedestrians.

        `shared`: the env's quantities for this snapshot, when usable (see `update`).
        """
        cfg = self.config
        dt = self.dt
        ca = gt.conflict_area
        tab = self._peds
        rows = tab.rows(gt.pedestrian_ids)
        pp: FloatArray = gt.pedestrian_positions
        pv: FloatArray = gt.pedestrian_velocities
        rad = gt.pedestrian_radii
        ca_lo, ca_hi = self._conflict_arrays(ca)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            # Separation: signed distance from each disc to the ego box.
            if shared is not None:
                min_sep = shared.min_separation
            else:
                min_sep = min_pedestrian_separation(gt, half)
            self.step_separation = min_sep
            if min_sep < self._min_sep:
                self._min_sep = min_sep
            if min_sep < cfg.clearance:
                self._clearance_time += dt
            if min_sep < cfg.near_miss_distance and speed > 0.0:
                self._update_near_miss(gt, half, speed)
            # TTC: exact box–disc, only while the ego moves.
            if speed > cfg.ttc_min_ego_speed:
                min_ttc = shared.min_ttc if shared is not None else min_pedestrian_ttc(gt, cfg, half)
                self.step_ttc = min_ttc
                if min_ttc < self._min_ttc:
                    self._min_ttc = min_ttc
                if min_ttc < cfg.serious_ttc:
                    self._serious_time += dt
                if min_ttc < cfg.encounter_ttc:
                    self._encounter_time += dt
            # Conflict-area occupancy interval of each disc's bounding square (constant velocity).
            margin = rad[:, None]
            t_in, t_out = _slabs(pp, pv, ca_lo - margin, ca_hi + margin)
            ped_in = (t_in <= 0.0) & (t_out >= 0.0) & gt.on_road
            # Crossing DRAC: pedestrians holding the conflict area when the ego front would reach it.
            d_b = ca.x_min - front
            evx = float(gt.ego_velocity[0])
            if d_b > 0.0 and evx > 0.0:
                t_ego = d_b / evx
                first = (t_in <= t_ego) & (t_out > t_ego)
                if np.count_nonzero(first):
                    # crossing_drac is non-decreasing in t_A, so the latest exit gives the maximum.
                    drac = _crossing_drac_scalar(evx, d_b, float(t_out[first].max()))
                    self.step_drac = drac
                    if drac > self._max_drac_cross:
                        self._max_drac_cross = drac

        was_in = tab.in_ca[rows]
        if ego_entered or np.count_nonzero(ped_in != was_in):
            self._update_pet(t, rows, ped_in, was_in, ego_in, ego_entered, prev_ego_entry)

        # Pedestrian waiting times (only on state changes).
        states = gt.pedestrian_states
        prev = tab.prev_state[rows]
        changed = states != prev
        if np.count_nonzero(changed):
            self._update_waits(t, rows, states, prev, changed)

        if shared is not None:
            self._yield.state = shared.yield_after
        else:
            self._yield.update(gt, ego_in)

    def _update_near_miss(self, gt: GroundTruth, half: np.ndarray, speed: float) -> None:
        """Proximity × speed of the closest pedestrian on the road (`EpisodeResult.near_miss`)."""
        cfg = self.config
        on_road = gt.on_road
        if not np.count_nonzero(on_road):
            return
        sep = min_pedestrian_separation(gt, half, on_road)
        proximity = min(max(1.0 - sep / cfg.near_miss_distance, 0.0), 1.0)
        severity = proximity * min(speed / cfg.near_miss_speed, 1.0)
        if severity > self._near_miss:
            self._near_miss = severity

    def _update_pet(
        self,
        t: float,
        rows: np.ndarray,
        ped_in: np.ndarray,
        was_in: np.ndarray,
        ego_in: bool,
        ego_entered: bool,
        prev_ego_entry: float,
    ) -> None:
        """Record conflict-area entries and exits and the PET pairs they close."""
        tab = self._peds
        tab.last_exit[rows[was_in & ~ped_in]] = t
        # Pedestrian first: the ego enters after pedestrians that left since its previous entry.
        if ego_entered:
            self._simultaneous += int(np.count_nonzero(ped_in))  # pedestrians inside as the ego enters
            last_exit = tab.last_exit[rows]
            pair = ~ped_in & (last_exit > prev_ego_entry)
            if np.count_nonzero(pair):
                self._pets_ped_first.extend((t - last_exit[pair]).tolist())
        # Ego first: a pedestrian enters after the ego left since that pedestrian's previous entry.
        entered = ped_in & ~was_in
        if np.count_nonzero(entered):
            if ego_in and not ego_entered:
                self._simultaneous += int(np.count_nonzero(entered))
            elif not ego_in:
                pair = entered & (tab.last_entry[rows] < self._ego_last_exit)
                self._pets_ego_first.extend([t - self._ego_last_exit] * int(np.count_nonzero(pair)))
            tab.last_entry[rows[entered]] = t
        tab.in_ca[rows] = ped_in

    def _update_waits(
        self, t: float, rows: np.ndarray, states: np.ndarray, prev: np.ndarray, changed: np.ndarray
    ) -> None:
        """Kerb arrival → stepping off, from `PedState` transitions."""
        tab = self._peds
        tab.wait_start[rows[changed & (states == _WAITING)]] = t
        step_off = changed & (states == _CROSSING) & ((prev == _WAITING) | (prev == _APPROACHING))
        if np.count_nonzero(step_off):
            r_off = rows[step_off]
            ws = tab.wait_start[r_off]
            self._waits.extend(np.where(np.isnan(ws), 0.0, t - ws).tolist())
        # Leaving the kerb any other way (stepping off, giving up, vanishing) ends the wait.
        tab.wait_start[rows[changed & (prev == _WAITING)]] = math.nan
        tab.prev_state[rows] = states

    # -- end of episode -------------------------------------------------------------------------------

    def result(self) -> EpisodeResult:
        """Summarise the episode so far (can be called at any time; does not reset)."""
        road = self.scenario.road
        compliant, violations, declined, unresolved = self._yield.counts()
        passed = not math.isnan(self._reach_time)
        delay = math.nan
        if passed:
            free_flow = (self._target_x - self._start_x) / road.speed_limit
            delay = self._reach_time - free_flow
        ttp = math.nan
        if not math.isnan(self._clear_time):
            trigger = 0.0 if math.isnan(self._trigger_time) else self._trigger_time
            ttp = self._clear_time - trigger
        stops = self._stops
        unneeded = stops.unneeded_so_far()
        pets_p = tuple(self._pets_ped_first)
        pets_e = tuple(self._pets_ego_first)
        return EpisodeResult(
            scenario=self.scenario.name,
            duration=self._time,
            steps=self._steps,
            collision=self._ped_collisions + self._veh_collisions + self._static_collisions > 0,
            pedestrian_collisions=self._ped_collisions,
            vehicle_collisions=self._veh_collisions,
            compliant_pedestrian_collisions=self._compliant_collisions,
            noncompliant_pedestrian_collisions=self._ped_collisions - self._compliant_collisions,
            max_impact_speed=self._max_impact,
            background_collisions=self._bg_collisions,
            background_collision_max_speed=self._bg_max_speed,
            background_collisions_legal=self._bg_legal,
            min_ttc=self._min_ttc,
            min_ttc_vehicle=self._min_ttc_veh,
            serious_conflict_time=self._serious_time,
            encounter_time=self._encounter_time,
            min_separation=self._min_sep,
            min_vehicle_separation=self._min_sep_veh,
            clearance_violation_time=self._clearance_time,
            max_drac_crossing=self._max_drac_cross,
            max_drac_following=self._max_drac_follow,
            min_pet_pedestrian_first=min(pets_p, default=_INF),
            min_pet_ego_first=min(pets_e, default=_INF),
            pets_pedestrian_first=pets_p,
            pets_ego_first=pets_e,
            simultaneous_occupancies=self._simultaneous,
            hard_braking_steps=int(self._hard_steps),
            hard_braking_events=int(self._hard_events),
            comfort_violation_steps=int(self._comfort_steps),
            max_deceleration=self._max_decel,
            yield_obligations=compliant + violations + unresolved,
            yield_compliant=compliant,
            yield_violations=violations,
            yield_offers_declined=declined,
            passed_crossing=passed,
            delay=delay,
            time_to_pass=ttp,
            distance_travelled=self._last_x - self._start_x,
            pedestrian_wait_times=tuple(self._waits),
            censored_waits=int(np.count_nonzero(~np.isnan(self._peds.wait_start))),
            stops=stops.stops,
            unneeded_stops=unneeded,
            max_speed_over_limit=self._max_over,
            time_over_speed_limit=self._over_time,
            pedestrian_collisions_at_fault=self._ped_at_fault,
            vehicle_collisions_at_fault=self._veh_at_fault,
            static_collisions=self._static_collisions,
            yield_unresolved=unresolved,
            ncap_outcome=self._ncap_outcome(),
            ncap_impact_speed=self._dummy_impact,
            near_miss=self._near_miss,
            target_time=self._reach_time,
        )

    def _ncap_outcome(self) -> str:
        """'impact', 'outrun', 'not tested', 'avoided' for a test dummy's episode; '' without one."""
        d = self._dummy
        if d is None:
            return ""
        if not math.isnan(self._dummy_impact):
            return "impact"
        if math.isnan(d.released_at):
            return "not tested"
        if d.along_speed > 0.0:  # it walks ahead within the car's width: no car gets past it untouched
            return "avoided"
        # When the dummy's body, on its fixed path at its fixed speed, reaches the car's side of its lane.
        reach_y = self._ego_width / 2 + d.radius
        gap = max(abs(d.start_y - self._ego_y) - reach_y, 0.0)
        reaches = d.released_at + gap / d.speed
        clear = self._path_clear_time
        if not math.isnan(clear) and 0.0 <= reaches - clear < self.config.outrun_margin:
            return "outrun"
        return "avoided"


def _cross_time(t0: float, t1: float, x0: float, x1: float, target: float) -> float:
    """Time at which a coordinate moving linearly from x0 (t0) to x1 (t1) reaches target."""
    if x1 <= x0 or target <= x0:
        return t0 if target <= x0 else t1
    return t0 + (t1 - t0) * (target - x0) / (x1 - x0)
