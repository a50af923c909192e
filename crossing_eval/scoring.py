"""Each episode's score against the reference driver on the same seed, and a group's mean with its interval.

The score (`crossing_env.safety.score`) gates progress on what the careful reference driver
(`REFERENCE_POLICY`) made of the same seed, so a run scores every seed it runs with that driver too:
`reference_tasks` adds the episodes the run lacks (they are reported apart, never as a row of the table).
"""

from __future__ import annotations

from collections.abc import Sequence

from crossing_env.safety import EpisodeResult
from crossing_env.safety.score import REFERENCE_POLICY, episode_score
from crossing_eval.statistics import t_interval
from crossing_eval.tasks import EpisodeRecord, EpisodeTask

__all__ = ["REFERENCE_POLICY", "attach_scores", "mean_interval", "reference_tasks"]


def reference_tasks(tasks: Sequence[EpisodeTask]) -> list[EpisodeTask]:
    """The reference driver's episodes on every (scenario, seed) of `tasks` that `tasks` does not run."""
    have = {(t.scenario, t.seed) for t in tasks if t.policy == REFERENCE_POLICY}
    extra = {
        EpisodeTask(scenario=t.scenario, policy=REFERENCE_POLICY, episode=t.episode, seed=t.seed)
        for t in tasks
        if (t.scenario, t.seed) not in have
    }
    return sorted(extra, key=lambda t: (t.scenario, t.episode))


def attach_scores(records: Sequence[EpisodeRecord], references: Sequence[EpisodeRecord] = ()) -> None:
    """Set each record's `score` (`EpisodeScore.as_dict`) against the reference's episode on its seed.

    Raises:
        ValueError: a record whose seed the reference driver did not run (neither in `records` nor in
            `references`).
    """
    ref = {
        (r.task.scenario, r.task.seed): EpisodeResult.from_dict(r.result)
        for r in (*records, *references)
        if r.task.policy == REFERENCE_POLICY
    }
    for rec in records:
        key = (rec.task.scenario, rec.task.seed)
        if key not in ref:
            raise ValueError(f"no {REFERENCE_POLICY!r} episode on {rec.task.scenario} seed {rec.task.seed}")
        rec.score = episode_score(EpisodeResult.from_dict(rec.result), ref[key]).as_dict()


def mean_interval(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float, float]:
    """Mean and its Student-t interval (`statistics.t_interval`), clipped to a score's [0, 1]."""
    mean, lo, hi = t_interval(values, confidence)
    return mean, max(lo, 0.0), min(hi, 1.0)
