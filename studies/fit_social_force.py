"""Fit the simulator's social-force parameters to real pedestrian windows, per scene (seed Case 2).

``python -m studies.fit_social_force [--scenes eth,...] [--windows 300]`` fits, per scene, the force
parameters of :data:`predictors.social_force_predictor.FIT_FIELDS` by coordinate search over
:data:`FIT_GRID` (most-likely ADE on a subsample of the train split), tunes the sample spread of the
default and of the fitted predictor on the val split, and saves both to
``predictors/social_force_fit.json`` (:data:`predictors.social_force_predictor.FIT_FILE`), where
``studies.evaluate`` reads its ``sf-fit`` rows. The predictor itself:
:class:`predictors.social_force_predictor.SocialForcePredictor`.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from crossing_common.files import write_text_atomic
from predictors.data import SCENES, Windows, default_data_root, iterate_batches, load_split
from predictors.social_force_predictor import FIT_FIELDS, FIT_FILE, SocialForcePredictor

FIT_GRID: dict[str, tuple[float, ...]] = {
    "relaxation_time": (0.1, 0.25, 0.5, 1.0, 2.0, 4.0),
    "base_strength": (0.0, 0.5, 2.0, 5.0, 10.0, 25.0, 50.0),
    "ped_range": (0.05, 0.1, 0.2, 0.3, 0.5, 0.8),
    "anisotropy": (0.0, 0.1, 0.3, 0.5, 1.0),
}
"""Coordinate-search grid of the fitted parameters (the simulator default is in every list)."""


def k1_ade(p: SocialForcePredictor, w: Windows, batch_peds: int = 4096) -> float:
    """Mean most-likely ADE of ``p`` over ``w``."""
    total, n = 0.0, 0
    for b in iterate_batches(w, batch_peds):
        total += float((p.predict(b.obs, b.seq_start_end) - b.fut).norm(dim=-1).mean(dim=1).sum())
        n += b.obs.shape[0]
    return total / max(n, 1)


def fit(base: SocialForcePredictor, train: Windows, sweeps: int = 2) -> tuple[SocialForcePredictor, float]:
    """Coordinate search over :data:`FIT_GRID` minimising most-likely ADE on ``train``; returns the fit."""
    best, best_ade = base, k1_ade(base, train)
    for _ in range(sweeps):
        changed = False
        for name, grid in FIT_GRID.items():
            for v in grid:
                cand = replace(best, force=replace(best.force, **{name: v}))
                if cand == best:
                    continue
                ade = k1_ade(cand, train)
                if ade < best_ade - 1e-6:
                    best, best_ade, changed = cand, ade, True
        if not changed:
            break
    return best, best_ade


def tune_heading_std(
    p: SocialForcePredictor,
    val: Windows,
    grid: tuple[float, ...] = (5.0, 10.0, 15.0, 20.0, 25.0),
    seed: int = 0,
) -> SocialForcePredictor:
    """``heading_std_deg`` with the best per-pedestrian best-of-20 ADE on ``val``."""
    best, best_ade = p, float("inf")
    for sd in grid:
        cand = replace(p, heading_std_deg=sd)
        total, n = 0.0, 0
        gen = torch.Generator().manual_seed(seed)
        for b in iterate_batches(val, 1024):
            err = (cand.sample(b.obs, b.seq_start_end, 20, gen) - b.fut).norm(dim=-1).mean(dim=-1)
            total += float(err.min(dim=0).values.sum())
            n += b.obs.shape[0]
        if total / n < best_ade:
            best, best_ade = cand, total / n
    return best


def every_nth(w: Windows, most: int) -> Windows:
    """At most ``most`` windows of ``w``, evenly spaced in time (deterministic subsample for fitting)."""
    return w.subset(np.unique(np.linspace(0, w.num_windows - 1, min(most, w.num_windows)).astype(int)))


def fit_scene(root: Path, scene: str, windows: int = 300) -> dict[str, object]:
    """Fit on a subsample of ``scene``'s train split, tune the sample spread on its val split; JSON-ready."""
    train = every_nth(load_split(root, scene, "train"), windows)
    val = every_nth(load_split(root, scene, "val"), windows)
    default = SocialForcePredictor()
    fitted, _ = fit(default, train)
    out: dict[str, object] = {"train_windows": train.num_windows, "val_windows": val.num_windows}
    for name, p in (("default", default), ("fit", fitted)):
        p = tune_heading_std(p, val)
        out[name] = {
            **{f: getattr(p.force, f) for f in FIT_FIELDS},
            "heading_std_deg": p.heading_std_deg,
            "train_ade": k1_ade(p, train),
            "val_ade": k1_ade(p, val),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    """``python -m studies.fit_social_force [--scenes eth,...] [--windows 300]``: fit and save per scene."""
    ap = argparse.ArgumentParser(prog="python -m studies.fit_social_force", description=fit_scene.__doc__)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--windows", type=int, default=300, help="train/val windows used (evenly spaced)")
    ap.add_argument("--data", default="")
    ap.add_argument("--save", default=str(FIT_FILE))
    a = ap.parse_args(argv)
    scenes = [s for s in a.scenes.split(",") if s]
    bad = [s for s in scenes if s not in (*SCENES, "sdd")]
    if bad or a.windows < 1:
        msg = f"--scenes {bad} not in {SCENES} or --windows {a.windows} < 1"
        print(f"studies.fit_social_force: error: {msg}", file=sys.stderr)
        return 2
    root = Path(a.data) if a.data else default_data_root()
    save = Path(a.save)
    res = json.loads(save.read_text()) if save.is_file() else {"scenes": {}}
    res["grid"] = {k: list(v) for k, v in FIT_GRID.items()}
    for scene in scenes:
        res["scenes"][scene] = fit_scene(root, scene, a.windows)
        print(scene, json.dumps(res["scenes"][scene]), flush=True)
        write_text_atomic(save, json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
