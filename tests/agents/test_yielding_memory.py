"""The yielding policy's track memory: no stop for people who have crossed or walk off along the kerb."""

from __future__ import annotations

import numpy as np
import pytest

from agents import PredictiveYielding, YieldingConfig, YieldingPolicy
from crossing_env.observation import PEDESTRIAN_TRACKS_KEY
from tests.agents.test_policies import K, accel, crossing_centre, make_obs, stack

TO_STOP = 0.5
"""The car stands at the stop line: only the legal rule could hold it there."""


def with_tracks(obs: dict[str, np.ndarray], tracks: list[int]) -> dict[str, np.ndarray]:
    out = dict(obs)
    out[PEDESTRIAN_TRACKS_KEY] = np.zeros(K, dtype=np.float32)
    out[PEDESTRIAN_TRACKS_KEY][: len(tracks)] = tracks
    return out


def crossing_then_leaving(steps_after: int) -> list[dict]:
    """A pedestrian crossing from the far (north) side, then walking along the near kerb, away from it."""
    x0 = crossing_centre(TO_STOP)
    frames = [{"dx": x0, "dy": y, "vy": -1.3, "oc": 1, "road": 1} for y in np.arange(6.0, -1.7, -0.13)]
    frames += [{"dx": x0 + 0.13 * i, "dy": -2.3, "vx": 1.3} for i in range(1, steps_after + 1)]
    return frames


def drive(policy, frames: list[dict], tracks: bool, extra: list[dict] | None = None) -> list[float]:
    """Accelerations of a car standing at the line while `frames` (one pedestrian, track 1) play."""
    out = []
    for ped in frames:
        peds = [ped, *(extra or [])]
        obs = make_obs(0.0, TO_STOP, peds)
        if tracks:
            obs = with_tracks(obs, list(range(1, len(peds) + 1)))
        out.append(float(accel(policy(obs))[0]))
    return out


@pytest.mark.parametrize("cls", [YieldingPolicy, PredictiveYielding])
def test_no_second_stop_for_someone_who_has_crossed_and_walks_along_the_kerb(cls) -> None:
    frames = crossing_then_leaving(steps_after=10)
    remembering = drive(cls(), frames, tracks=True)
    forgetful = drive(cls(), frames, tracks=False)
    on_road = sum(f.get("road", 0) for f in frames)
    assert max(remembering[:on_road]) <= 0.0  # held while the pedestrian is on the crossing
    assert min(remembering[on_road:]) > 0.5  # then goes: the one by the kerb has just crossed
    assert max(forgetful[on_road:]) <= 0.0  # without tracks it cannot tell and waits


def test_still_stops_for_someone_waiting_at_the_kerb() -> None:
    policy = YieldingPolicy()
    waiting = {"dx": crossing_centre(25.0), "dy": -2.6, "w": 1}
    obs = with_tracks(make_obs(12.0, 25.0, [waiting]), [1])
    assert accel(policy(obs))[0] < -2.0
    # ... also right after someone else has crossed there.
    frames = crossing_then_leaving(steps_after=10)
    standing = {"dx": crossing_centre(TO_STOP) - 1.0, "dy": -2.6, "w": 1}
    after = drive(YieldingPolicy(), frames, tracks=True, extra=[standing])
    assert max(after) <= 0.0


def test_a_bystander_walking_off_along_the_kerb_is_released_only_when_it_keeps_walking() -> None:
    x0 = crossing_centre(TO_STOP)
    walking = [{"dx": x0 + 0.2 + 0.13 * i, "dy": -2.3, "vx": 1.3} for i in range(8)]
    assert drive(YieldingPolicy(), walking[:3], tracks=True)[-1] <= 0.0  # 0.3 s: maybe a shuffle
    assert drive(YieldingPolicy(), walking, tracks=True)[-1] > 0.5  # 0.8 s: walking away
    # Walking along the kerb *towards* the crossing may be walking up to it: still yielded to.
    towards = [{"dx": x0 + 2.0 - 0.13 * i, "dy": -2.3, "vx": -1.3} for i in range(8)]
    assert drive(YieldingPolicy(), towards, tracks=True)[-1] <= 0.0


def test_one_who_has_crossed_counts_again_when_stepping_back_towards_the_road() -> None:
    frames = crossing_then_leaving(steps_after=5)
    back = {"dx": frames[-1]["dx"], "dy": -2.3, "vy": 0.6}  # turns and steps towards the road
    assert drive(YieldingPolicy(), [*frames, back], tracks=True)[-1] <= 0.0


def test_memory_is_per_batch_element_and_cleared_at_a_new_episode() -> None:
    policy = YieldingPolicy()
    frames = crossing_then_leaving(steps_after=5)
    # Element 1 approaches another zebra where its track 1 waits at the kerb (never on the road).
    approaching = with_tracks(make_obs(12.0, 25.0, [{"dx": crossing_centre(25.0), "dy": -2.3, "w": 1}]), [1])
    for ped in frames:  # element 0 sees its track 1 cross and walk off
        a = accel(policy(stack([with_tracks(make_obs(0.0, TO_STOP, [ped]), [1]), approaching])))
    assert a[0, 0] > 0.5 and a[1, 0] < -2.0
    # Element 0's episode restarts (the ego is far before the line again; track ids restart at 1): the
    # pedestrian now waiting there as track 1 is someone new.
    a = accel(policy(stack([approaching, approaching])))
    assert a[0, 0] < -2.0 and a[1, 0] < -2.0
    policy.reset()
    assert policy._tracks == []


def test_a_declined_offer_follows_the_track_not_the_position() -> None:
    """Someone who declined and then shuffles further than `decline_match_radius` has still declined."""
    cfg = YieldingConfig(offer_timeout=1.0, dt=0.1)
    x0 = crossing_centre(TO_STOP)
    # Standing (no velocity observed), 0.55 m further along the kerb each step, at the crossing ± 1.5 m.
    spots = [{"dx": x0 - 3.3 + 0.55 * i, "dy": -2.6, "w": 1} for i in range(12)]
    by_track = drive(YieldingPolicy(cfg), spots, tracks=True)
    by_position = drive(YieldingPolicy(cfg), spots, tracks=False)
    assert by_track[0] <= 0.0 and by_track[-1] > 0.5  # declined after the timeout: the car goes
    assert max(by_position) <= 0.0  # by position it looks like a newcomer every step and keeps waiting
