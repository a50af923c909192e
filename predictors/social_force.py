"""The simulator's social-force pedestrians run as a trajectory predictor on real windows (seed Case 2).

Song et al. (2022, Case 2) predict with a social-force model whose pedestrian intensity (0.42) is updated by
the QLB curve when others behave irrationally, and claim AVG ETH/UCY 0.32/0.63. This module runs *our*
simulator's model (:func:`crossing_env.pedestrians.social_force.walk_step`, the same compiled kernel the
environment steps) on each 8-step observation: the observed pedestrians of a window are simulated together,
each walking towards a goal straight ahead of its last observed heading at a desired speed equal to its mean
observed speed of the last ``speed_steps`` steps; pedestrians slower than ``STAND_SPEED`` stand still. The
window's other pedestrians are its only neighbours (no vehicles, no kerbs in the recordings). The same
run is therefore a realism score of the simulator's pedestrian motion against real data.

QLB variant: each pedestrian's intensity is :func:`crossing_env.pedestrians.behaviour.updated_ped_intensity`
of the fraction of its neighbours within 10 m who look irrational in the observation. The recordings carry no
"irrational" labels, so we use a proxy: running (last speed above ``RUN_SPEED``) or an abrupt turn (more
than ``TURN_DEG`` between the last two displacements while walking). This proxy is our choice.

Samples: each sample rotates a pedestrian's initial velocity and goal by one ``N(0, heading_std)`` angle
(CVM-S's perturbation, pushed through the interacting model); ``heading_std`` is tuned on val.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import torch

from crossing_env.pedestrians.behaviour import irrational_neighbour_fraction, updated_ped_intensity
from crossing_env.pedestrians.social_force import model_parameters, walk_step
from predictors.data import PRED_LEN, Windows, iterate_batches
from scenarios.config import SocialForceConfig

STEP_S = 0.4
"""Seconds between dataset frames."""
STAND_SPEED = 0.15
"""m/s: below this mean observed speed a pedestrian is simulated standing (desired speed 0)."""
RUN_SPEED = 2.0
"""m/s: observed speed above which a neighbour counts as irrational (running) for the QLB update."""
TURN_DEG = 45.0
"""Heading change between the last two displacements above which a walking neighbour counts as irrational."""
WINDOW_GAP = 1000.0
"""Metres between windows laid side by side in one kernel call, far beyond the force's reach."""


@dataclass(frozen=True)
class SocialForcePredictor:
    """Social-force predictor settings (the force parameters are the simulator's own config)."""

    force: SocialForceConfig = field(default_factory=SocialForceConfig)
    """Force parameters; the default is the simulator's default pedestrian model."""
    qlb: bool = False
    """Update each pedestrian's intensity by the QLB curve from its irrational-looking neighbours."""
    radius: float = 0.28
    """Body radius, metres (the simulator's population default)."""
    substeps: int = 4
    """Euler steps per 0.4 s frame (dt = 0.1 s, the simulator's step)."""
    speed_steps: int = 1
    """Observed displacements averaged for the desired speed (1: the last one, as CVM; 4 was worse on val)."""
    heading_std_deg: float = 15.0
    """Per-sample heading perturbation of velocity and goal, degrees."""

    def _setup(self, obs: np.ndarray, sse: np.ndarray) -> tuple[np.ndarray, ...]:
        n = obs.shape[0]
        group = np.repeat(np.arange(len(sse)), sse[:, 1] - sse[:, 0])
        offset = np.zeros((n, 2))
        offset[:, 0] = WINDOW_GAP * group
        pos = obs[:, -1].astype(np.float64) + offset
        disp = np.diff(obs[:, -self.speed_steps - 1 :].astype(np.float64), axis=1)
        speed = np.linalg.norm(disp, axis=-1).mean(axis=1) / STEP_S
        last = disp[:, -1]
        vel = last / STEP_S
        norm = np.linalg.norm(last, axis=-1)
        heading = np.where(norm[:, None] > 1e-6, last / np.maximum(norm, 1e-9)[:, None], 0.0)
        desired = np.where(speed >= STAND_SPEED, speed, 0.0)
        if self.qlb:
            frac = self._irrational_fraction(pos, np.diff(obs[:, -3:].astype(np.float64), axis=1))
            k_p = updated_ped_intensity(self.force.ped_intensity, frac)
        else:
            k_p = np.full(n, self.force.ped_intensity)
        return pos, vel, heading, desired, np.ascontiguousarray(k_p, dtype=np.float64), offset

    @staticmethod
    def _irrational_fraction(pos: np.ndarray, disp: np.ndarray) -> np.ndarray:
        """Per pedestrian, the fraction of window neighbours within 10 m that look irrational (proxy)."""
        speed_last = np.linalg.norm(disp[:, -1], axis=-1) / STEP_S
        a, b = disp[:, -2], disp[:, -1]
        na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
        cos = (a * b).sum(-1) / np.maximum(na * nb, 1e-12)
        walking = (na > 0.1 * STEP_S) & (nb > 0.1 * STEP_S)
        turn = walking & (cos < math.cos(math.radians(TURN_DEG)))
        irrational = (speed_last > RUN_SPEED) | turn
        return irrational_neighbour_fraction(pos, np.ones(len(pos), bool), irrational)

    def _simulate(
        self, pos: np.ndarray, vel: np.ndarray, heading: np.ndarray, desired: np.ndarray, k_p: np.ndarray
    ) -> np.ndarray:
        """``(N, 12, 2)`` positions after each frame, from the given state."""
        n = pos.shape[0]
        pos, vel = pos.copy(), vel.copy()
        reach = np.maximum(desired * PRED_LEN * STEP_S * 2.0, 10.0)
        goals = pos + heading * reach[:, None]
        rows = np.arange(n)
        radii = np.full(n, self.radius)
        stay = np.zeros(n, bool)
        boxes = np.zeros((0, 4))
        params = model_parameters(self.force)
        dt = STEP_S / self.substeps
        out = np.empty((n, PRED_LEN, 2))
        for t in range(PRED_LEN):
            for _ in range(self.substeps):
                walk_step(
                    rows, pos, vel, goals, desired, radii, stay, boxes, 0.0, 0.0, k_p, dt,
                    self.force.max_speed_factor, params,
                )  # fmt: skip
                pos += vel * dt
            out[:, t] = pos
        return out

    def predict(self, obs: torch.Tensor, seq_start_end: torch.Tensor) -> torch.Tensor:
        """Most-likely future ``(N, 12, 2)`` (the deterministic simulation)."""
        o, s = obs.double().numpy(), seq_start_end.numpy()
        pos, vel, heading, desired, k_p, offset = self._setup(o, s)
        fut = self._simulate(pos, vel, heading, desired, k_p) - offset[:, None]
        return torch.as_tensor(fut, dtype=obs.dtype)

    def sample(
        self, obs: torch.Tensor, seq_start_end: torch.Tensor, num_samples: int, generator: torch.Generator
    ) -> torch.Tensor:
        """``(S, N, 12, 2)``: every sample simulates the whole window with perturbed headings."""
        o, s = obs.double().numpy(), seq_start_end.numpy()
        pos, vel, heading, desired, k_p, offset = self._setup(o, s)
        n = pos.shape[0]
        ang = torch.randn((num_samples, n), generator=generator, dtype=torch.float64).numpy()
        ang = ang * math.radians(self.heading_std_deg)
        c, si = np.cos(ang)[..., None], np.sin(ang)[..., None]

        def rot(v: np.ndarray) -> np.ndarray:
            x, y = v[None, :, :1], v[None, :, 1:]
            return np.concatenate([c * x - si * y, si * x + c * y], -1)

        # All samples in one kernel call, sample k's windows laid out after sample k - 1's along x (the
        # kernel scans neighbours in x order, so copies stacked in y would all be scanned).
        shift = np.zeros((num_samples, 1, 2))
        shift[:, 0, 0] = WINDOW_GAP * (len(s) + 1) * np.arange(num_samples)
        fut = self._simulate(
            (pos[None] + shift).reshape(-1, 2),
            rot(vel).reshape(-1, 2),
            rot(heading).reshape(-1, 2),
            np.tile(desired, num_samples),
            np.tile(k_p, num_samples),
        ).reshape(num_samples, n, PRED_LEN, 2)
        return torch.as_tensor(fut - shift[:, :, None] - offset[None, :, None], dtype=obs.dtype)


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


FIT_FIELDS: tuple[str, ...] = tuple(FIT_GRID)


def fit_scene(root: object, scene: str, windows: int = 300) -> dict[str, object]:
    """Fit on a subsample of ``scene``'s train split, tune the sample spread on its val split; JSON-ready."""
    from predictors.data import load_split

    train = every_nth(load_split(root, scene, "train"), windows)  # type: ignore[arg-type]
    val = every_nth(load_split(root, scene, "val"), windows)  # type: ignore[arg-type]
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


def load_fit(path: object, scene: str, which: str) -> SocialForcePredictor:
    """The ``default`` or ``fit`` predictor of ``scene`` from a file written by :func:`main`."""
    import json
    from pathlib import Path

    entry = json.loads(Path(path).read_text())["scenes"][scene][which]  # type: ignore[arg-type]
    force = replace(SocialForceConfig(), **{f: float(entry[f]) for f in FIT_FIELDS})
    return SocialForcePredictor(force=force, heading_std_deg=float(entry["heading_std_deg"]))


FIT_FILE = __import__("pathlib").Path(__file__).resolve().parent / "social_force_fit.json"


def main(argv: list[str] | None = None) -> int:
    """``python -m predictors.social_force [--scenes eth,...] [--windows 300]``: fit and save per scene."""
    import argparse
    import json
    import sys
    from pathlib import Path

    from crossing_common.files import write_text_atomic
    from predictors.data import SCENES, default_data_root

    ap = argparse.ArgumentParser(prog="python -m predictors.social_force", description=fit_scene.__doc__)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--windows", type=int, default=300, help="train/val windows used (evenly spaced)")
    ap.add_argument("--data", default="")
    ap.add_argument("--save", default=str(FIT_FILE))
    a = ap.parse_args(argv)
    scenes = [s for s in a.scenes.split(",") if s]
    bad = [s for s in scenes if s not in (*SCENES, "sdd")]
    if bad or a.windows < 1:
        msg = f"--scenes {bad} not in {SCENES} or --windows {a.windows} < 1"
        print(f"predictors.social_force: error: {msg}", file=sys.stderr)
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
