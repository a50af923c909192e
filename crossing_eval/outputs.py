"""The files of a run, each written atomically into the output folder.

- ``results.json``: the settings, a summary per policy and per (scenario, policy) plus the world-health
  figures, and every episode's metrics (`crossing_env.safety.EpisodeResult.as_dict`);
- ``episodes.csv`` (one row per episode), ``summary.csv`` (one row per policy; no row pools policies) and
  ``per_scenario.csv`` (one row per scenario and policy); missing or undefined values are empty cells;
- ``ncap.csv`` (runs with an ``ncap_*`` scenario: one row per scenario, policy and test speed, with the
  outcomes, Euro NCAP colours, points and NeuroNCAP score of `crossing_eval.ncap`);
- ``report.md`` (per-policy and per-scenario tables and the column definitions, `crossing_eval.report`),
  ``table.txt`` (the headline table `crossing-eval` prints) and ``table_full.txt`` (every column);
- ``safety_vs_efficiency.png`` (a legend instead of point labels, so no label overlaps another; policies
  at the same point are drawn side by side) and ``min_ttc.png`` (ECDF per policy; each curve has its own
  dash pattern and marker, wider curves under narrower ones, and the legend names identical curves);
  matplotlib, Agg backend;
- ``worst/*.json``: episode logs of the worst episodes (collisions first, then lowest min TTC; the five
  worst overall plus the worst of every other policy) that ``crossing-replay episode`` re-runs.

Records arrive sorted by (scenario, policy, episode) and the JSON holds no timing or worker information,
so the files are identical whatever ``--workers`` or ``--backend``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import multiprocessing
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from crossing_common.files import write_bytes_atomic
from crossing_common.processes import fork_is_safe
from crossing_env.safety import json_safe
from crossing_eval.ncap import NCAP_CSV_FIELDS, ncap_csv_rows, ncap_markdown, ncap_rows
from crossing_eval.report import csv_cell, per_scenario_rows, report_markdown, scenario_labels
from crossing_eval.summary import HEADLINE_COLUMNS, format_table
from crossing_eval.tasks import EpisodeRecord
from crossing_replay.episode_log import save_episode_log

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

WORST_EPISODES = 5
"""Number of worst episodes overall saved as replayable logs (plus the worst of every other policy)."""

CSV_EPISODE_FIELDS = (
    "scenario",
    "policy",
    "episode",
    "seed",
    "collision",
    "pedestrian_collisions",
    "vehicle_collisions",
    "pedestrian_collisions_at_fault",
    "vehicle_collisions_at_fault",
    "static_collisions",
    "max_impact_speed",
    "background_collisions",
    "background_collisions_legal",
    "background_collision_max_speed",
    "min_ttc",
    "min_separation",
    "min_pet_pedestrian_first",
    "min_pet_ego_first",
    "max_drac_crossing",
    "hard_braking_events",
    "max_deceleration",
    "max_speed_over_limit",
    "time_over_speed_limit",
    "yield_obligations",
    "yield_compliant",
    "yield_violations",
    "yield_unresolved",
    "ncap_outcome",
    "ncap_impact_speed",
    "passed_crossing",
    "delay",
    "time_to_pass",
    "distance_travelled",
    "duration",
    "near_miss",
    "target_time",
    "score",
)
"""Columns of ``episodes.csv``: the task's four, then `EpisodeResult` fields, then the episode's score."""


# ---------------------------------------------------------------------------------------------------------
# JSON and CSV
# ---------------------------------------------------------------------------------------------------------


def _csv_text(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buf.getvalue()


def _episode_entry(r: EpisodeRecord, settings: dict[str, Any]) -> dict[str, Any]:
    """One record as ``results.json`` holds it (``score`` only where the record was scored)."""
    entry = {
        "scenario": r.task.scenario,
        "scenario_name": settings.get("scenario_names", {}).get(r.task.scenario, r.task.scenario),
        "policy": r.task.policy,
        "episode": r.task.episode,
        "seed": r.task.seed,
        "predictors": r.predictors,
        "initial_speed": json_safe(r.initial_speed),
        "metrics": r.result,
    }
    if r.score is not None:
        entry["score"] = json_safe(r.score)
    return entry


def _write_results_json(
    records: Sequence[EpisodeRecord],
    summary: dict[str, Any],
    settings: dict[str, Any],
    out: Path,
    references: Sequence[EpisodeRecord] = (),
) -> None:
    doc = {
        "settings": settings,
        "summary": json_safe(summary),
        "episodes": [_episode_entry(r, settings) for r in records],
        "reference_episodes": [_episode_entry(r, settings) for r in references],
    }
    write_bytes_atomic(
        out / "results.json", (json.dumps(doc, indent=1, sort_keys=True) + "\n").encode("utf-8")
    )


def _write_episodes_csv(records: Sequence[EpisodeRecord], out: Path) -> None:
    rows = [
        [
            r.task.scenario,
            r.task.policy,
            r.task.episode,
            r.task.seed,
            *(csv_cell(r.result[f]) for f in CSV_EPISODE_FIELDS[4:-1]),
            csv_cell(r.score["score"] if r.score is not None else None),
        ]
        for r in records
    ]
    write_bytes_atomic(out / "episodes.csv", _csv_text(CSV_EPISODE_FIELDS, rows).encode("utf-8"))


def _write_summary_csv(summary: dict[str, Any], policies: Sequence[str], out: Path) -> None:
    """One row per policy (no row pools policies); the scalar aggregates plus the collision-rate interval."""
    entries = [(p, summary["per_policy"][p]) for p in policies if p in summary["per_policy"]]
    first = entries[0][1] if entries else {}
    keys = [k for k in first if not isinstance(first[k], tuple | list)]
    rows = []
    for name, agg in entries:
        lo, hi = agg["collision_ci95"]
        rows.append([name, *(csv_cell(agg[k]) for k in keys), csv_cell(lo), csv_cell(hi)])
    header = ["policy", *keys, "collision_ci95_low", "collision_ci95_high"]
    write_bytes_atomic(out / "summary.csv", _csv_text(header, rows).encode("utf-8"))


# ---------------------------------------------------------------------------------------------------------
# Plots
# ---------------------------------------------------------------------------------------------------------


LINE_STYLES: tuple[Any, ...] = ("-", (0, (6, 2)), (0, (1, 1.5)), "-.", (0, (8, 2, 1, 2, 1, 2)), (0, (3, 3)))
"""Dash patterns of the min-TTC curves, one per policy (cycled), so that coinciding curves stay visible."""
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">")
"""Marker per policy (cycled) in both plots."""


def import_plotting() -> Any:
    """The pyplot module on the Agg backend (about 1 s to import: a run does it while its workers run)."""
    # Imported here, not at the top: the Agg backend is selected only when plotting, never as a side
    # effect of importing this module.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _plot(
    records: Sequence[EpisodeRecord], summary: dict[str, Any], policies: Sequence[str], out: Path
) -> None:
    """Safety-vs-efficiency scatter and min-TTC distributions as PNG (written atomically)."""
    plt = import_plotting()

    names = [p for p in policies if p in summary["per_policy"]]
    plots: list[tuple[str, Callable[[Axes], None]]] = [
        ("safety_vs_efficiency.png", lambda ax: _draw_safety_vs_efficiency(ax, summary, names)),
        ("min_ttc.png", lambda ax: _draw_min_ttc(ax, records, names)),
    ]

    def draw_and_save(file_name: str, draw: Callable[[Axes], None]) -> None:
        fig, ax = plt.subplots(figsize=(9.0, 4.8))
        draw(ax)
        fig.tight_layout()
        _save_fig(fig, out / file_name)
        plt.close(fig)

    # Each plot after the first is drawn in a forked child while this process draws the first: drawing
    # (text layout, rasterising) is most of the time after the last episode. Not after torch has been
    # imported (a forked child of a process that ran torch ops can hang) nor where fork is unavailable.
    children = []
    if fork_is_safe():
        fork = multiprocessing.get_context("fork")
        for file_name, draw in plots[1:]:
            child = fork.Process(target=draw_and_save, args=(file_name, draw), name=f"plot {file_name}")
            child.start()
            children.append((file_name, child))
        plots = plots[:1]
    try:
        for file_name, draw in plots:
            draw_and_save(file_name, draw)
    finally:
        for _, child in children:
            child.join()
    for file_name, child in children:
        if child.exitcode != 0:
            raise RuntimeError(f"drawing {file_name} failed (exit status {child.exitcode} of its process)")


def _share(value: float | None) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.2f}"


def dodge_offsets(
    points: Sequence[tuple[float, float]], tolerance: float = 0.02, step: float = 9.0
) -> list[float]:
    """Horizontal offsets (in points) that set apart markers at (nearly) the same place.

    Points closer than `tolerance` of the data range on both axes form a group; a group of k points is
    spread symmetrically, `step` points apart. Single points keep offset 0.
    """
    arr = np.array([(x if math.isfinite(x) else 0.0, y if math.isfinite(y) else 0.0) for x, y in points])
    if arr.size == 0:
        return []
    span = np.maximum(arr.max(axis=0) - arr.min(axis=0), 1e-9)
    group = [-1] * len(points)
    for i in range(len(points)):
        if group[i] < 0:
            group[i] = i
            for j in range(i + 1, len(points)):
                if group[j] < 0 and np.all(np.abs(arr[j] - arr[i]) <= tolerance * span):
                    group[j] = i
    offsets = []
    for i, g in enumerate(group):
        members = [j for j, h in enumerate(group) if h == g]
        offsets.append((members.index(i) - (len(members) - 1) / 2) * step)
    return offsets


def _draw_safety_vs_efficiency(ax: Axes, summary: dict[str, Any], names: Sequence[str]) -> None:
    """One marker per policy: its mean episode score (with its interval) against its delay.

    Safety is the score, not the collision rate alone: its gates zero an at-fault collision or a broken
    yield duty and take a near miss off, its TTC term counts the margin, so a car that never hits anyone
    but ignores its yield duties or passes pedestrians at half a metre does not look safe. The names are
    in the legend, so no label overlaps.
    """
    from matplotlib.transforms import offset_copy

    aggs = [summary["per_policy"][name] for name in names]
    points = [(agg["censored_mean_delay"], agg["score_mean"]) for agg in aggs]
    offsets = dodge_offsets(points)
    colours = plt_colours(len(names))
    for i, (name, agg, (x, score)) in enumerate(zip(names, aggs, points, strict=True)):
        lo, hi = agg["score_ci95"]
        ax.update_datalim([(x, lo), (x, hi)])  # the shifted artists do not enter the autoscaling
        shift = offset_copy(ax.transData, fig=ax.figure, x=offsets[i], y=0.0, units="points")
        ax.errorbar(
            x,
            score,
            yerr=[[score - lo], [hi - score]],
            fmt=MARKERS[i % len(MARKERS)],
            markersize=7,
            capsize=4,
            color=colours[i],
            markeredgecolor="black",
            transform=shift,
            label=f"{name}: score {score:.2f}, compliance {_share(agg['yield_compliance'])}, delay {x:.1f} s",
        )
    ax.set_xlabel("delay at the crossing, non-passing episodes at the duration (s)  → less efficient")
    ax.set_ylabel("episode score (95% CI): 0 = collision or broken yield  → safer, better")
    ax.set_title("Safety (the episode score: collisions, yield duties, margins) vs efficiency per policy")
    ax.grid(alpha=0.3)
    ax.margins(x=0.15, y=0.1)
    ax.autoscale_view()
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)


def _draw_min_ttc(ax: Axes, records: Sequence[EpisodeRecord], names: Sequence[str]) -> None:
    """Empirical CDF of the episode minimum TTC per policy.

    Episodes without a finite TTC never enter the curve, so each curve ends at its finite fraction. The
    curves are drawn widest first, each with its own dash pattern and marker, so a curve identical to an
    earlier one still shows under it; the legend says which curves coincide.
    """
    cap = 10.0
    colours = plt_colours(len(names))
    curves: list[tuple[str, np.ndarray, np.ndarray]] = []
    count = len(names)
    for i, (name, colour) in enumerate(zip(names, colours, strict=True)):
        vals = np.array(
            [
                r.result["min_ttc"]
                for r in records
                if r.task.policy == name and r.result["min_ttc"] is not None
            ],
            dtype=np.float64,
        )
        n = sum(r.task.policy == name for r in records)
        vals = np.sort(vals[np.isfinite(vals)])
        xs = np.concatenate([[0.0], np.minimum(vals, cap), [cap]])
        ys = np.concatenate([[0.0], np.arange(1, vals.size + 1) / max(n, 1), [vals.size / max(n, 1)]])
        same = [other for other, oxs, oys in curves if np.array_equal(oxs, xs) and np.array_equal(oys, ys)]
        label = f"{name} (n={n})" + (f", same curve as {same[0]}" if same else "")
        curves.append((name, xs, ys))
        width = 1.6 + 3.0 * (count - 1 - i) / max(count - 1, 1)
        ax.step(
            xs,
            ys,
            where="post",
            linewidth=width,
            linestyle=LINE_STYLES[i % len(LINE_STYLES)],
            marker=MARKERS[i % len(MARKERS)],
            markersize=4 + 0.8 * width,
            markevery=max(1, xs.size // 8),
            markerfacecolor="none" if same else colour,
            color=colour,
            alpha=0.9,
            zorder=2 + i,
            label=label,
        )
    ax.axvline(1.5, color="black", linestyle=":", linewidth=1.2, label="serious conflict (1.5 s)")
    ax.set_xlim(0.0, cap)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel(f"episode minimum TTC to a pedestrian (s; axis cut at {cap:g})")
    ax.set_ylabel("fraction of episodes with min TTC ≤ x")
    ax.set_title("Minimum TTC per policy (ECDF; 'never' episodes stay off the curve)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)


def plt_colours(n: int) -> list[Any]:
    """`n` distinct colours from matplotlib's qualitative tab10 map (none of them the threshold's black)."""
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    return [cmap(i % 10) for i in range(n)]


def _save_fig(fig: Figure, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    write_bytes_atomic(path, buf.getvalue())


# ---------------------------------------------------------------------------------------------------------
# Worst episodes
# ---------------------------------------------------------------------------------------------------------


def worst_records(records: Sequence[EpisodeRecord], n: int = WORST_EPISODES) -> list[EpisodeRecord]:
    """The `n` worst episodes overall, then the worst of each policy not yet included.

    Ranking: collisions first (highest impact speed first), then the lowest min TTC; ties by key.
    Episodes with neither a collision nor a finite TTC are never "worst".
    """

    def badness(r: EpisodeRecord) -> tuple[int, float, float, tuple[str, str, int]]:
        res = r.result
        impact = res["max_impact_speed"] if res["max_impact_speed"] is not None else 0.0
        ttc = res["min_ttc"] if res["min_ttc"] is not None else math.inf
        return (0 if res["collision"] else 1, -impact, ttc, r.key)

    ranked = [
        r for r in sorted(records, key=badness) if r.result["collision"] or r.result["min_ttc"] is not None
    ]
    chosen = ranked[:n]
    for rec in ranked:
        if all(c.task.policy != rec.task.policy for c in chosen):
            chosen.append(rec)
    return chosen


def file_slug(text: str) -> str:
    """`text` as one safe file-name part: a policy spec's path becomes its stem, odd characters '-'.

    ``sb3:/runs/a/model.zip`` → ``sb3-model``, ``pkg.mod:Policy`` → ``pkg.mod-Policy``; names stay.
    """
    kind, sep, rest = text.partition(":")
    if sep and ("/" in rest or "\\" in rest or rest.endswith(".zip")):
        text = f"{kind}-{Path(rest.replace(chr(92), '/')).stem}"
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip(".-") or "policy"


def save_worst(records: Sequence[EpisodeRecord], out: Path, n: int = WORST_EPISODES) -> list[str]:
    """Write replayable logs of the worst episodes into ``out/worst``; returns the file names."""
    folder = out / "worst"
    names = []
    for rank, rec in enumerate(worst_records(records, n)):
        t = rec.task
        name = f"{rank:02d}_{file_slug(Path(t.scenario).stem)}_{file_slug(t.policy)}_ep{t.episode}.json"
        folder.mkdir(parents=True, exist_ok=True)
        save_episode_log(
            folder / name,
            scenario=t.scenario,
            seed=t.seed,
            actions=np.asarray(rec.actions, dtype=np.float32),
            policy=t.policy,
            # Only the wrappers the episode really ran with, so that the replay rebuilds the same env.
            predictor=t.predictor if f"trajectory:{t.predictor}" in rec.predictors else None,
            intention=t.intention if f"intention:{t.intention}" in rec.predictors else None,
            final_ground_truth=rec.final_ground_truth,
            metadata={
                "rank": rank,
                "episode": t.episode,
                "metrics": rec.result,
                "predictors": rec.predictors,
            },
        )
        names.append(name)
    return names


def write_outputs(
    records: Sequence[EpisodeRecord],
    summary: dict[str, Any],
    settings: dict[str, Any],
    out: Path,
    references: Sequence[EpisodeRecord] = (),
) -> list[str]:
    """JSON, CSVs, report, table, plots and worst-episode logs; every file written atomically.

    `out` is normally the staging folder of `crossing_common.folders.StagedFolder`, swapped in whole by
    the caller. `references`: the reference driver's episodes the run added to score its seeds
    (``results.json`` keeps them apart, so that every score can be recomputed). Returns the file names.
    """
    out.mkdir(parents=True, exist_ok=True)
    policies = settings["policies"]
    labels = settings.get("scenario_names") or scenario_labels(sorted({r.task.scenario for r in records}))
    _write_results_json(records, summary, settings, out, references)
    _write_episodes_csv(records, out)
    _write_summary_csv(summary, policies, out)
    header, rows = per_scenario_rows(summary, labels, policies)
    write_bytes_atomic(out / "per_scenario.csv", _csv_text(header, rows).encode("utf-8"))
    report = report_markdown(summary, policies, labels, settings, extra_sections=ncap_markdown(records))
    ncap = ncap_rows(records)
    if ncap:
        cells = [[csv_cell(v) for v in row] for row in ncap_csv_rows(ncap)]
        write_bytes_atomic(out / "ncap.csv", _csv_text(NCAP_CSV_FIELDS, cells).encode("utf-8"))
    write_bytes_atomic(out / "report.md", report.encode("utf-8"))
    headline = format_table(summary, policies, HEADLINE_COLUMNS)
    write_bytes_atomic(out / "table.txt", (headline + "\n").encode("utf-8"))
    write_bytes_atomic(out / "table_full.txt", (format_table(summary, policies) + "\n").encode("utf-8"))
    _plot(records, summary, policies, out)
    worst = save_worst(records, out)
    return [
        "results.json",
        "report.md",
        "table.txt",
        "table_full.txt",
        "episodes.csv",
        "summary.csv",
        "per_scenario.csv",
        *(["ncap.csv"] if ncap else []),
        "safety_vs_efficiency.png",
        "min_ttc.png",
        *(f"worst/{w}" for w in worst),
    ]
