"""Mean ± sd over training seeds of `predictors.evaluate` results, and the verdict against a baseline.

Run ``python -m predictors.seed_table SEED0.json SEED1.json ... [--baseline dcvm] [--model s-cgru]``, where
each file is ``python -m predictors.evaluate --save`` output for checkpoints trained with one seed (the
same protocol and sample seed in every file). The table gives, per scene, the model's K = 1 and best-of-20
(per pedestrian) ADE/FDE and energy score as mean ± sample sd over the files, the baseline's values (the
mean over the files, as it has no training seed), and whether the model beats the baseline by more than
the seed sd on K = 1 ADE and on best-of-20 ADE, as issue #15's target asks.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from predictors.data import SCENES

ROWS: tuple[tuple[str, int, str], ...] = (
    ("k1", 0, "K=1 ADE"),
    ("k1", 1, "K=1 FDE"),
    ("ped20", 0, "best-of-20 ADE"),
    ("ped20", 1, "best-of-20 FDE"),
    ("es", 0, "energy score"),
)


def _values(runs: list[dict], model: str, scene: str, metric: str, i: int) -> np.ndarray:
    vals = []
    for r in runs:
        entry = r["results"].get(model, {}).get(scene, {})
        if metric in entry:
            vals.append(float(entry[metric][i]))
    return np.asarray(vals)


def table(runs: list[dict], model: str, baseline: str) -> tuple[str, int]:
    """Markdown table and the number of ETH/UCY scenes where the model beats the baseline as asked."""
    head = "| scene | metric | " + f"{model} (mean ± sd, n seeds) | {baseline} | difference |"
    lines = [head, "|---|---|---|---|---|"]
    wins = 0
    for scene in SCENES:
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
        if len(beats) == 2 and all(beats):
            wins += 1
    return "\n".join(lines), wins


def main(argv: list[str] | None = None) -> int:
    """Console entry point."""
    p = argparse.ArgumentParser(prog="python -m predictors.seed_table", description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+", help="predictors.evaluate --save JSON, one per training seed")
    p.add_argument("--model", default="s-cgru")
    p.add_argument("--baseline", default="dcvm")
    a = p.parse_args(argv)
    runs = []
    for f in a.files:
        try:
            runs.append(json.loads(Path(f).read_text()))
        except (OSError, json.JSONDecodeError) as exc:
            print(f"predictors.seed_table: error: {f}: {exc}", file=sys.stderr)
            return 2
    text, wins = table(runs, a.model, a.baseline)
    print(text)
    print(
        f"\n{a.model} beats {a.baseline} by more than the seed sd at K=1 ADE and best-of-20 ADE on "
        f"{wins} of {len(SCENES)} ETH/UCY scenes (target: >= 4)."
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
