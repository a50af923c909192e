"""Real data against simulation: the trajectory predictors on the simulator's own pedestrians.

Why: the predictors are trained and scored on ETH/UCY, but the env wrapper feeds them simulated
pedestrians. This module runs built-in scenarios, records every pedestrian's *true* position from the
world (``info["ground_truth"]``) every 0.4 s, cuts Social-GAN windows from those tracks (8 observed + 12
future frames, a window per start frame, pedestrians present in all 20, windows with >= 2 of them) and
scores the predictors on them with :func:`predictors.metrics.evaluate_one`, beside CVM.

The ego brakes and waits (``ACTION``); the pedestrians do not depend on which predictor is scored, so every
row sees the same windows. Learned rows use the wrapper's model (``s-cgru_all.pt``) and, for the other
kinds, their ``<kind>_zara1.pt`` checkpoints (trained on the other four scenes); ``dcvm`` uses the damped
CVM tuned on ZARA1's val split. ``python -m studies.sim_transfer --scenarios busy_zebra --episodes 4``
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import torch

from crossing_common.cadence import HISTORY_INTERVAL
from crossing_common.files import write_text_atomic
from predictors.data import OBS_LEN, PRED_LEN, Windows

FRAME_S = HISTORY_INTERVAL
"""Seconds between recorded frames (the datasets' rate)."""
SEQ = OBS_LEN + PRED_LEN
ACTION = -1.0
"""The ego brakes to a stop and waits: the episode then runs its full duration (at action 0 it ends once
the ego has passed, too soon for 8 s windows)."""


def record_tracks(scenario: object, seed: int) -> dict[int, dict[int, np.ndarray]]:
    """``{pedestrian id: {frame: (x, y)}}`` of one episode, one frame every 0.4 s of simulated time."""
    from crossing_env.env import CrossingEnv

    env = CrossingEnv(scenario)  # type: ignore[arg-type]
    _, info = env.reset(seed=seed)
    every = max(1, round(FRAME_S / env.config.dt))
    if abs(every * env.config.dt - FRAME_S) > 1e-6:
        raise ValueError(f"scenario dt {env.config.dt} s does not divide the 0.4 s frame")
    tracks: dict[int, dict[int, np.ndarray]] = {}
    step, action = 0, np.full(1, ACTION, np.float32)
    while True:
        if step % every == 0:
            gt = info["ground_truth"]
            for pid, pos in zip(gt.pedestrian_ids, gt.pedestrian_positions, strict=True):
                tracks.setdefault(int(pid), {})[step // every] = np.asarray(pos, dtype=np.float64)
        _, _, terminated, truncated, info = env.step(action)
        step += 1
        if terminated or truncated:
            break
    env.close()
    return tracks


def windows_from_tracks(tracks: dict[int, dict[int, np.ndarray]]) -> Windows:
    """Social-GAN windows (see module docstring) from recorded tracks."""
    if not tracks:
        return Windows(np.zeros((0, SEQ, 2), np.float32), np.zeros((0, 2), np.int64))
    last = max(max(f) for f in tracks.values())
    trajs: list[np.ndarray] = []
    sse: list[tuple[int, int]] = []
    for start in range(last - SEQ + 2):
        frames = range(start, start + SEQ)
        peds = [np.stack([t[f] for f in frames]) for t in tracks.values() if all(f in t for f in frames)]
        if len(peds) >= 2:
            sse.append((len(trajs), len(trajs) + len(peds)))
            trajs.extend(peds)
    if not trajs:
        return Windows(np.zeros((0, SEQ, 2), np.float32), np.zeros((0, 2), np.int64))
    return Windows(np.stack(trajs).astype(np.float32), np.asarray(sse, np.int64))


def simulated_windows(names: list[str], episodes: int, seed: int) -> Windows:
    """Windows of ``episodes`` seeded episodes of each built-in scenario in ``names``."""
    from scenarios import load_scenario

    parts = [
        windows_from_tracks(record_tracks(load_scenario(name), seed + e))
        for name in names
        for e in range(episodes)
    ]
    return Windows.concat(parts)


def predictors_for_sim(data_root: Path) -> dict[str, object]:
    """The rows of the table: name -> ``(obs, sse, k, gen) -> (most_likely, samples)``."""
    from predictors import damped
    from predictors.checkpoints import WEIGHTS_DIR, load_model
    from predictors.data import load_split
    from predictors.social_force_predictor import SocialForcePredictor
    from studies import evaluate

    rows: dict[str, object] = {}
    for name in ("cvm", "cvm-s", "kalman"):
        rows[name] = evaluate.make_predictor(name, "zara1", WEIGHTS_DIR)[0]
    d, _ = damped.tune(load_split(data_root, "zara1", "val"))
    rows["dcvm (zara1 val)"] = lambda o, s, k, g: (d.predict(o), d.sample(o, k, g))
    for qlb in (False, True):
        sf = SocialForcePredictor(qlb=qlb)
        rows["sf-qlb" if qlb else "sf"] = lambda o, s, k, g, sf=sf: (sf.predict(o, s), sf.sample(o, s, k, g))
    checkpoints = {"s-cgru_all (wrapper)": "s-cgru_all.pt"}
    checkpoints.update({f"{k}_zara1": f"{k}_zara1.pt" for k in ("s-cgru", "s-gru", "s-lstm", "lstm")})
    for label, file in checkpoints.items():
        if (WEIGHTS_DIR / file).is_file():
            m = load_model(WEIGHTS_DIR / file)
            rows[label] = lambda o, s, k, g, m=m: (m.predict(o, s), m.sample(o, s, k, g, "autoregressive"))
    return rows


def measure(names: list[str], episodes: int, seed: int, data_root: Path) -> dict[str, Any]:
    """Record the episodes, cut the windows and score every row: the JSON-ready result."""
    from predictors.metrics import evaluate_one

    if episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {episodes}")
    torch.set_num_threads(1)
    w = simulated_windows(names, episodes, seed)
    if w.num_windows == 0:
        raise ValueError("no window with >= 2 pedestrians for 8 s")
    res: dict[str, Any] = {"scenarios": names, "episodes": episodes, "seed": seed}
    res["counts"] = [w.num_windows, w.num_peds]
    res["results"] = {
        name: evaluate_one(fn, w, 20, seed) for name, fn in predictors_for_sim(data_root).items()
    }
    return res


def render(res: dict[str, Any]) -> str:
    """The markdown table of a :func:`measure` result."""
    n, peds = res["counts"]
    lines = [
        f"Simulated windows: {n} / pedestrian instances {peds} ({', '.join(res['scenarios'])},"
        f" {res['episodes']} episodes each, seeds {res['seed']}..{res['seed'] + res['episodes'] - 1})",
        "",
        "| Predictor | K=1 ADE/FDE | best-of-20 per ped | best-of-20 per scene | energy score |",
        "|---|---|---|---|---|",
    ]
    order = ["cvm", "cvm-s", "kalman", "dcvm (zara1 val)", "sf", "sf-qlb", "s-cgru_all (wrapper)"]
    names = sorted(res["results"], key=lambda n: (order.index(n) if n in order else len(order), n))
    for name in names:  # a fixed order: the stored JSON has sorted keys
        r = res["results"][name]
        lines.append(
            f"| {name} | {r['k1'][0]:.2f}/{r['k1'][1]:.2f} | {r['ped20'][0]:.2f}/{r['ped20'][1]:.2f}"
            f" | {r['scene20'][0]:.2f}/{r['scene20'][1]:.2f} | {r['es'][0]:.2f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Console entry point: record, score and print a markdown table (JSON with ``--save``)."""
    from predictors.data import default_data_root

    p = argparse.ArgumentParser(prog="python -m studies.sim_transfer", description=__doc__.splitlines()[0])
    p.add_argument("--scenarios", default="busy_zebra,zebra_case1")
    p.add_argument("--episodes", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--data", default="")
    p.add_argument("--save", default="")
    a = p.parse_args(argv)
    root = Path(a.data) if a.data else default_data_root()
    try:
        res = measure([s for s in a.scenarios.split(",") if s], a.episodes, a.seed, root)
    except (ValueError, FileNotFoundError) as exc:
        print(f"studies.sim_transfer: error: {exc}", file=sys.stderr)
        return 2
    if a.save:
        write_text_atomic(Path(a.save), json.dumps(res, indent=1))
    print(render(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
