"""Value of prediction v2: each row against no prediction on delay *and* safety margins, with paired CIs.

Reads the episodes of `studies.value_of_prediction` (rows of (intention, predictor) for one policy, every row
on the same seeds) and the open-loop accuracy of each row, and returns one JSON-safe dict that
`render_body` turns into the tables of ``docs/value_of_prediction.md`` and `plot_curve` into its figure:

- per row and metric: the value, the paired difference to the ``none / none`` row with a paired bootstrap
  95 % interval (`scipy.stats.bootstrap`, ``paired=True``, percentile, seeded), and the **value captured**:
  (row − none) / (oracle − none), the oracle being the row's own kind of prediction made perfect; reported
  only where the oracle's own difference is an improvement whose interval excludes 0 (a share of a gain
  that is not there means nothing);
- censored delay per scenario with its paired difference to the reference (where a row's value is earned
  or lost), yield compliance per scenario, and the same comparison without any scenario that holds more
  than a third of the obligations (one busy scenario must not carry the table);
- the accuracy-to-value points: each row's open-loop accuracy (Brier, ADE) beside its driving value.

Delay is censored: an episode that never passed the crossing counts at its duration minus the free-flow
time (`crossing_eval.prediction_value`). Episodes that never came near a pedestrian have no min-TTC and no
separation; the 5th percentiles are taken over those that did.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from crossing_eval.prediction_value import (
    _difference,
    _free_flow_times,
    _interval,
    _mean,
    _p5,
    _ratio,
    figure_png,
)

__all__ = ["METRICS", "analyse", "plot_curve", "render_body", "render_summary"]

N_RESAMPLES = 2000
"""Bootstrap resamples of every interval."""
NO_ADDED_DELAY = 0.02
"""'No added delay' for the path oracle's target: the delay difference's interval includes 0 (or lies below
it) and its point estimate is within this share of the reference's mean delay."""
DOMINANT_SHARE = 1 / 3
"""A scenario holding more than this share of the reference row's obligations is left out of the check."""


def _p95(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.percentile(x, 95, axis=axis)


# name → (columns, statistic, label, digits, +1 if higher is better else −1)
METRICS: dict[str, tuple[tuple[str, ...], Callable[..., np.ndarray], str, int, int]] = {
    "collision_rate": (("collision",), _mean, "collision rate", 3, -1),
    "yield_compliance": (("compliant", "obligations"), _ratio, "yield compliance", 3, +1),
    "mean_delay": (("delay",), _mean, "censored delay s", 2, -1),
    "hard_brakes": (("hard_brakes",), _mean, "hard brakes/ep", 2, -1),
    "min_ttc_p5": (("min_ttc",), _p5, "min-TTC p5 s", 2, +1),
    "drac_p95": (("drac",), _p95, "DRAC p95 m/s²", 2, -1),
    "min_separation_p5": (("separation",), _p5, "min separation p5 m", 2, +1),
    "unneeded_stops": (("unneeded_stops",), _mean, "unneeded stops/ep", 2, -1),
}
"""The table's metrics, in column order."""


def row_columns(records: Sequence[dict[str, Any]], free_flow: dict[str, float]) -> dict[str, np.ndarray]:
    """Per-episode arrays of one row (records sorted by scenario and episode)."""

    def col(fn: Callable[[dict[str, Any], str], float]) -> np.ndarray:
        return np.array([fn(r["result"], r["scenario"]) for r in records], dtype=np.float64)

    def delay(res: dict[str, Any], sc: str) -> float:
        if res["passed_crossing"] and res["delay"] is not None:
            return float(res["delay"])
        return float(res["duration"]) - free_flow[sc]

    def finite(key: str) -> Callable[[dict[str, Any], str], float]:
        return lambda r, _: math.inf if r.get(key) is None else float(r[key])

    return {
        "collision": col(lambda r, _: float(bool(r["collision"]))),
        "compliant": col(lambda r, _: r["yield_compliant"]),
        "obligations": col(lambda r, _: r["yield_obligations"]),
        "delay": col(delay),
        "hard_brakes": col(lambda r, _: r["hard_braking_events"]),
        "min_ttc": col(finite("min_ttc")),
        "drac": col(lambda r, _: float(r.get("max_drac_crossing") or 0.0)),
        "separation": col(finite("min_separation")),
        "unneeded_stops": col(lambda r, _: r.get("unneeded_stops", 0)),
    }


def episode_figures(result: dict[str, Any], scenario: str) -> dict[str, float]:
    """One episode's figures as the study's tables compute them (`row_columns` of that episode alone).

    The study's fingerprint hashes these, so that a field added to the episode record leaves it current.
    """
    cols = row_columns([{"result": result, "scenario": scenario}], _free_flow_times([scenario]))
    return {key: float(values[0]) for key, values in cols.items()}


def _oracle_of(intention: str, predictor: str) -> tuple[str, str] | None:
    """The perfect version of a row's prediction (None for the reference and the oracles themselves)."""
    if (intention, predictor) in (("none", "none"), ("oracle", "none"), ("none", "oracle")):
        return None
    if predictor == "none":
        return ("oracle", "none")
    if intention == "none":
        return ("none", "oracle")
    return ("oracle", "oracle")


def kind_of(intention: str, predictor: str) -> str:
    """'reference', 'oracle', 'degraded' (an oracle spoilt on purpose) or 'real'."""
    if (intention, predictor) == ("none", "none"):
        return "reference"
    names = {intention, predictor} - {"none"}
    if any(n.startswith(("oracle-flip", "oracle-noise")) for n in names):
        return "degraded"
    return "oracle" if names == {"oracle"} else "real"


def _select(records: Sequence[dict[str, Any]], keys: set[tuple[str, int]]) -> list[dict[str, Any]]:
    return sorted(
        (r for r in records if (r["scenario"], r["episode"]) in keys),
        key=lambda r: (r["scenario"], r["episode"]),
    )


def _compare(
    mine: dict[str, np.ndarray],
    ref: dict[str, np.ndarray],
    oracle: dict[str, np.ndarray] | None,
    seed: int,
    n_resamples: int = N_RESAMPLES,
) -> dict[str, Any]:
    """Every metric of a row: value, difference to the reference [CI], value captured [CI]."""
    out: dict[str, Any] = {}
    for m, (names, fn, _, _, better) in METRICS.items():
        a = [mine[n] for n in names]
        b = [ref[n] for n in names]
        value, base = float(fn(*a)), float(fn(*b))
        diff = value - base

        def difference(*cols: np.ndarray, axis: int = -1, fn: Any = fn, k: int = len(names)) -> np.ndarray:
            return fn(*cols[:k], axis=axis) - fn(*cols[k:], axis=axis)

        lo, hi = _interval([*a, *b], difference, n_resamples, seed)
        cell: dict[str, Any] = {"value": value, "diff": diff, "diff_ci": [lo, hi]}
        if oracle is not None:
            o = [oracle[n] for n in names]
            gain = float(fn(*o)) - base
            olo, ohi = _interval([*o, *b], difference, n_resamples, seed)
            real_gain = better * gain > 0 and better * olo > 0 and better * ohi > 0
            cell["oracle_diff"], cell["oracle_diff_ci"] = gain, [olo, ohi]
            cell["captured"], cell["captured_ci"] = math.nan, [math.nan, math.nan]
            if real_gain:
                k = len(names)

                def captured(*cols: np.ndarray, axis: int = -1, fn: Any = fn, k: int = k) -> np.ndarray:
                    r, n, orc = cols[:k], cols[k : 2 * k], cols[2 * k :]
                    with np.errstate(invalid="ignore", divide="ignore"):
                        base_ = fn(*n, axis=axis)
                        return (fn(*r, axis=axis) - base_) / (fn(*orc, axis=axis) - base_)

                cell["captured"] = diff / gain
                cell["captured_ci"] = list(_interval([*a, *b, *o], captured, n_resamples, seed))
        out[m] = cell
    return out


def analyse(
    records: dict[tuple[str, str], list[dict[str, Any]]],
    accuracy: dict[str, dict[str, float]],
    settings: dict[str, Any],
    seed: int = 0,
    n_resamples: int = N_RESAMPLES,
) -> dict[str, Any]:
    """The v2 data: rows with metrics, compliance per scenario, the rows without the dominant scenarios."""
    scenarios = sorted({r["scenario"] for recs in records.values() for r in recs})
    free_flow = _free_flow_times(scenarios)
    ref_all = records[("none", "none")]

    def metrics(key: tuple[str, str], keys: set[tuple[str, int]]) -> dict[str, Any]:
        """Row `key` on the episodes `keys`, paired with the reference and its oracle on the same ones."""
        okey = _oracle_of(*key)
        mine = row_columns(_select(records[key], keys), free_flow)
        ref = row_columns(_select(ref_all, keys), free_flow)
        oracle = None if okey not in records else row_columns(_select(records[okey], keys), free_flow)
        if len(ref["delay"]) != len(keys) or (oracle is not None and len(oracle["delay"]) != len(keys)):
            raise ValueError(f"row {key[0]} / {key[1]} is not paired with the reference and its oracle")
        return _compare(mine, ref, oracle, seed, n_resamples)

    rows = []
    for (intention, predictor), recs in records.items():
        okey = _oracle_of(intention, predictor)
        rows.append(
            {
                "intention": intention,
                "predictor": predictor,
                "kind": kind_of(intention, predictor),
                "episodes": len(recs),
                "oracle": "" if okey is None else f"{okey[0]} / {okey[1]}",
                "accuracy": _accuracy_of(accuracy, intention, predictor),
                "metrics": metrics((intention, predictor), {(r["scenario"], r["episode"]) for r in recs}),
                "compliance_by_scenario": _by_scenario(recs),
                "delay_by_scenario": (
                    {}
                    if kind_of(intention, predictor) == "degraded"
                    else _delay_by_scenario(recs, ref_all, free_flow, seed, n_resamples)
                ),
            }
        )
    share = _obligation_share(ref_all)
    dominant = sorted(sc for sc, s in share.items() if s > DOMINANT_SHARE)
    without = []
    for (intention, predictor), recs in records.items():
        keys = {(r["scenario"], r["episode"]) for r in recs if r["scenario"] not in dominant}
        if keys and kind_of(intention, predictor) != "degraded":
            row = {"intention": intention, "predictor": predictor, "episodes": len(keys)}
            without.append(row | {"metrics": metrics((intention, predictor), keys)})
    return {
        "settings": settings,
        "rows": rows,
        "obligation_share": share,
        "dominant": dominant,
        "without_dominant": without,
    }


def _accuracy_of(accuracy: dict[str, dict[str, Any]], intention: str, predictor: str) -> dict[str, Any]:
    """The open-loop accuracy of a row that predicts one thing (intent or paths); empty otherwise."""
    if predictor == "none" and intention != "none":
        return dict(accuracy.get("intent", {}).get(intention, {}))
    if intention == "none" and predictor != "none":
        return dict(accuracy.get("path", {}).get(predictor, {}))
    return {}


def _by_scenario(recs: Sequence[dict[str, Any]]) -> dict[str, list[int]]:
    """Scenario → [compliant, obligations]."""
    out: dict[str, list[int]] = {}
    for r in recs:
        c = out.setdefault(r["scenario"], [0, 0])
        c[0] += int(r["result"]["yield_compliant"])
        c[1] += int(r["result"]["yield_obligations"])
    return dict(sorted(out.items()))


def _delay_by_scenario(
    recs: Sequence[dict[str, Any]],
    ref_all: Sequence[dict[str, Any]],
    free_flow: dict[str, float],
    seed: int,
    n_resamples: int,
) -> dict[str, dict[str, Any]]:
    """Scenario → the row's mean censored delay and its paired difference to the reference [CI].

    Where a row's value comes from (or is lost) is a per-scenario question: a pooled mean can hide one
    scenario that carries it.
    """
    fn = METRICS["mean_delay"][1]
    out: dict[str, dict[str, Any]] = {}
    for sc in sorted({r["scenario"] for r in recs}):
        keys = {(r["scenario"], r["episode"]) for r in recs if r["scenario"] == sc}
        mine = row_columns(_select(recs, keys), free_flow)["delay"]
        ref = row_columns(_select(ref_all, keys), free_flow)["delay"]
        lo, hi = _interval([mine, ref], _difference(fn, 1), n_resamples, seed)
        value = float(fn(mine))
        out[sc] = {"value": value, "diff": value - float(fn(ref)), "diff_ci": [lo, hi], "episodes": len(keys)}
    return out


def _obligation_share(recs: Sequence[dict[str, Any]]) -> dict[str, float]:
    counts = {sc: c[1] for sc, c in _by_scenario(recs).items()}
    total = sum(counts.values()) or 1
    return {sc: n / total for sc, n in counts.items()}


# ---------------------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------------------


def _f(x: float, d: int, sign: bool = False) -> str:
    if x is None or not math.isfinite(x):
        return "–"
    return f"{x:+.{d}f}" if sign else f"{x:.{d}f}"


def _diff_cell(cell: dict[str, Any], d: int) -> str:
    lo, hi = cell["diff_ci"]
    if not math.isfinite(cell["diff"]) or (cell["diff"] == 0 and lo == 0 and hi == 0):
        return _f(cell["value"], d)
    return f"{_f(cell['value'], d)} ({_f(cell['diff'], d, True)} [{_f(lo, d, True)}, {_f(hi, d, True)}])"


def _label(row: dict[str, Any]) -> str:
    i, p = row["intention"], row["predictor"]
    if (i, p) == ("none", "none"):
        return "no prediction"
    return f"intent: {i}" if p == "none" else f"paths: {p}" if i == "none" else f"{i} / {p}"


def _metric_table(rows: Sequence[dict[str, Any]], metrics: Sequence[str]) -> list[str]:
    head = ["row", "n", *(METRICS[m][2] for m in metrics)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        cells = [_label(row), str(row["episodes"])]
        cells += [_diff_cell(row["metrics"][m], METRICS[m][3]) for m in metrics]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _captured_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    head = ["row", "oracle", *(METRICS[m][2] for m in METRICS if m != "collision_rate")]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        if not row["oracle"]:
            continue
        cells = [_label(row), row["oracle"]]
        for m in METRICS:
            if m == "collision_rate":
                continue
            c = row["metrics"][m]
            if math.isfinite(c.get("captured", math.nan)):
                lo, hi = c["captured_ci"]
                cells.append(f"{c['captured']:.0%} [{_f(lo * 100, 0)}, {_f(hi * 100, 0)}]")
            else:
                cells.append("–")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _targets(data: dict[str, Any]) -> list[str]:
    rows = {(r["intention"], r["predictor"]): r for r in data["rows"]}
    out = []
    ref = rows[("none", "none")]["metrics"]
    oi = rows.get(("oracle", "none"))
    if oi is not None:
        d = oi["metrics"]["mean_delay"]
        rel, (lo, hi) = d["diff"] / ref["mean_delay"]["value"], d["diff_ci"]
        base = ref["mean_delay"]["value"]
        ok = rel <= -0.25 and oi["metrics"]["collision_rate"]["value"] == 0
        ok = ok and oi["metrics"]["yield_compliance"]["value"] >= 0.99
        out.append(
            f"- Oracle intention vs the remembering baseline: censored delay {rel:+.1%}"
            f" [{lo / base:+.1%}, {hi / base:+.1%}], collision rate"
            f" {oi['metrics']['collision_rate']['value']:.3f}, compliance"
            f" {oi['metrics']['yield_compliance']['value']:.3f} (target ≤ −25 %, 0, ≥ 0.99):"
            f" **{'met' if ok else 'missed'}**."
        )
    real = [rows[(i, "none")] for i in ("learned", "qlb", "classical") if (i, "none") in rows]
    if real:
        best = max(
            real, key=lambda r: np.nan_to_num(r["metrics"]["mean_delay"].get("captured", math.nan), nan=-9)
        )
        c = best["metrics"]["mean_delay"]
        lo, hi = c.get("captured_ci", [math.nan, math.nan])
        comp = best["metrics"]["yield_compliance"]["value"]
        ok = math.isfinite(c.get("captured", math.nan)) and c["captured"] >= 0.3 and lo > 0 and comp >= 0.99
        parts = ", ".join(
            f"{r['intention']} {_f(r['metrics']['mean_delay'].get('captured', math.nan) * 100, 0)} %"
            for r in real
        )
        out.append(
            f"- Best real intention predictor: **{best['intention']}** captures"
            f" {_f(c.get('captured', math.nan) * 100, 0)} % [{_f(lo * 100, 0)}, {_f(hi * 100, 0)}]"
            f" of the oracle's delay value at compliance {comp:.3f} ({parts}; target ≥ 30 % with the"
            f" interval above 0, compliance ≥ 0.99): **{'met' if ok else 'missed'}**."
        )
    po = rows.get(("none", "oracle"))
    if po is not None:
        m = po["metrics"]
        ttc, hb, dl = m["min_ttc_p5"], m["hard_brakes"], m["mean_delay"]
        ttc_ok = ttc["diff_ci"][0] > 0
        hb_ok = hb["diff_ci"][1] < 0
        delay_ok = dl["diff_ci"][0] <= 0 and dl["diff"] <= NO_ADDED_DELAY * ref["mean_delay"]["value"]
        out.append(
            f"- Path oracle: min-TTC p5 {_f(ttc['diff'], 2, True)} s [{_f(ttc['diff_ci'][0], 2, True)},"
            f" {_f(ttc['diff_ci'][1], 2, True)}], hard brakes {_f(hb['diff'], 2, True)}/ep"
            f" [{_f(hb['diff_ci'][0], 2, True)}, {_f(hb['diff_ci'][1], 2, True)}], delay"
            f" {_f(dl['diff'], 2, True)} s [{_f(dl['diff_ci'][0], 2, True)}, {_f(dl['diff_ci'][1], 2, True)}]"
            " (target: min-TTC p5 or hard brakes better with the interval excluding 0, and no added delay:"
            f" an interval that includes 0 and a point estimate within {NO_ADDED_DELAY:.0%} of the"
            " reference's delay):"
            f" **{'met' if (ttc_ok or hb_ok) and delay_ok else 'missed'}**."
        )
    return out


def render_body(data: dict[str, Any]) -> str:
    """The markdown block of ``docs/value_of_prediction.md`` (registry entry ``value_of_prediction``)."""
    s = data["settings"]
    main = [r for r in data["rows"] if r["kind"] != "degraded"]
    degraded = [r for r in data["rows"] if r["kind"] == "degraded"]
    lines = [
        f"Measured with `{s['command'].strip()}` on commit `{data['commit'][:12]}`"
        f" ({s.get('workers', 2)} workers: the rows' episodes took {data.get('rows_wall_seconds', 0):.0f} s,"
        f" the run that analysed them {data['wall_seconds']:.0f} s); rendered from"
        " `benchmarks/results/value_of_prediction.json` by `python -m benchmarks.results`.",
        "",
        f"Policy `{s['policy']}` on {len(s['scenarios'])} scenarios ({', '.join(s['scenarios'])}),"
        f" {s['episodes']} episodes each (base seed {s['seed']}), every row on the same episodes;"
        + (
            ""
            if s["path_episodes"] == s["episodes"]
            else f" the path rows (oracle, CVM, S-CGRU) on the first {s['path_episodes']} of each scenario,"
        )
        + f" the degraded intent rows on the first {s['flip_episodes']} and the degraded path rows on the"
        f" first {s['path_sweep_episodes']}, each compared with the reference on those. Cells: value"
        " (difference to no prediction [paired bootstrap 95 % interval])."
        " **oracle** and **degraded** rows read the ground truth: bounds and probes, not predictors.",
        "",
        "**Targets**",
        "",
        *_targets(data),
        "",
        "**Efficiency and the law**",
        "",
        *_metric_table(main, ["collision_rate", "yield_compliance", "mean_delay", "unneeded_stops"]),
        "",
        "**Safety margins**",
        "",
        *_metric_table(main, ["hard_brakes", "min_ttc_p5", "drac_p95", "min_separation_p5"]),
        "",
        '**Value captured**: (row − none) / (oracle − none) per metric [95 % interval]; "–" where the oracle'
        " itself does not improve on no prediction with an interval excluding 0.",
        "",
        *_captured_table(main),
        "",
        "**Censored delay per scenario** (s; difference to no prediction on the same episodes [paired"
        " bootstrap 95 % interval]): where each row's delay value is earned or lost",
        "",
        *_delay_scenario_table(main),
        "",
        "**Yield compliance per scenario** (compliant / obligations; share of the reference's obligations)",
        "",
        *_compliance_table(data, main),
        "",
        f"**Without the dominant scenario** ({', '.join(data['dominant']) or 'none'}: more than a third"
        " of the obligations)",
        "",
        *_metric_table(
            data["without_dominant"], ["collision_rate", "yield_compliance", "mean_delay", "hard_brakes"]
        ),
        "",
        "**Accuracy to value**: open-loop accuracy (Brier of `crossing_intent` against the true intent;"
        " ADE / FDE of `predicted_paths` against the true future of a car holding its speed, metres, over"
        f" {s['accuracy_episodes']} episodes per scenario) beside the driving value (difference to no"
        " prediction). Figure: `docs/value_of_prediction_curve.png`.",
        "",
        *_accuracy_table([*main, *degraded]),
    ]
    return "\n".join(lines)


def render_summary(data: dict[str, Any]) -> str:
    """The README's block: the targets, read from the same JSON."""
    s = data["settings"]
    return "\n".join(
        [
            f"Paired on {len(s['scenarios'])} scenarios, {s['episodes']} episodes each per intention row"
            f" and {s['path_episodes']} per path row"
            " (rendered from `benchmarks/results/value_of_prediction.json`; every table, the safety"
            " margins and the accuracy-to-value curve in"
            " [docs/value_of_prediction.md](docs/value_of_prediction.md)):",
            "",
            *_targets(data),
        ]
    )


def _compliance_table(data: dict[str, Any], rows: Sequence[dict[str, Any]]) -> list[str]:
    head = ["scenario", "share", *(f"{_label(r)} (n={r['episodes']})" for r in rows)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for sc, share in data["obligation_share"].items():
        cells = [sc, f"{share:.0%}"]
        for r in rows:
            c, n = r["compliance_by_scenario"].get(sc, [0, 0])
            cells.append(f"{c / n:.3f}" if n else "–")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _delay_scenario_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    shown = [r for r in rows if r.get("delay_by_scenario")]
    head = ["scenario", *(f"{_label(r)} (n/scenario={_per_scenario_n(r)})" for r in shown)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    scenarios = sorted({sc for r in shown for sc in r["delay_by_scenario"]})
    for sc in scenarios:
        cells = [sc]
        for r in shown:
            c = r["delay_by_scenario"].get(sc)
            cells.append("–" if c is None else _diff_cell(c, 2))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _per_scenario_n(row: dict[str, Any]) -> str:
    counts = sorted({c["episodes"] for c in row["delay_by_scenario"].values()})
    return "/".join(str(n) for n in counts)


def _accuracy_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    head = [
        "row", "kind", "n", "Brier", "ADE m", "FDE m", "collision rate", "yield compliance", "Δ delay s",
        "Δ hard brakes/ep", "Δ min-TTC p5 s",
    ]  # fmt: skip
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if r["kind"] == "reference":
            continue
        a, m = r["accuracy"], r["metrics"]

        def d(name: str, digits: int = 2, m: dict[str, Any] = m) -> str:
            c = m[name]
            lo, hi = c["diff_ci"]
            return f"{_f(c['diff'], digits, True)} [{_f(lo, digits, True)}, {_f(hi, digits, True)}]"

        lines.append(
            "| "
            + " | ".join(
                [
                    _label(r),
                    r["kind"],
                    str(r["episodes"]),
                    _f(a.get("brier", math.nan), 3),
                    _f(a.get("ade", math.nan), 2),
                    _f(a.get("fde", math.nan), 2),
                    _f(m["collision_rate"]["value"], 3),
                    _f(m["yield_compliance"]["value"], 3),
                    d("mean_delay"),
                    d("hard_brakes"),
                    d("min_ttc_p5"),
                ]
            )
            + " |"
        )
    return lines


def plot_curve(data: dict[str, Any]) -> bytes:
    """Driving value against open-loop accuracy: Brier → Δ delay; ADE → Δ hard brakes and Δ min-TTC p5."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    panels = (
        (axes[0], "brier", "predictor", "mean_delay", "Brier (intent to cross)", "Δ censored delay (s)"),
        (
            axes[1],
            "ade",
            "intention",
            "hard_brakes",
            "ADE (m), car holding its speed",
            "Δ hard brakes / episode",
        ),
        (axes[2], "ade", "intention", "min_ttc_p5", "ADE (m), car holding its speed", "Δ min-TTC p5 (s)"),
    )
    for ax, acc, other, metric, xlabel, ylabel in panels:
        rows = [
            r
            for r in data["rows"]
            if r[other] == "none" and r["kind"] != "reference" and acc in r["accuracy"]
        ]
        probe = sorted(
            (r for r in rows if r["kind"] in ("oracle", "degraded")), key=lambda r: r["accuracy"][acc]
        )
        if probe:
            xs = [r["accuracy"][acc] for r in probe]
            ys = [r["metrics"][metric]["diff"] for r in probe]
            lo = [y - r["metrics"][metric]["diff_ci"][0] for y, r in zip(ys, probe, strict=True)]
            hi = [r["metrics"][metric]["diff_ci"][1] - y for y, r in zip(ys, probe, strict=True)]
            ax.errorbar(
                xs, ys, yerr=[lo, hi], fmt="o-", color="tab:grey", capsize=3, label="oracle, degraded"
            )
        for i, r in enumerate(x for x in rows if x["kind"] == "real"):
            y, (lo_, hi_) = r["metrics"][metric]["diff"], r["metrics"][metric]["diff_ci"]
            ax.errorbar(
                r["accuracy"][acc], y, yerr=[[y - lo_], [hi_ - y]], fmt="s", capsize=3, color=f"C{i}",
                label=_label(r),
            )  # fmt: skip
        ax.axhline(0.0, color="black", lw=0.6)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="best")
    fig.suptitle("Accuracy to value: paired differences to no prediction, 95 % intervals")
    fig.tight_layout()
    return figure_png(fig, dpi=100)
