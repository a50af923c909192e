"""The value-of-prediction table: each grid row against the no-prediction row, with paired bootstrap CIs.

For every row (policy, intention, predictor) of a grid run (`crossing_eval.grid`) it reports collision
rate, yield compliance, unneeded stops per episode, the mean delay with episodes that never passed the
crossing counted at their duration (the *censored* delay: duration minus free-flow time) and the pass
rate, hard brakes per episode and the 5th percentile of the episodes' minimum TTC; each also as the
difference to the same policy's ``none / none`` row, with a paired bootstrap 95 % interval
(`scipy.stats.bootstrap`, ``paired=True``, percentile method, seeded): the rows ran on the same episodes,
so resampling episodes keeps the pairs. "Value captured" is (none − row) / (none − oracle) of the
censored delay, the oracle row being the row's own predictors made perfect (``qlb / none`` against
``oracle / none``, ``none / cvm`` against ``none / oracle``, ``qlb / s-cgru`` against ``oracle / oracle``);
its interval comes from the same paired resampling of all three rows. It is left out ("–") where that
oracle is not faster than no prediction: a share of a gain that does not exist means nothing.
Files: ``value_of_prediction.md``, ``.csv``, ``.png``.
"""

from __future__ import annotations

import io
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from crossing_common.files import write_bytes_atomic, write_text_atomic
from crossing_env.road import RoadGeometry
from crossing_env.safety import MetricsConfig
from crossing_eval.tasks import EpisodeRecord
from scenarios import load_scenario

__all__ = ["EpisodeColumns", "value_table", "write_value_outputs"]

CONFIDENCE = 0.95
"""Level of the bootstrap intervals."""


@dataclass(frozen=True)
class EpisodeColumns:
    """Per-episode figures of one row, aligned episode by episode with every other row."""

    keys: list[tuple[str, int]]
    """(scenario, episode) of each position."""
    collision: np.ndarray
    """1.0 if the episode had an ego collision."""
    compliant: np.ndarray
    """Yield obligations met."""
    obligations: np.ndarray
    """Yield obligations."""
    unneeded_stops: np.ndarray
    """Unneeded stops (`crossing_env.safety.stops`)."""
    delay: np.ndarray
    """Delay (s); for an episode that did not pass the crossing, its duration minus the free-flow time."""
    passed: np.ndarray
    """1.0 if the ego passed the crossing."""
    hard_brakes: np.ndarray
    """Hard-braking events."""
    min_ttc: np.ndarray
    """Minimum TTC (s), inf when never on a collision course."""


def _free_flow_times(scenarios: Sequence[str]) -> dict[str, float]:
    """Free-flow time (s) from the ego's start to the delay target of each scenario, as `EpisodeMetrics`."""
    out = {}
    margin = MetricsConfig().delay_margin
    for name in scenarios:
        sc = load_scenario(name)
        ca = RoadGeometry(sc.road, sc.crossing).conflict_area(sc.ego.lane)
        out[name] = (ca.x_max + margin - sc.ego.x) / sc.road.speed_limit
    return out


def episode_columns(records: Sequence[EpisodeRecord], free_flow: dict[str, float]) -> EpisodeColumns:
    """Columns of one row's records (already sorted by scenario and episode)."""

    def col(fn: Callable[[dict[str, Any], str], float]) -> np.ndarray:
        return np.array([fn(r.result, r.task.scenario) for r in records], dtype=np.float64)

    def delay(res: dict[str, Any], sc: str) -> float:
        if res["passed_crossing"] and res["delay"] is not None:
            return float(res["delay"])
        return float(res["duration"]) - free_flow[sc]

    return EpisodeColumns(
        keys=[(r.task.scenario, r.task.episode) for r in records],
        collision=col(lambda r, _: float(bool(r["collision"]))),
        compliant=col(lambda r, _: r["yield_compliant"]),
        obligations=col(lambda r, _: r["yield_obligations"]),
        unneeded_stops=col(lambda r, _: r.get("unneeded_stops", 0)),
        delay=col(delay),
        passed=col(lambda r, _: float(bool(r["passed_crossing"]))),
        hard_brakes=col(lambda r, _: r["hard_braking_events"]),
        min_ttc=col(lambda r, _: math.inf if r["min_ttc"] is None else r["min_ttc"]),
    )


# Statistics of one row, vectorised along `axis` for scipy's bootstrap. Each takes the row's columns.
def _mean(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis)


def _ratio(c: np.ndarray, o: np.ndarray, axis: int = -1) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sum(c, axis=axis) / np.sum(o, axis=axis)


def _p5(x: np.ndarray, axis: int = -1) -> np.ndarray:
    finite = np.where(np.isfinite(x), x, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanpercentile(finite, 5, axis=axis)


METRICS: dict[str, tuple[tuple[str, ...], Callable[..., np.ndarray]]] = {
    "collision_rate": (("collision",), _mean),
    "yield_compliance": (("compliant", "obligations"), _ratio),
    "unneeded_stops": (("unneeded_stops",), _mean),
    "mean_delay": (("delay",), _mean),
    "pass_rate": (("passed",), _mean),
    "hard_brakes": (("hard_brakes",), _mean),
    "min_ttc_p5": (("min_ttc",), _p5),
}
"""Name → (columns it reads, statistic); the order of the table's columns."""


def _interval(
    data: Sequence[np.ndarray], statistic: Callable[..., np.ndarray], n_resamples: int, seed: int
) -> tuple[float, float]:
    """Paired percentile bootstrap interval of `statistic(*data)`; nan when it cannot be formed."""
    if data[0].shape[0] < 2:
        return math.nan, math.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # degenerate (all-equal) resamples: the interval is a point
        res = stats.bootstrap(
            tuple(data),
            statistic,
            paired=True,
            vectorized=True,
            n_resamples=n_resamples,
            confidence_level=CONFIDENCE,
            method="percentile",
            rng=np.random.default_rng(seed),
        )
    lo, hi = res.confidence_interval
    return float(lo), float(hi)


def _difference(fn: Callable[..., np.ndarray], k: int) -> Callable[..., np.ndarray]:
    """Statistic of (row columns..., reference columns...) = fn(row) − fn(reference)."""

    def diff(*cols: np.ndarray, axis: int = -1) -> np.ndarray:
        return fn(*cols[:k], axis=axis) - fn(*cols[k:], axis=axis)

    return diff


def _captured(none: np.ndarray, row: np.ndarray, oracle: np.ndarray, axis: int = -1) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        n = np.mean(none, axis=axis)
        return (n - np.mean(row, axis=axis)) / (n - np.mean(oracle, axis=axis))


def value_table(
    rows: dict[tuple[str, str, str], list[EpisodeRecord]], n_resamples: int = 2000, seed: int = 0
) -> list[dict[str, Any]]:
    """One dict per row: n, each metric, its difference to ``none / none`` with a CI, value captured.

    Rows must have run on the same episodes (the grid guarantees it; checked).
    """
    scenarios = sorted({r.task.scenario for recs in rows.values() for r in recs})
    free_flow = _free_flow_times(scenarios)
    cols = {key: episode_columns(recs, free_flow) for key, recs in rows.items()}
    out = []
    for key in rows:
        policy, intention, predictor = key
        c = cols[key]
        ref_key = (policy, "none", "none")
        ref = cols.get(ref_key)
        if ref is not None and ref.keys != c.keys:
            raise ValueError(f"rows {key} and {ref_key} ran on different episodes: not a paired grid")
        row: dict[str, Any] = {
            "policy": policy,
            "intention": intention,
            "predictor": predictor,
            "episodes": len(c.keys),
        }
        for m, (names, fn) in METRICS.items():
            mine = [getattr(c, n) for n in names]
            row[m] = float(fn(*mine))
            if ref is None or key == ref_key:
                row[f"{m}_diff"], row[f"{m}_diff_ci"] = math.nan, (math.nan, math.nan)
                continue
            theirs = [getattr(ref, n) for n in names]
            row[f"{m}_diff"] = row[m] - float(fn(*theirs))
            row[f"{m}_diff_ci"] = _interval([*mine, *theirs], _difference(fn, len(names)), n_resamples, seed)
        oracle_key = _oracle_key(rows, key)
        row["value_captured"], row["value_captured_ci"] = math.nan, (math.nan, math.nan)
        row["value_oracle"] = "" if oracle_key is None else f"{oracle_key[1]} / {oracle_key[2]}"
        if ref is not None and oracle_key is not None and key != ref_key:
            o = cols[oracle_key].delay
            if float(np.mean(ref.delay)) > float(np.mean(o)):
                row["value_captured"] = float(_captured(ref.delay, c.delay, o))
                row["value_captured_ci"] = _interval([ref.delay, c.delay, o], _captured, n_resamples, seed)
        out.append(row)
    return out


def _oracle_key(
    rows: dict[tuple[str, str, str], Any], key: tuple[str, str, str]
) -> tuple[str, str, str] | None:
    """The bound of row `key`: its real predictors replaced by the oracles.

    None for an oracle or no-prediction row, or when the grid lacks that oracle row.
    """
    policy, intention, predictor = key
    real = [x not in ("none", "oracle") for x in (intention, predictor)]
    if not any(real):
        return None
    bound = (policy, "oracle" if real[0] else intention, "oracle" if real[1] else predictor)
    return bound if bound in rows else None


# ---------------------------------------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------------------------------------

_COLUMNS = (
    ("collision_rate", "collision rate", 3),
    ("yield_compliance", "yield compliance", 3),
    ("unneeded_stops", "unneeded stops/ep", 2),
    ("mean_delay", "mean delay s (censored)", 2),
    ("pass_rate", "pass rate", 2),
    ("hard_brakes", "hard brakes/ep", 2),
    ("min_ttc_p5", "min-TTC p5 s", 2),
)


def _fmt(x: float, digits: int, sign: bool = False) -> str:
    if not math.isfinite(x):
        return "–"
    return f"{x:+.{digits}f}" if sign else f"{x:.{digits}f}"


def format_markdown(table: Sequence[dict[str, Any]], settings: dict[str, Any]) -> str:
    """The table as markdown: value, then Δ to no prediction [95 % CI] in each cell."""
    head = (
        ["policy", "intention", "predictor", "n"] + [label for _, label, _ in _COLUMNS] + ["value captured"]
    )
    lines = [
        "# Value of prediction",
        "",
        f"Command: `{settings['command']}`",
        "",
        f"Scenarios: {', '.join(settings['scenarios'])}; {settings['episodes']} episode(s) each, base seed"
        f" {settings['seed']}; every row on the same episodes. Cells: value, then the difference to the"
        " policy's `none / none` row with its paired bootstrap 95 % interval. Delay counts episodes that"
        " never passed the crossing at their duration. Value captured = (none − row) / (none − oracle)"
        " of that delay, the oracle being the row's own predictors made perfect (`qlb / none` against"
        ' `oracle / none`); "–" where that oracle is not faster than no prediction. **oracle** rows are'
        " privileged (ground truth): upper bounds, not predictors.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for row in table:
        cells = [row["policy"], row["intention"], row["predictor"], str(row["episodes"])]
        for m, _, d in _COLUMNS:
            cell = _fmt(row[m], d)
            if math.isfinite(row[f"{m}_diff"]):
                lo, hi = row[f"{m}_diff_ci"]
                cell += f" ({_fmt(row[f'{m}_diff'], d, True)} [{_fmt(lo, d, True)}, {_fmt(hi, d, True)}])"
            cells.append(cell)
        vc = row["value_captured"]
        lo, hi = row["value_captured_ci"]
        cells.append(f"{_fmt(vc, 2)} [{_fmt(lo, 2)}, {_fmt(hi, 2)}]" if math.isfinite(vc) else "–")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def format_csv(table: Sequence[dict[str, Any]]) -> str:
    """One line per row, every number in its own column (CIs as _lo / _hi)."""
    import csv

    header = ["policy", "intention", "predictor", "episodes"]
    for m, _, _ in _COLUMNS:
        header += [m, f"{m}_diff", f"{m}_diff_lo", f"{m}_diff_hi"]
    header += ["value_captured", "value_captured_lo", "value_captured_hi", "value_oracle"]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in table:
        line: list[Any] = [row["policy"], row["intention"], row["predictor"], row["episodes"]]
        for m, _, _ in _COLUMNS:
            line += [row[m], row[f"{m}_diff"], *row[f"{m}_diff_ci"]]
        line += [row["value_captured"], *row["value_captured_ci"], row["value_oracle"]]
        w.writerow(["nan" if isinstance(x, float) and math.isnan(x) else x for x in line])
    return buf.getvalue()


def plot_png(table: Sequence[dict[str, Any]]) -> bytes:
    """Δ mean delay (censored) per row with its CI; red: more collisions or compliance below 0.99."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in table if math.isfinite(r["mean_delay_diff"])]
    fig, ax = plt.subplots(figsize=(8, 0.45 * max(len(rows), 2) + 1.5))
    for y, r in enumerate(rows):
        lo, hi = r["mean_delay_diff_ci"]
        unsafe = r["collision_rate_diff"] > 0 or r["yield_compliance"] < 0.99
        ax.errorbar(
            r["mean_delay_diff"],
            y,
            xerr=[[r["mean_delay_diff"] - lo], [hi - r["mean_delay_diff"]]],
            fmt="o",
            color="tab:red" if unsafe else "tab:blue",
            capsize=3,
        )
    ax.axvline(0.0, color="grey", lw=0.8)
    ax.set_yticks(range(len(rows)), [f"{r['policy']}: {r['intention']} / {r['predictor']}" for r in rows])
    ax.invert_yaxis()
    ax.set_xlabel("Δ mean delay vs no prediction (s, censored), paired bootstrap 95 % CI")
    ax.set_title("Value of prediction (red: more collisions or compliance < 0.99)")
    fig.tight_layout()
    return figure_png(fig)


def figure_png(fig: Any, dpi: int = 110) -> bytes:
    """The figure as PNG bytes; the figure is closed (matplotlib keeps open figures alive)."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()


def write_value_outputs(table: Sequence[dict[str, Any]], settings: dict[str, Any], out: Path) -> list[str]:
    """Markdown, CSV and plot into `out` (atomically). Returns the file names."""
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "value_of_prediction.md", format_markdown(table, settings))
    write_text_atomic(out / "value_of_prediction.csv", format_csv(table))
    write_bytes_atomic(out / "value_of_prediction.png", plot_png(table))
    return ["value_of_prediction.md", "value_of_prediction.csv", "value_of_prediction.png"]
