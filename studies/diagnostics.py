"""What the shipped networks actually predict: K = 1 speed and heading against CVM, and their learned sigma.

``python -m studies.diagnostics`` prints, per checkpoint, on (at most 300 evenly spaced windows of) its
scene's test split: the median and 10th/90th percentiles of the ratio of the most-likely path's mean speed
to CVM's speed, the median angle between the most-likely path's final displacement and CVM's, and the
median predicted sigma (geometric mean of sigma_x, sigma_y, m per 0.4 s step) over the 12 future steps.
Pedestrians slower than 0.1 m per step are left out of the ratios (their heading is undefined).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import torch

from predictors.baselines import cvm
from predictors.checkpoints import WEIGHTS_DIR, load_model
from predictors.data import default_data_root, load_split, to_batch
from predictors.models import gaussian_params
from studies.fit_social_force import every_nth


@torch.no_grad()
def diagnose(path: Path, data_root: Path, windows: int = 300) -> dict[str, float]:
    """The quantities of the module docstring for one checkpoint."""
    model = load_model(path)
    scene = path.stem.split("_", 1)[1]
    split = "val" if scene == "all" else "test"
    w = every_nth(load_split(data_root, "eth" if scene == "all" else scene, split), windows)
    b = to_batch(w)
    raw, ml = model.rollout(b.obs, b.seq_start_end)
    base = cvm(b.obs)
    last = b.obs[:, -1]
    v_cvm = (b.obs[:, -1] - b.obs[:, -2]).norm(dim=-1)
    moving = v_cvm > 0.1
    v_ml = (ml[:, -1] - last).norm(dim=-1) / ml.shape[1]
    ratio = (v_ml / v_cvm.clamp_min(1e-9))[moving].numpy()
    a, c = ml[:, -1] - last, base[:, -1] - last
    cos = (a * c).sum(-1) / (a.norm(dim=-1) * c.norm(dim=-1)).clamp_min(1e-9)
    angle = torch.rad2deg(torch.arccos(cos.clamp(-1.0, 1.0)))[moving].numpy()
    _, sigma, _ = gaussian_params(raw[:, -ml.shape[1] :])
    sig = torch.sqrt(sigma[..., 0] * sigma[..., 1]).median().item()
    p10, p50, p90 = np.percentile(ratio, [10, 50, 90]) if ratio.size else (math.nan,) * 3
    return {
        "speed_ratio_median": float(p50),
        "speed_ratio_p10": float(p10),
        "speed_ratio_p90": float(p90),
        "heading_change_median_deg": float(np.median(angle)) if angle.size else math.nan,
        "sigma_median": float(sig),
        "sample_scale": float(model.config.sample_scale),
    }


def main(argv: list[str] | None = None) -> int:
    """Console entry point: one markdown row per shipped checkpoint."""
    p = argparse.ArgumentParser(prog="python -m studies.diagnostics", description=__doc__.splitlines()[0])
    p.add_argument("--data", default="")
    p.add_argument("--windows", type=int, default=300)
    a = p.parse_args(argv)
    torch.set_num_threads(1)
    root = Path(a.data) if a.data else default_data_root()
    print(
        "| Checkpoint | K=1 speed / CVM speed, median [p10, p90] | heading change, median"
        " | median σ (m/step) |"
    )
    print("|---|---|---|---|")
    for path in sorted(WEIGHTS_DIR.glob("*.pt")):
        d = diagnose(path, root, a.windows)
        print(
            f"| {path.name} | {d['speed_ratio_median']:.2f} [{d['speed_ratio_p10']:.2f},"
            f" {d['speed_ratio_p90']:.2f}] | {d['heading_change_median_deg']:.1f}°"
            f" | {d['sigma_median']:.2f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
