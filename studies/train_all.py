"""Train every model kind on every leave-one-out scene (and SDD) at once, one process per run.

Run: ``python -m studies.train_all [--jobs 16] [--minutes 3] [--out-dir DIR] [--models ...] [--scenes ...]
[--hidden-size 128 --embed-size 64] [--seeds 0,1,2] [--train-fraction 1 --patience 8 --lr-plateau 3]``.

With ``--seeds`` every run is repeated per seed into ``<out-dir>/seed<k>/`` (evaluate each folder with
``studies.evaluate --weights-dir ... --save``, then ``studies.seed_table`` gives mean ± sd).

Each run is one :func:`predictors.train.train` with one torch thread and its own wall-clock budget, so
a machine with ``jobs`` free cores trains the whole table in about ``ceil(runs / jobs)`` budgets. A run's
output (its traceback too, if it fails) goes to ``<log-dir>/<model>_<scene>.log``; a failed run is
reported and the others go on. Ctrl-C cancels the runs not yet started.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import sys
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from pathlib import Path

from predictors.checkpoints import WEIGHTS_DIR, checkpoint_meta, is_shipped, update_manifest
from predictors.data import SCENES
from predictors.models import MODEL_KINDS
from predictors.train import TrainConfig, train


def _run(cfg: TrainConfig, log: Path) -> str:
    """One training run in a worker process, its output to ``log``; a one-line summary."""
    with log.open("w") as f, contextlib.redirect_stdout(f), contextlib.redirect_stderr(f):
        try:
            out = train(cfg)
        except BaseException:
            traceback.print_exc(file=f)
            raise
    meta = checkpoint_meta(out)
    return (
        f"{out.name}: epochs {meta.get('epochs_run')}, best {meta.get('best_epoch')}, val ADE/FDE "
        f"{float(meta['val_ade']):.3f}/{float(meta['val_fde']):.3f}, scale {meta.get('sample_scale')}, "
        f"{meta.get('wall_s')} s"
    )


def main(argv: list[str] | None = None) -> int:
    """Console entry point."""
    p = argparse.ArgumentParser(prog="python -m studies.train_all", description=__doc__.splitlines()[0])
    p.add_argument("--models", default=",".join(MODEL_KINDS), help=f"comma list from {MODEL_KINDS}")
    p.add_argument("--scenes", default=",".join((*SCENES, "sdd")), help="comma list of training scenes")
    p.add_argument("--jobs", type=int, default=2, help="runs at once (one torch thread each)")
    p.add_argument("--minutes", type=float, default=TrainConfig.max_minutes, help="budget of each run")
    p.add_argument(
        "--out-dir", default="runs/train_all/weights", help="where the checkpoints go (default: %(default)s)"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help=f"allow --out-dir to be the shipped {WEIGHTS_DIR} (replaces those files, updates the manifest)",
    )
    p.add_argument("--log-dir", default="runs/train_all", help="where each run's log goes")
    p.add_argument("--data", default="", help="data root (default $CROSSING_DATA or ../shared/data)")
    p.add_argument("--hidden-size", type=int, default=TrainConfig.hidden_size)
    p.add_argument("--embed-size", type=int, default=TrainConfig.embed_size)
    p.add_argument("--seed", type=int, default=TrainConfig.seed)
    p.add_argument(
        "--seeds",
        default="",
        help="comma list of seeds: every run once per seed, into <out-dir>/seed<k>/ (overrides --seed)",
    )
    p.add_argument("--epochs", type=int, default=TrainConfig.epochs, help="maximum epochs of each run")
    p.add_argument(
        "--train-fraction", type=float, default=TrainConfig.train_fraction, help="share of windows per epoch"
    )
    p.add_argument("--rotate", type=int, default=TrainConfig.rotate, help="1: random-rotation augmentation")
    p.add_argument("--patience", type=int, default=TrainConfig.patience, help="early-stopping patience")
    p.add_argument(
        "--lr-plateau", type=int, default=TrainConfig.lr_plateau, help="halve lr after N flat epochs"
    )
    a = p.parse_args(argv)
    models = [m for m in a.models.split(",") if m]
    scenes = [s for s in a.scenes.split(",") if s]
    problems = [f"--models: unknown {m!r}" for m in models if m not in MODEL_KINDS]
    problems += [f"--scenes: unknown {s!r}" for s in scenes if s not in (*SCENES, "sdd", "all")]
    problems += [f"--jobs must be >= 1, got {a.jobs}"] if a.jobs < 1 else []
    try:
        seeds = [int(k) for k in a.seeds.split(",") if k.strip()]
    except ValueError:
        seeds = []
        problems.append(f"--seeds must be a comma list of integers, got {a.seeds!r}")
    if seeds and is_shipped(Path(a.out_dir) / "x.pt"):
        problems.append("--seeds writes one folder per seed: choose an --out-dir outside predictors/weights")
    if problems:
        print(f"studies.train_all: error: {'; '.join(problems)}", file=sys.stderr)
        return 2
    out_dir, log_dir = Path(a.out_dir), Path(a.log_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    log_dir.mkdir(parents=True, exist_ok=True)
    base = TrainConfig(
        data=a.data,
        max_minutes=a.minutes,
        hidden_size=a.hidden_size,
        embed_size=a.embed_size,
        seed=a.seed,
        epochs=a.epochs,
        train_fraction=a.train_fraction,
        patience=a.patience,
        lr_plateau=a.lr_plateau,
        rotate=a.rotate,
        threads=1,
    )
    runs: dict[str, TrainConfig] = {}
    for k in seeds or [None]:  # no --seeds: one run each, base seed, straight into --out-dir
        folder, prefix = (out_dir, "") if k is None else (out_dir / f"seed{k}", f"seed{k}_")
        for s in scenes:
            for m in models:
                cfg = replace(base, model=m, scene=s, out=str(folder / f"{m}_{s}.pt"), force=a.force)
                runs[f"{prefix}{m}_{s}"] = cfg if k is None else replace(cfg, seed=k)
    failed = 0
    context = multiprocessing.get_context("spawn")  # no forked torch/numba thread state in the workers
    pool = ProcessPoolExecutor(max_workers=a.jobs, mp_context=context)
    try:
        futures = {pool.submit(_run, cfg, log_dir / f"{name}.log"): name for name, cfg in runs.items()}
        for fut in as_completed(futures):
            name = futures[fut]
            try:
                print(fut.result(), flush=True)
            except Exception as exc:  # report every failed run, keep the others
                failed += 1
                print(f"{name}: FAILED ({type(exc).__name__}: {exc}); see {log_dir / name}.log", flush=True)
    except KeyboardInterrupt:
        pool.shutdown(wait=False, cancel_futures=True)
        print("interrupted: runs not yet started were cancelled", file=sys.stderr)
        return 130
    pool.shutdown()
    if is_shipped(out_dir / "x.pt"):
        # Runs in parallel processes each updated their own entry; one final pass leaves no lost update.
        update_manifest([p.name for p in sorted(out_dir.glob("*.pt"))])
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
