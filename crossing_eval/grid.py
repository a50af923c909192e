"""The paired prediction grid: every intention x predictor combination on the same seeds.

`crossing-eval --grid intention=none,classical,qlb,oracle predictor=none,cvm,s-cgru,oracle` runs each
policy that uses predictors once per combination, each on the same episodes: an episode's seed depends
only on (base seed, scenario, episode index) (`crossing_eval.tasks.episode_seed`), never on the policy or
the predictors, so the rows differ only by what the car was told. Policies that use no predictors run
once, as the row ``none / none``. The table and its paired statistics are `crossing_eval.prediction_value`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents import policy_uses_predictors
from crossing_eval.plugins import degraded_spec
from crossing_eval.tasks import EpisodeRecord, EpisodeTask, make_tasks
from rollout.wrappers import plugin_target

GRID_KEYS = ("intention", "predictor")
"""The axes a grid spec may name."""


@dataclass(frozen=True)
class GridSpec:
    """The combinations to run: the product of the listed intention and predictor wrappers."""

    intentions: tuple[str, ...]
    """Intention wrappers ('none', 'classical', 'qlb', 'oracle'); 'none' is the reference row."""
    predictors: tuple[str, ...]
    """Trajectory predictors ('none', 'cvm', 's-cgru', 'oracle'); 'none' is the reference row."""

    def combinations(self) -> list[tuple[str, str]]:
        """(intention, predictor) pairs in table order."""
        return list(itertools.product(self.intentions, self.predictors))


def parse_grid(
    items: Sequence[str], intention_choices: Sequence[str], predictor_choices: Sequence[str]
) -> GridSpec:
    """`["intention=none,qlb", "predictor=none,cvm"]` → `GridSpec`; raises ValueError naming the bad item.

    An axis left out is ``none`` only; ``none`` is always added (the reference row of the differences).
    Plug-in predictors (``pkg.module:attr``, entry points) are values too.
    """
    values: dict[str, list[str]] = {}
    allowed = {"intention": tuple(intention_choices), "predictor": tuple(predictor_choices)}
    for item in items:
        key, sep, rest = item.partition("=")
        key = key.strip()
        if not sep or key not in GRID_KEYS:
            raise ValueError(f"grid item {item!r}: expected intention=A,B,... or predictor=A,B,...")
        if key in values:
            raise ValueError(f"grid item {item!r}: {key} given twice")
        names = [s.strip() for s in rest.split(",") if s.strip()]
        if not names:
            raise ValueError(f"grid item {item!r}: no values after '='")
        for name in names:
            if name not in allowed[key] and not degraded_spec(name, key) and not plugin_target(name):
                raise ValueError(
                    f"grid item {item!r}: unknown {key} {name!r}; allowed: {', '.join(allowed[key])}"
                )
        values[key] = list(dict.fromkeys(["none", *names]))
    return GridSpec(
        intentions=tuple(values.get("intention", ["none"])),
        predictors=tuple(values.get("predictor", ["none"])),
    )


def make_grid_tasks(
    scenarios: Sequence[str], policies: Sequence[str], episodes: int, base_seed: int, spec: GridSpec
) -> list[EpisodeTask]:
    """All tasks of the grid; every combination of a (scenario, episode) gets the same seed."""
    tasks = []
    for pol in policies:
        combos = spec.combinations() if policy_uses_predictors(pol) else [("none", "none")]
        for intention, predictor in combos:
            tasks += make_tasks(scenarios, [pol], episodes, base_seed, predictor, intention)
    return tasks


def row_key(task: EpisodeTask) -> tuple[str, str, str]:
    """(policy, intention, predictor): one row of the table."""
    return task.policy, task.intention, task.predictor


def group_rows(records: Sequence[EpisodeRecord]) -> dict[tuple[str, str, str], list[EpisodeRecord]]:
    """Records per row, each sorted by (scenario, episode), so that rows line up episode by episode."""
    rows: dict[tuple[str, str, str], list[EpisodeRecord]] = {}
    for rec in records:
        rows.setdefault(row_key(rec.task), []).append(rec)
    for recs in rows.values():
        recs.sort(key=lambda r: (r.task.scenario, r.task.episode))
    return rows


GRID_MARKER = "value_of_prediction.csv"
"""The file that marks a folder as an earlier grid run's output (the staged folder may replace it)."""


def grid_settings(args: Any) -> dict[str, Any]:
    """What determines a grid's numbers (stored beside the table): the command, scenarios, seeds, axes."""
    spec: GridSpec = args.grid
    return {
        "command": "crossing-eval " + " ".join(args.argv) if args.argv else "crossing-eval",
        "scenarios": list(args.scenarios),
        "policies": list(args.policies),
        "episodes": args.episodes,
        "seed": args.seed,
        "intentions": list(spec.intentions),
        "predictors": list(spec.predictors),
    }


def write_grid_outputs(records: Sequence[EpisodeRecord], args: Any, out: Path) -> tuple[str, list[str]]:
    """The value-of-prediction table (markdown, CSV, plot), ``grid_episodes.csv`` and ``provenance.json``.

    Returns the markdown table and the file names.
    """
    import json

    from crossing_common.files import write_text_atomic

    # Imported here: the table needs scipy and matplotlib, which a plain `crossing-eval` does not.
    from crossing_eval.prediction_value import format_markdown, value_table, write_value_outputs
    from crossing_eval.provenance import run_provenance

    table = value_table(group_rows(records), seed=args.seed)
    settings = grid_settings(args)
    files = write_value_outputs(table, settings, out)
    files.append(_write_episodes(records, out))
    prov = run_provenance(args, records)
    write_text_atomic(out / "provenance.json", json.dumps(prov, indent=1, sort_keys=True) + "\n")
    files.append("provenance.json")
    return format_markdown(table, settings), files


def _write_episodes(records: Sequence[EpisodeRecord], out: Path) -> str:
    """``grid_episodes.csv``: one line per episode with its row, seed and main figures."""
    import csv
    import io

    from crossing_common.files import write_text_atomic

    fields = (
        "collision",
        "yield_obligations",
        "yield_compliant",
        "stops",
        "unneeded_stops",
        "passed_crossing",
        "delay",
        "duration",
        "hard_braking_events",
        "min_ttc",
    )
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(("policy", "intention", "predictor", "scenario", "episode", "seed", *fields))
    order = sorted(records, key=lambda r: (*row_key(r.task), r.task.scenario, r.task.episode))
    for r in order:
        t = r.task
        w.writerow(
            (
                t.policy,
                t.intention,
                t.predictor,
                t.scenario,
                t.episode,
                t.seed,
                *(r.result.get(f) for f in fields),
            )
        )
    write_text_atomic(out / "grid_episodes.csv", buf.getvalue())
    return "grid_episodes.csv"
