"""Train a trajectory predictor (``crossing-train`` / ``python -m predictors.train``).

Training uses the ``train/`` split of a leave-one-out scene (or of SDD, or ``all`` = the union of the
ETH/UCY ``_train`` files of every recording), with random-rotation augmentation, Adam and teacher-forced
bivariate Gaussian NLL. Model selection uses the ``val/`` split only (most-likely ADE after each epoch);
the test split is never read here.

The run writes into a hidden file beside ``--out`` and moves it over ``--out`` only once it is finished
(`predictors.checkpoints.install_checkpoint`): an interrupted or failed run leaves the previous file, and
for ``--force`` over a shipped checkpoint its manifest entry, untouched. Checkpoint format, saving and
loading: `predictors.checkpoints` (``load_model``, ``save_checkpoint`` and ``checkpoint_meta`` are also
importable from here).
"""

from __future__ import annotations

import argparse
import ast
import inspect
import itertools
import sys
import textwrap
import time
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from crossing_common.cli import DefaultsHelpFormatter
from predictors.checkpoints import (
    CHECKPOINT_FORMAT,
    WEIGHTS_DIR,
    CheckpointError,
    checkpoint_meta,
    install_checkpoint,
    is_shipped,
    load_model,
    partial_path,
    save_checkpoint,
)
from predictors.data import (
    SCENES,
    Windows,
    default_data_root,
    iterate_batches,
    load_files,
    split_files,
    to_batch,
)
from predictors.models import MODEL_KINDS, SocialRecurrent, default_config

__all__ = [
    "CHECKPOINT_FORMAT",
    "RUNS_DIR",
    "SCALE_GRID",
    "WEIGHTS_DIR",
    "TrainConfig",
    "checkpoint_meta",
    "load_model",
    "load_training_data",
    "main",
    "most_likely_ade",
    "output_path",
    "parse_args",
    "save_checkpoint",
    "train",
]

RUNS_DIR = Path("runs")
"""Default folder (relative to the working directory) of the checkpoints `crossing-train` writes."""


@dataclass(frozen=True)
class TrainConfig:
    """Command-line arguments of ``crossing-train``."""

    model: str = "s-cgru"
    """Model kind: s-cgru, s-gru, s-lstm or lstm."""
    scene: str = "all"
    """Leave-one-out scene (eth, hotel, univ, zara1, zara2), ``sdd``, or ``all`` (every ETH/UCY recording)."""
    epochs: int = 20
    """Maximum number of epochs (an epoch is ``train_fraction`` of the training windows)."""
    seed: int = 0
    """Seed of torch and of the numpy generator that shuffles and rotates batches."""
    data: str = ""
    """Data root with ``eth_ucy/`` and ``sdd/`` (default: ``$CROSSING_DATA`` or ``../shared/data``)."""
    out: str = ""
    """Checkpoint path (default: runs/<model>_<scene>.pt); predictors/weights/ needs --force."""
    force: bool = False
    """Allow --out to replace a shipped checkpoint (its manifest entry is then updated)."""
    lr: float = 5e-4
    """Adam learning rate."""
    batch_peds: int = 256
    """Pedestrian budget per batch (whole windows)."""
    train_fraction: float = 0.25
    """Fraction of training windows drawn (without replacement) each epoch, to fit a CPU budget."""
    max_minutes: float = 3.0
    """Wall-clock budget for the whole run (0 = none); training stops after the epoch that exceeds it."""
    fov_deg: float = 120.0
    """Field of view of S-CGRU's pooling sector, degrees."""
    grad_clip: float = 1.0
    """Gradient-norm clip."""
    threads: int = 1
    """torch intra-op threads (1 on the shared 2-core machine)."""
    hidden_size: int = 128
    """Real width of the recurrent state (S-CGRU: twice its complex units); 128 as in the papers."""
    embed_size: int = 64
    """Width of the displacement and social-tensor embeddings; 64 as in the papers."""
    cv_residual: int = 1
    """1: learned models predict a correction to the last displacement (constant-velocity prior)."""
    nll_beta: float = 1.0
    """beta of the beta-NLL loss (0 = plain Gaussian NLL); see ``models.bivariate_nll``."""
    teacher_forcing: int = 0
    """1: feed the ground truth back during the future steps (Social-LSTM); 0: feed the predicted means."""
    patience: int = 0
    """Early stopping: stop after this many epochs without a better val ADE (0 = run every epoch)."""
    lr_plateau: int = 0
    """Halve the learning rate after this many epochs without a better val ADE (0 = constant rate):
    the val ADE of a constant 5e-4 swings by ±0.05 m from epoch to epoch, so it never settles."""
    rotate: int = 1
    """1: rotate each training batch by a random angle (augmentation the protocol allows); 0: no rotation."""


def _union_split(root: Path, split: str) -> Windows:
    files: dict[str, Path] = {}
    for s in SCENES:
        for f in split_files(root, s, split):
            files.setdefault(f.name, f)
    return load_files(list(files.values()))


def load_training_data(root: Path, scene: str) -> tuple[Windows, Windows]:
    """Train and val windows of ``scene`` (``all`` = union of every recording's train/val parts)."""
    if scene == "all":
        return _union_split(root, "train"), _union_split(root, "val")
    return load_files(split_files(root, scene, "train")), load_files(split_files(root, scene, "val"))


@torch.no_grad()
def most_likely_ade(model: SocialRecurrent, w: Windows, batch_peds: int = 2048) -> tuple[float, float]:
    """Mean ADE and FDE of the most-likely prediction over all pedestrians of ``w``."""
    model.eval()
    ade, fde, n = 0.0, 0.0, 0
    for b in iterate_batches(w, batch_peds):
        err = (model.predict(b.obs, b.seq_start_end) - b.fut).norm(dim=-1)
        ade += float(err.mean(dim=1).sum())
        fde += float(err[:, -1].sum())
        n += err.shape[0]
    return ade / max(n, 1), fde / max(n, 1)


SCALE_GRID: tuple[float, ...] = (0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0)


@torch.no_grad()
def _calibrate(
    model: SocialRecurrent, val_w: Windows, num_samples: int = 20, seed: int = 0
) -> dict[str, float]:
    """Set ``sample_scale`` from :data:`SCALE_GRID` by best-of-20 ADE on val; returns the metadata it adds.

    Why: in our few-minute runs the Gaussian head's sigma barely moves from its initial 1 m per step, so
    raw samples are far too spread; a single post-hoc scale fixes that without touching the test split.
    """
    gen_seed = seed
    best_scale, best_ade = 1.0, float("inf")
    b = to_batch(val_w)
    for scale in SCALE_GRID:
        model.config = replace(model.config, sample_scale=scale)
        s = model.sample(b.obs, b.seq_start_end, num_samples, torch.Generator().manual_seed(gen_seed))
        ade = float((s - b.fut).norm(dim=-1).mean(dim=-1).min(dim=0).values.mean())
        if ade < best_ade:
            best_scale, best_ade = scale, ade
    model.config = replace(model.config, sample_scale=best_scale)
    return {"sample_scale": best_scale, "val_ped20_ade": best_ade}


def output_path(cfg: TrainConfig) -> Path:
    """Where `train` writes: ``--out`` or ``runs/<model>_<scene>.pt``; never a shipped file without --force.

    Raises:
        ValueError: ``--out`` names a shipped checkpoint and ``--force`` is not given.
    """
    out = Path(cfg.out) if cfg.out else RUNS_DIR / f"{cfg.model}_{cfg.scene}.pt"
    if is_shipped(out) and not cfg.force:
        raise ValueError(
            f"--out {out} would replace a shipped checkpoint (the env's wrappers load these); give another"
            " path, or --force to replace it and update its manifest entry"
        )
    return out


def train(cfg: TrainConfig) -> Path:
    """Train one model; return the checkpoint path. Model selection on val ADE only.

    The checkpoint is written to a hidden file beside the output path and moved over it only when the
    run has finished (with the manifest entry of a shipped file): on any error or interrupt the previous
    file stays as it was and the hidden file is removed.
    """
    if cfg.model not in MODEL_KINDS:
        raise ValueError(f"--model must be one of {MODEL_KINDS}, got {cfg.model!r}")
    if cfg.scene not in (*SCENES, "sdd", "all"):
        raise ValueError(f"--scene must be one of {(*SCENES, 'sdd', 'all')}, got {cfg.scene!r}")
    if cfg.epochs < 1:
        raise ValueError(f"--epochs must be >= 1, got {cfg.epochs}")
    if not 0.0 < cfg.train_fraction <= 1.0:
        raise ValueError(f"--train-fraction must be in (0, 1], got {cfg.train_fraction}")
    if cfg.rotate not in (0, 1):
        raise ValueError(f"--rotate must be 0 or 1, got {cfg.rotate}")
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    root = Path(cfg.data) if cfg.data else default_data_root()
    train_w, val_w = load_training_data(root, cfg.scene)
    out = output_path(cfg)
    work = partial_path(out)
    try:
        return _train(cfg, train_w, val_w, rng, out, work)
    finally:
        work.unlink(missing_ok=True)


def _train(
    cfg: TrainConfig, train_w: Windows, val_w: Windows, rng: np.random.Generator, out: Path, work: Path
) -> Path:
    """The training run of :func:`train`, writing into ``work``; installs it as ``out`` at the end."""
    mcfg = replace(
        default_config(cfg.model, cfg.fov_deg),
        hidden_size=cfg.hidden_size,
        embed_size=cfg.embed_size,
        cv_residual=bool(cfg.cv_residual),
    )
    model = SocialRecurrent(mcfg)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    plateau = (
        torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=cfg.lr_plateau - 1)
        if cfg.lr_plateau > 0
        else None
    )
    best = (float("inf"), float("inf"))
    best_epoch, t0, windows_seen = -1, time.time(), 0
    history: list[dict[str, float]] = []
    n_take = max(1, round(cfg.train_fraction * train_w.num_windows))
    for epoch in range(cfg.epochs):
        model.train()
        sub = train_w.subset(np.sort(rng.choice(train_w.num_windows, n_take, replace=False)))
        batches = list(iterate_batches(sub, cfg.batch_peds, rng=rng, rotate=bool(cfg.rotate)))
        total = 0.0
        bar = tqdm(batches, desc=f"{cfg.model} {cfg.scene} epoch {epoch + 1}/{cfg.epochs}", leave=False)
        for b in bar:
            loss = model.loss(b.obs, b.fut, b.seq_start_end, bool(cfg.teacher_forcing), cfg.nll_beta)
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            opt.step()
            total += loss.item()
            bar.set_postfix(nll=f"{loss.item():.3f}")
        windows_seen += sub.num_windows
        val = most_likely_ade(model, val_w)
        history.append(
            {"epoch": epoch + 1, "train_nll": total / len(batches), "val_ade": val[0], "val_fde": val[1]}
        )
        print(
            f"epoch {epoch + 1}: train nll {total / len(batches):.3f}  val ADE/FDE {val[0]:.3f}/{val[1]:.3f}"
        )
        if val[0] < best[0]:
            best, best_epoch = val, epoch + 1
            meta = {
                "scene": cfg.scene,
                "seed": cfg.seed,
                "best_epoch": best_epoch,
                "val_ade": val[0],
                "val_fde": val[1],
                "train_windows": train_w.num_windows,
                "train_fraction": cfg.train_fraction,
                "lr": cfg.lr,
                "batch_peds": cfg.batch_peds,
                "teacher_forcing": cfg.teacher_forcing,
                "nll_beta": cfg.nll_beta,
                "cv_residual": cfg.cv_residual,
                "rotate": cfg.rotate,
                "patience": cfg.patience,
                "lr_plateau": cfg.lr_plateau,
            }
            save_checkpoint(work, model, meta)
        if plateau is not None:
            plateau.step(val[0])
        if cfg.max_minutes and time.time() - t0 > 60.0 * cfg.max_minutes:
            print(f"time budget of {cfg.max_minutes} min reached after epoch {epoch + 1}")
            break
        if cfg.patience and epoch + 1 - best_epoch >= cfg.patience:
            print(f"early stop: no better val ADE for {cfg.patience} epochs (best epoch {best_epoch})")
            break
    if best_epoch < 0:
        vals = [h["val_ade"] for h in history]
        raise ValueError(f"no epoch gave a finite val ADE ({vals}); {out} left as it was")
    # Record the full budget and the sample scale in the selected checkpoint, then put it in place.
    final = load_model(work, verify_manifest=False)
    meta = checkpoint_meta(work)
    meta.update(
        {
            "epochs_run": len(history),
            "windows_seen": windows_seen,
            "wall_s": round(time.time() - t0, 1),
            "threads": cfg.threads,
            "history": history,
        }
    )
    meta.update(_calibrate(final, val_w))
    scale = final.config.sample_scale
    save_checkpoint(work, final, meta)
    install_checkpoint(work, out)
    print(f"saved {out} (best epoch {best_epoch}, val ADE/FDE {best[0]:.3f}/{best[1]:.3f}), scale {scale}")
    return out


def _field_docs(cls: type) -> dict[str, str]:
    """The docstring under each field of a dataclass (CleanRL `Args` style), read from its source."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body
    docs = {}
    for node, nxt in itertools.pairwise(body):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(nxt, ast.Expr)
            and isinstance(nxt.value, ast.Constant)
        ):
            docs[node.target.id] = " ".join(str(nxt.value.value).split())
    return docs


def parse_args(argv: list[str] | None = None) -> TrainConfig:
    """Parse command-line arguments into a :class:`TrainConfig` (help texts are the fields' docstrings)."""
    p = argparse.ArgumentParser(
        prog="crossing-train",
        description=__doc__.splitlines()[0].replace("``", ""),
        epilog=f"models: {', '.join(MODEL_KINDS)}; scenes: {', '.join((*SCENES, 'sdd', 'all'))}",
        formatter_class=DefaultsHelpFormatter,
    )
    d = TrainConfig()
    docs = _field_docs(TrainConfig)
    choices = {"model": MODEL_KINDS, "scene": (*SCENES, "sdd", "all")}
    for f in fields(TrainConfig):
        default = getattr(d, f.name)
        text = docs.get(f.name, "").replace("``", "").replace("%", "%%")
        flag = f"--{f.name.replace('_', '-')}"
        if isinstance(default, bool):
            p.add_argument(flag, action="store_true", help=text)
        else:
            # Choices shown, checked by `train` (exit 2 with the value named, like every other bad value).
            names = choices.get(f.name)
            metavar = "{" + ",".join(names) + "}" if names else None
            p.add_argument(flag, type=type(default), default=default, metavar=metavar, help=text)
    return TrainConfig(**vars(p.parse_args(argv)))


def main(argv: list[str] | None = None) -> int:
    """Console entry point; returns a non-zero exit status on bad input."""
    cfg = parse_args(argv)
    try:
        train(cfg)
    except (ValueError, FileNotFoundError, CheckpointError) as exc:
        print(f"crossing-train: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
