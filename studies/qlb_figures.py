"""Reproduce the crossing-intention figures of Song et al. (2022) with our QLB library.

``python -m studies.qlb_figures --out DIR`` writes

* ``fig03_cbm_far.png``, ``fig05_cbm_mid.png``, ``fig07_cbm_near.png``: the classical model's P(cross)
  over the two lane beliefs (planes);
* ``fig04_qlb_far.png``, ``fig06_qlb_mid.png``, ``fig08_qlb_near.png``: the QLB model's P(cross) with the
  similarity heuristic (irregular surfaces), the classical plane drawn as a grey wireframe;
* ``fig10_update_ped_ped.png``, ``fig11_update_vehicle_ped.png``: the force-intensity update curves for
  the classically calibrated 0.42 (pedestrian-pedestrian) and 0.71 (vehicle-pedestrian) intensities.

The figure numbers follow Song et al. (2022); which of Figures 3-8 shows which case is our reading (CBM and
QLB alternating for the far, mid and near cases). The CPTs and the force-update mapping are our design
(see :mod:`predictors.qlb`), so the shapes, not the exact values, are comparable with the paper.
Rendering uses matplotlib's Agg canvas through the object API, without touching the global backend.
Each PNG is written to a temporary file in the output folder and moved into place.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from crossing_common.files import atomic_output
from crossing_env.pedestrians.force_update import (
    PED_PED_INTENSITY,
    VEHICLE_PED_INTENSITY,
    ForceUpdateConfig,
    classical_updated_force_intensity,
    updated_force_intensity,
)
from predictors.qlb import (
    CASES,
    ZONE_BELIEF,
    cbm_cross_probability,
    qlb_cross_probability,
)

__all__ = ["FigureArgs", "main", "make_figures"]

_SURFACE_FIGURES = {"far": (3, 4), "mid": (5, 6), "near": (7, 8)}
"""Figure numbers (CBM, QLB) per distance case."""


@dataclass(frozen=True)
class FigureArgs:
    """Command-line options of ``python -m studies.qlb_figures``."""

    out: Path
    """Output folder; created if missing; must not be an existing file."""
    grid: int = 61
    """Grid points per belief axis for the surfaces."""
    dpi: int = 100
    """Resolution of the PNGs (dots per inch)."""


def _save(fig: Figure, path: Path, dpi: int) -> None:
    """Write a figure atomically: temporary file in the target folder, then ``os.replace``."""
    FigureCanvasAgg(fig)
    with atomic_output(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)


def _surface_figure(case: str, model: str, grid: int) -> Figure:
    """P(cross) over the two lane beliefs for one case, classical or QLB."""
    beliefs = np.linspace(0.0, 1.0, grid)
    b1, b2 = np.meshgrid(beliefs, beliefs, indexing="ij")
    cbm = cbm_cross_probability(b1, b2, case)
    z = cbm if model == "cbm" else qlb_cross_probability(b1, b2, case)
    fig = Figure(figsize=(6.4, 5.2))
    ax = fig.add_subplot(projection="3d")
    ax.plot_surface(b1, b2, z, cmap="viridis", vmin=0.0, vmax=1.0, linewidth=0, antialiased=True, alpha=0.9)
    if model == "qlb":
        step = max(1, grid // 10)
        ax.plot_wireframe(b1, b2, cbm, rstride=step, cstride=step, color="0.4", linewidth=0.5, label="CBM")
    anchors = np.array(sorted(set(ZONE_BELIEF.values())))
    a1, a2 = np.meshgrid(anchors, anchors, indexing="ij")
    za = cbm_cross_probability(a1, a2, case) if model == "cbm" else qlb_cross_probability(a1, a2, case)
    ax.scatter(
        a1.ravel(), a2.ravel(), za.ravel(), color="red", s=18, depthshade=False, label="belief 0/0.5/1"
    )
    ax.set_xlabel("belief lane 1 safe")
    ax.set_ylabel("belief lane 2 safe")
    ax.set_zlabel("P(cross)")
    ax.set_zlim(0.0, 1.0)
    ax.legend(loc="upper left", fontsize=8)
    label = "classical Bayesian model (CBM)" if model == "cbm" else "quantum-like Bayesian model (QLB)"
    fig.suptitle(f"{label}, car {case}")
    return fig


def _update_figure(base: float, title: str) -> Figure:
    """Force intensity against the observed fraction of irrational behaviour: base, classical, QLB."""
    cfg = ForceUpdateConfig()
    frac = np.linspace(0.0, 1.0, 201)
    fig = Figure(figsize=(6.4, 4.4))
    ax = fig.add_subplot()
    ax.axhline(base, color="0.5", linestyle=":", label=f"classical calibration {base:.2f}")
    ax.plot(frac, classical_updated_force_intensity(base, frac, cfg), "--", label="classical update")
    ax.plot(frac, updated_force_intensity(base, frac, config=cfg), "-", linewidth=2, label="QLB update")
    ax.set_xlabel("observed fraction of irrational behaviour of others")
    ax.set_ylabel("social-force intensity")
    ax.set_xlim(0.0, 1.0)
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title(f"{title} (theta = {cfg.heuristic_phase():.3f} rad)")
    return fig


def make_figures(args: FigureArgs) -> list[Path]:
    """Render every figure into ``args.out``.

    Args:
        args: Output folder and rendering options.

    Returns:
        The written PNG paths.
    """
    args.out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for case in CASES:
        for model, number in zip(("cbm", "qlb"), _SURFACE_FIGURES[case], strict=True):
            path = args.out / f"fig{number:02d}_{model}_{case}.png"
            _save(_surface_figure(case, model, args.grid), path, args.dpi)
            written.append(path)
    for number, base, name, title in (
        (10, PED_PED_INTENSITY, "ped_ped", "pedestrian-pedestrian intensity update"),
        (11, VEHICLE_PED_INTENSITY, "vehicle_ped", "vehicle-pedestrian intensity update"),
    ):
        path = args.out / f"fig{number:02d}_update_{name}.png"
        _save(_update_figure(base, title), path, args.dpi)
        written.append(path)
    return written


def _parse(argv: Sequence[str] | None) -> FigureArgs:
    """Parse and check the command line; errors exit with status 2 and name the bad value."""
    parser = argparse.ArgumentParser(
        prog="python -m studies.qlb_figures", description="Write the QLB crossing figures (PNG)."
    )
    parser.add_argument("--out", type=Path, required=True, help="output folder (created if missing)")
    parser.add_argument("--grid", type=int, default=FigureArgs.grid, help="grid points per belief axis")
    parser.add_argument("--dpi", type=int, default=FigureArgs.dpi, help="PNG resolution")
    ns = parser.parse_args(argv)
    out: Path = ns.out
    if out.exists() and not out.is_dir():
        parser.error(f"--out {str(out)!r} exists and is not a directory")
    if not 5 <= ns.grid <= 401:
        parser.error(f"--grid must be in [5, 401], got {ns.grid}")
    if not 20 <= ns.dpi <= 600:
        parser.error(f"--dpi must be in [20, 600], got {ns.dpi}")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        parser.error(f"--out {str(out)!r} cannot be created: {exc.strerror or exc}")
    if not os.access(out, os.W_OK):
        parser.error(f"--out {str(out)!r} is not writable")
    return FigureArgs(out=out, grid=ns.grid, dpi=ns.dpi)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit status."""
    args = _parse(argv)
    for path in make_figures(args):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
