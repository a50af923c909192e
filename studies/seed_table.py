"""Mean ± sd over training seeds of `studies.evaluate` results, and the verdict against a baseline.

Run ``python -m studies.seed_table SEED0.json SEED1.json ... [--models s-cgru,s-gru] [--baseline dcvm]``,
where each file is ``python -m studies.evaluate --save`` output for checkpoints trained with one seed (the
same protocol and sample seed in every file). It prints, first, one summary row per model (the baselines
too) with the ETH/UCY AVG and SDD as mean ± sample sd over the files — the AVG is taken within each file, so
its sd is the seed-to-seed spread of the average; then, per model, a per-scene table of K = 1 and
best-of-20 (per pedestrian) ADE/FDE and energy score against the baseline (the baseline's mean over the
files, as it has no training seed), and whether the model beats the baseline by more than the seed sd on
K = 1 ADE and on best-of-20 ADE on each ETH/UCY scene, as issue #15's target asks.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from predictors.checkpoints import checkpoint_meta
from predictors.data import SCENES
from predictors.metrics import EVAL_SCENES

ROWS: tuple[tuple[str, int, str], ...] = (
    ("k1", 0, "K=1 ADE"),
    ("k1", 1, "K=1 FDE"),
    ("ped20", 0, "best-of-20 ADE"),
    ("ped20", 1, "best-of-20 FDE"),
    ("es", 0, "energy score"),
)
SUMMARY: tuple[tuple[str, str], ...] = (
    ("k1", "K = 1"),
    ("ped20", "best-of-20 per ped."),
    ("scene20", "best-of-20 per scene"),
    ("es", "energy score"),
)


def _values(runs: list[dict], model: str, scene: str, metric: str, i: int) -> np.ndarray:
    vals = []
    for r in runs:
        entry = r["results"].get(model, {}).get(scene, {})
        if metric in entry:
            vals.append(float(entry[metric][i]))
    return np.asarray(vals)


def _avg_values(runs: list[dict], model: str, metric: str, i: int) -> np.ndarray:
    """Per file, the mean over the five ETH/UCY scenes (files missing a scene are left out)."""
    vals = []
    for r in runs:
        entries = [r["results"].get(model, {}).get(s, {}) for s in SCENES]
        if all(metric in e for e in entries):
            vals.append(float(np.mean([e[metric][i] for e in entries])))
    return np.asarray(vals)


def _mean_sd(v: np.ndarray, digits: int = 3) -> str:
    if not v.size:
        return "–"
    if v.size == 1:
        return f"{v[0]:.{digits}f} (1)"
    if np.all(v == v[0]):  # a baseline: no training seed, the same value in every file
        return f"{v[0]:.{digits}f}"
    return f"{v.mean():.{digits}f} ± {v.std(ddof=1):.{digits}f}"


def _pair(runs: list[dict], model: str, scene: str, metric: str) -> str:
    get = (
        (lambda i: _avg_values(runs, model, metric, i))
        if scene == "avg"
        else (lambda i: _values(runs, model, scene, metric, i))
    )
    if metric == "es":
        return _mean_sd(get(0))
    ade, fde = get(0), get(1)
    return "–" if not ade.size else f"{_mean_sd(ade)} / {_mean_sd(fde)}"


def summary(runs: list[dict], models: list[str]) -> str:
    """Markdown: one row per model, ETH/UCY AVG and SDD, mean ± sd over the files (plain: no spread)."""
    avg = " | ".join(f"AVG {label}" for _, label in SUMMARY)
    head = f"| model | {avg} | SDD K = 1 | SDD best-of-20 |"
    lines = [head, "|" + "---|" * (len(SUMMARY) + 3)]
    for m in models:
        cells = [_pair(runs, m, "avg", metric) for metric, _ in SUMMARY]
        cells += [_pair(runs, m, "sdd", "k1"), _pair(runs, m, "sdd", "ped20")]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def table(runs: list[dict], model: str, baseline: str) -> tuple[str, int]:
    """Markdown table and the number of ETH/UCY scenes where the model beats the baseline as asked."""
    head = "| scene | metric | " + f"{model} (mean ± sd, n seeds) | {baseline} | difference |"
    lines = [head, "|---|---|---|---|---|"]
    wins = 0
    for scene in EVAL_SCENES:
        beats = []
        for metric, i, label in ROWS:
            m = _values(runs, model, scene, metric, i)
            b = _values(runs, baseline, scene, metric, i)
            if not m.size or not b.size:
                continue
            sd = float(m.std(ddof=1)) if m.size > 1 else float("nan")
            diff = float(m.mean() - b.mean())
            if label in ("K=1 ADE", "best-of-20 ADE"):
                beats.append(diff < 0 and abs(diff) > (sd if np.isfinite(sd) else 0.0))
            lines.append(
                f"| {scene} | {label} | {m.mean():.3f} ± {sd:.3f} ({m.size}) | {b.mean():.3f} | {diff:+.3f} |"
            )
        if scene in SCENES and len(beats) == 2 and all(beats):
            wins += 1
    return "\n".join(lines), wins


def _finished_runs(folder: Path) -> list[tuple[str, str, dict]]:
    """(model, scene, metadata) of every checkpoint in ``folder/seed*/`` whose run has finished."""
    runs = []
    for ckpt in sorted(folder.glob("seed*/*.pt")):
        meta = checkpoint_meta(ckpt)
        if "epochs_run" in meta:  # a run still training has saved only its best epoch so far
            model, scene = ckpt.stem.split("_", 1)
            runs.append((model, scene, meta))
    return runs


def budget_table(folder: Path) -> str:
    """Markdown: per model, the training budget its checkpoints in ``folder/seed*/`` record.

    A run "stopped early" when its last epoch came ``patience`` epochs after its best; otherwise it was
    stopped by the clock (or ran every epoch), and may have had more to give.
    """
    per_model: dict[str, list[dict]] = {}
    for model, _, meta in _finished_runs(folder):
        per_model.setdefault(model, []).append(meta)
    lines = [
        "| model | runs | stopped early | epochs run | best epoch | wall s per run | wall s in all |",
        "|---|---|---|---|---|---|---|",
    ]
    for model, metas in per_model.items():
        early = sum(m["epochs_run"] - m["best_epoch"] >= max(1, m.get("patience", 0)) for m in metas)
        epochs = [m["epochs_run"] for m in metas]
        best = [m["best_epoch"] for m in metas]
        wall = [float(m["wall_s"]) for m in metas]
        lines.append(
            f"| {model} | {len(metas)} | {early} | {min(epochs)}–{max(epochs)} | {min(best)}–{max(best)} | "
            f"{min(wall):.0f}–{max(wall):.0f} | {sum(wall):.0f} |"
        )
    return "\n".join(lines)


def val_table(folder: Path) -> str:
    """Markdown: per model and scene, the selected val ADE of the checkpoints in ``folder/seed*/``.

    The number model selection saw, so two studies (an ablation) can be compared without reading test.
    """
    vals: dict[tuple[str, str], list[float]] = {}
    for model, scene, meta in _finished_runs(folder):
        vals.setdefault((model, scene), []).append(float(meta["val_ade"]))
    lines = ["| model | scene | val ADE (mean ± sd) | seeds |", "|---|---|---|---|"]
    for (model, scene), v in sorted(vals.items()):
        lines.append(f"| {model} | {scene} | {_mean_sd(np.asarray(v))} | {len(v)} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Console entry point."""
    p = argparse.ArgumentParser(prog="python -m studies.seed_table", description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="*", help="studies.evaluate --save JSON, one per training seed")
    p.add_argument("--models", default="s-cgru", help="comma list of the trained models to tabulate")
    p.add_argument("--baseline", default="dcvm")
    p.add_argument("--summary-only", action="store_true", help="print only the one-row-per-model summary")
    p.add_argument("--budget", default="", help="instead: the training budget of DIR/seed*/*.pt")
    p.add_argument("--val", default="", help="instead: the selected val ADE of DIR/seed*/*.pt")
    a = p.parse_args(argv)
    for flag, folder, make in (("--budget", a.budget, budget_table), ("--val", a.val, val_table)):
        if folder:
            if not list(Path(folder).glob("seed*/*.pt")):
                print(f"studies.seed_table: error: {flag}: no {folder}/seed*/*.pt", file=sys.stderr)
                return 2
            print(make(Path(folder)))
            return 0
    if not a.files:
        print("studies.seed_table: error: give evaluate JSON files (or --budget/--val DIR)", file=sys.stderr)
        return 2
    runs = []
    for f in a.files:
        try:
            runs.append(json.loads(Path(f).read_text()))
        except (OSError, json.JSONDecodeError) as exc:
            print(f"studies.seed_table: error: {f}: {exc}", file=sys.stderr)
            return 2
    models = [m for m in a.models.split(",") if m]
    present = {m for r in runs for m in r.get("results", {})}
    missing = [m for m in (*models, a.baseline) if m not in present]
    if missing:
        err = f"studies.seed_table: error: --models/--baseline: {missing} not in any file"
        print(err, file=sys.stderr)
        return 2
    baselines = [b for b in ("cvm", "cvm-s", "kalman", "dcvm", "k1-ref") if b in present and b not in models]
    print(summary(runs, [*baselines, *models]))
    if a.summary_only:
        return 0
    for model in models:
        text, wins = table(runs, model, a.baseline)
        print(f"\n{text}")
        print(
            f"\n{model} beats {a.baseline} by more than the seed sd at K=1 ADE and best-of-20 ADE on "
            f"{wins} of {len(SCENES)} ETH/UCY scenes (target: >= 4)."
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
