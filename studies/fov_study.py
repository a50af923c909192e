"""Field-of-view study of S-CGRU's pooling sector: per scene, per angle, several seeds, val ADE with 95 % CIs.

Why a separate study: one short run per angle (the old sweep) cannot separate an optimum from run-to-run
noise. Here every (scene, angle, seed) run has the same fixed budget in *epochs* (not minutes, so the
result does not depend on the machine's load), model selection on the val split as in ``crossing-train``,
and the table reports the mean val ADE over seeds with a Student-t 95 % interval (``scipy.stats``). The
test split is never read.

``python -m studies.fov_study --scenes eth,hotel --seeds 3 --epochs 4 --save runs/fov.json`` (the short
budget: 4 epochs of 25 % of the windows); ``--epochs 40 --train-fraction 1 --patience 6 --lr-plateau 3``
trains every run to convergence as ``studies.train_all`` does. Each row carries CVM's ADE on the same
val split, the bar a trained model has to clear.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from crossing_common.files import write_text_atomic
from predictors.baselines import cvm
from predictors.checkpoints import checkpoint_meta
from predictors.data import SCENES, default_data_root, load_split, to_batch
from predictors.metrics import EVAL_SCENES, errors
from predictors.train import TrainConfig, train

DEFAULT_FOVS: tuple[float, ...] = (60.0, 85.0, 120.0, 180.0, 360.0)
SEED_PAPER_FOV: dict[str, float] = {"eth": 85.0, "hotel": 75.0, "univ": 135.0, "sdd": 120.0}
"""Xu et al. 2023, Table 3: the per-scene optimum the seed paper reports (picked on test)."""


def mean_ci(values: list[float], level: float = 0.95) -> tuple[float, float]:
    """Mean and half-width of the Student-t interval of the mean (``nan`` half-width for one value)."""
    x = np.asarray(values, dtype=float)
    if x.size < 2:
        return float(x.mean()), float("nan")
    half = float(stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size))
    return float(x.mean()), half


BUDGET_KEYS: tuple[str, ...] = ("epochs", "train_fraction", "patience", "lr_plateau")
"""What a resumed study must share with the saved one (older files lack the last two: 0, 0)."""


def cvm_val_ade(scene: str, data: Path) -> float:
    """Constant velocity's most-likely ADE on the scene's val split: the bar every run has to clear."""
    b = to_batch(load_split(data, scene, "val"))
    return float(errors(cvm(b.obs), b.fut)[0].mean())


def run_one(scene: str, fov: float, seed: int, budget: dict[str, float], data: Path, out: Path) -> dict:
    """Train one S-CGRU with this sector and seed; return its selected val ADE/FDE and epochs."""
    cfg = TrainConfig(
        model="s-cgru",
        scene=scene,
        epochs=int(budget["epochs"]),
        seed=seed,
        max_minutes=0.0,
        train_fraction=float(budget["train_fraction"]),
        patience=int(budget.get("patience", 0)),
        lr_plateau=int(budget.get("lr_plateau", 0)),
        fov_deg=fov,
        data=str(data),
        out=str(out),
    )
    train(cfg)
    meta = checkpoint_meta(out)
    return {
        "val_ade": meta["val_ade"],
        "val_fde": meta["val_fde"],
        "best_epoch": meta["best_epoch"],
        "wall_s": meta["wall_s"],
    }


def to_markdown(res: dict[str, object]) -> str:
    """One row per scene: mean val ADE ± 95 % half-width per angle, the best angle, the seed's angle, CVM."""
    runs: dict[str, dict[str, list[dict]]] = res["runs"]  # type: ignore[assignment]
    cvm_ade: dict[str, float] = res.get("cvm_val_ade", {})  # type: ignore[assignment]
    listed = {float(f) for f in res["fovs"]}  # type: ignore[union-attr]
    fovs = sorted(listed | {float(f) for per_fov in runs.values() for f in per_fov})
    lines = [
        "| Scene | "
        + " | ".join(f"{f:.0f}°" for f in fovs)
        + " | best (mean) | all CIs overlap best? | seed Table 3 | CVM (val) |",
        "|---" * (len(fovs) + 5) + "|",
    ]
    for scene, per_fov in runs.items():
        cells, means = [], {}
        for f in fovs:
            vals = [r["val_ade"] for r in per_fov.get(str(f), [])]
            if not vals:
                cells.append("–")
                continue
            m, h = mean_ci(vals)
            means[f] = (m, h)
            cells.append(f"{m:.3f} ± {h:.3f} (n={len(vals)})")
        if means:
            best = min(means, key=lambda f: means[f][0])
            bm, bh = means[best]
            overlap = all(abs(m - bm) <= h + bh for f, (m, h) in means.items() if f != best)
            unknown = any(np.isnan(h) for _, h in means.values())
            best_cell = f"{best:.0f}°"
            overlap_cell = "n/a (n < 2)" if unknown else ("yes" if overlap else "no")
        else:
            best_cell = overlap_cell = "–"
        seed = SEED_PAPER_FOV.get(scene)
        seed_cell = f"{seed:.0f}°" if seed else "–"
        cvm_cell = f"{cvm_ade[scene]:.3f}" if scene in cvm_ade else "–"
        tail = f" | {best_cell} | {overlap_cell} | {seed_cell} | {cvm_cell} |"
        lines.append(f"| {scene} | " + " | ".join(cells) + tail)
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Console entry point; results are saved after every run, so an interrupted study keeps what ran."""
    p = argparse.ArgumentParser(prog="python -m studies.fov_study", description=__doc__.splitlines()[0])
    p.add_argument("--scenes", default=",".join(SCENES))
    p.add_argument("--fovs", default=",".join(f"{f:g}" for f in DEFAULT_FOVS))
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--epochs", type=int, default=4, help="epochs of --train-fraction of the train windows")
    p.add_argument("--train-fraction", type=float, default=0.25)
    p.add_argument("--patience", type=int, default=0, help="early stopping on val ADE (0: every epoch)")
    p.add_argument("--lr-plateau", type=int, default=0, help="halve the lr after N flat epochs (0: never)")
    p.add_argument("--data", default="")
    p.add_argument("--save", default="runs/fov_study.json")
    p.add_argument("--report", action="store_true", help="print the table of --save without training")
    a = p.parse_args(argv)
    save = Path(a.save)
    try:
        if a.report:
            print(to_markdown(json.loads(save.read_text())))
            return 0
        scenes = [s for s in a.scenes.split(",") if s]
        fovs = [float(f) for f in a.fovs.split(",") if f]
        for s in scenes:
            if s not in EVAL_SCENES:
                raise ValueError(f"--scenes: unknown scene {s!r}; choose from {EVAL_SCENES}")
        for f in fovs:
            if not 0.0 < f <= 360.0:
                raise ValueError(f"--fovs: angle {f} outside (0, 360]")
        if a.seeds < 1 or a.epochs < 1:
            raise ValueError(f"--seeds and --epochs must be >= 1, got {a.seeds}, {a.epochs}")
        if a.patience < 0 or a.lr_plateau < 0:
            raise ValueError(f"--patience and --lr-plateau must be >= 0, got {a.patience}, {a.lr_plateau}")
        budget = {"epochs": a.epochs, "train_fraction": a.train_fraction}
        budget |= {"patience": a.patience, "lr_plateau": a.lr_plateau}
        res: dict[str, object] = {**budget, "fovs": fovs, "seeds": a.seeds, "runs": {}, "cvm_val_ade": {}}
        if save.is_file():  # resume: add to an earlier study with the same budget, every scene kept
            old = json.loads(save.read_text())
            if not isinstance(old, dict) or not isinstance(old.get("runs"), dict):
                raise ValueError(
                    f"{save}: not a field-of-view study (no field 'runs'); choose another --save"
                )
            for k in BUDGET_KEYS:
                if old.get(k, 0) != budget[k]:
                    raise ValueError(
                        f"{save}: field {k!r} is {old.get(k, 0)!r} there but {budget[k]!r} here; a study "
                        "keeps one budget, so choose another --save"
                    )
            res["runs"] = old["runs"]
            res["cvm_val_ade"] = old.get("cvm_val_ade", {})
            res["fovs"] = sorted({*map(float, old.get("fovs", [])), *fovs})
        data = Path(a.data) if a.data else default_data_root()
        res["cvm_val_ade"] |= {s: cvm_val_ade(s, data) for s in scenes}  # type: ignore[operator]
    except (ValueError, FileNotFoundError, json.JSONDecodeError) as exc:
        print(f"studies.fov_study: error: {exc}", file=sys.stderr)
        return 2
    runs: dict[str, dict[str, list[dict]]] = res["runs"]  # type: ignore[assignment]
    write_text_atomic(save, json.dumps(res, indent=1))  # a resumed study gains the CVM column at once
    ckpt = save.with_suffix(".pt")
    for seed in range(a.seeds):  # seeds outermost: an interrupted study still has every angle
        for scene in scenes:
            for fov in fovs:
                if any(r["seed"] == seed for r in runs.get(scene, {}).get(str(fov), [])):
                    continue
                r = run_one(scene, fov, seed, budget, data, ckpt)
                runs.setdefault(scene, {}).setdefault(str(fov), []).append({"seed": seed, **r})
                print(f"fov {scene} {fov:g} seed {seed}: {r}", file=sys.stderr, flush=True)
                write_text_atomic(save, json.dumps(res, indent=1))
    print(to_markdown(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
