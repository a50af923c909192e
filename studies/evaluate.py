"""Evaluate every predictor on the ETH/UCY leave-one-out test scenes and SDD.

Run ``python -m studies.evaluate [--json]``.

Protocol and metrics (``k1``, ``ped20``, ``scene20``, ``es``): :mod:`predictors.metrics`; whole test
recordings.

Baselines tuned on val only: ``dcvm`` (damped CVM + persistent Gaussian velocity offset,
:mod:`predictors.damped`, ``(d, s)`` per scene, chosen for best-of-20) and ``k1-ref``, the K = 1
comparator (the better on val of CVM and a damped CVM whose damping is chosen for K = 1 ADE; its samples
are its point repeated). Social-force rows
(:mod:`predictors.social_force_predictor`): ``sf`` and ``sf-qlb`` use the simulator's default parameters
(classical / QLB-updated intensity), ``sf-fit`` and ``sf-fit-qlb`` the parameters fitted on the scene's
train split (``predictors/social_force_fit.json``, written by :mod:`studies.fit_social_force`).

Learned models use ``predictors/weights/<kind>_<scene>.pt`` (trained on that scene's ``train/`` split,
selected on ``val/``). Their 20 samples are drawn from the model's own predictive distribution, per step and
autoregressively (each drawn displacement is fed back, as Social-LSTM and Social-GAN sample), with the
learned sigma unscaled. ``<kind>+persist`` is the most-likely path plus one persistent draw per sample
through each step's Gaussian, sigma unscaled: every step's displacement is drawn from the Gaussian the
network was trained to output (the model's predictive distribution, see
:meth:`predictors.models.SocialRecurrent.sample`). ``<kind>+corr`` is the same with sigma multiplied by the
``sample_scale`` tuned on val for best-of-20. For SDD,
``<kind>_sdd.pt`` is used if present, else ``<kind>_all.pt`` (trained on all ETH/UCY recordings: a
cross-dataset result, flagged in the output). SDD glitch steps are not filtered.
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
from predictors import damped
from predictors import social_force_predictor as social_force
from predictors.baselines import cvm, cvm_samples, kalman_predict, kalman_samples
from predictors.checkpoints import WEIGHTS_DIR, load_model, weights_for
from predictors.data import SCENES, default_data_root, load_split
from predictors.metrics import EVAL_SCENES, METRICS, Predictor, evaluate_one
from predictors.models import MODEL_KINDS

BASELINES: tuple[str, ...] = ("cvm", "cvm-s", "kalman", "dcvm", "k1-ref")
SOCIAL_FORCE: tuple[str, ...] = ("sf", "sf-qlb", "sf-fit", "sf-fit-qlb")
PERSISTENT: tuple[str, ...] = tuple(f"{k}+persist" for k in MODEL_KINDS)
CORRELATED: tuple[str, ...] = tuple(f"{k}+corr" for k in MODEL_KINDS)
ALL_MODELS: tuple[str, ...] = (*BASELINES, *SOCIAL_FORCE, *MODEL_KINDS, *PERSISTENT, *CORRELATED)


def make_predictor(
    name: str, scene: str, weights_dir: Path, data_root: Path | None = None
) -> tuple[Predictor | None, str]:
    """A function ``(obs, seq_start_end, k, generator) -> (most_likely, samples)`` and its source label.

    ``data_root`` is needed by ``dcvm`` and ``k1-ref``, which are tuned on the scene's val split here.
    """
    if name in ("dcvm", "k1-ref"):
        if data_root is None:
            raise ValueError(f"{name} needs the data root to tune on the val split")
        val = load_split(data_root, scene, "val")
        if name == "k1-ref":
            p, _ = damped.tune_k1(val)
            label = "cvm" if p.damping == 1.0 else f"d={p.damping:g}"
            return (lambda o, s, k, g: (p.predict(o), p.predict(o)[None].expand(k, -1, -1, -1))), label
        p, _ = damped.tune(val)
        return (lambda o, s, k, g: (p.predict(o), p.sample(o, k, g))), f"d={p.damping:g} s={p.spread:g}"
    if name in SOCIAL_FORCE:
        fitted = name.startswith("sf-fit")
        try:
            sf = social_force.load_fit(social_force.FIT_FILE, scene, "fit" if fitted else "default")
        except (FileNotFoundError, KeyError):
            if fitted:
                return None, "no fit"
            sf = social_force.SocialForcePredictor()
        sf = replace(sf, qlb=name.endswith("qlb"))
        label = ", ".join(f"{k}={getattr(sf.force, k):g}" for k in social_force.FIT_FIELDS)
        return (lambda o, s, k, g: (sf.predict(o, s), sf.sample(o, s, k, g))), label
    if name == "cvm":
        return (lambda o, s, k, g: (cvm(o), cvm(o)[None].expand(k, -1, -1, -1))), "-"
    if name == "cvm-s":
        return (lambda o, s, k, g: (cvm(o), cvm_samples(o, k, g))), "sigma=25deg"
    if name == "kalman":
        return (lambda o, s, k, g: (kalman_predict(o), kalman_samples(o, k, g))), "-"
    kind, _, variant = name.partition("+")
    mode = "autoregressive" if not variant else "correlated"
    scale = 1.0 if variant == "persist" else None
    path = weights_for(kind, scene, weights_dir)
    if path is None:
        return None, "no weights"
    model = load_model(path)
    return (lambda o, s, k, g: (model.predict(o, s), model.sample(o, s, k, g, mode, scale))), path.name


def run(
    data_root: Path,
    models: list[str],
    scenes: list[str],
    num_samples: int = 20,
    seed: int = 0,
    weights_dir: Path = WEIGHTS_DIR,
) -> dict[str, object]:
    """Evaluate ``models`` on ``scenes``; return a JSON-ready dict ``results[model][scene][metric]``.

    A scene's sample seed is ``seed + 1000 * k``, ``k`` its place in :data:`EVAL_SCENES` (not in
    ``scenes``), so a scene evaluated alone or in parallel parts gives the numbers of the full run.
    """
    results: dict[str, dict[str, object]] = {}
    counts: dict[str, list[int]] = {}
    for scene in scenes:
        si = EVAL_SCENES.index(scene)
        w = load_split(data_root, scene, "test")
        counts[scene] = [w.num_windows, w.num_peds]
        for name in models:
            pred, source = make_predictor(name, scene, weights_dir, data_root)
            entry: dict[str, object] = {"weights": source}
            if pred is not None:
                entry.update(evaluate_one(pred, w, num_samples, seed + 1000 * si))
            results.setdefault(name, {})[scene] = entry
            print(f"{name:7s} {scene:6s} {entry}", file=sys.stderr)
    return {
        "protocol": "sgan-windows-8-12",
        "num_samples": num_samples,
        "seed": seed,
        "counts": counts,
        "results": results,
    }


def with_average(res: dict[str, object]) -> dict[str, object]:
    """Add an ``avg`` entry (mean over the five ETH/UCY scenes) per model where all five are present."""
    for entries in res["results"].values():  # type: ignore[union-attr]
        if all(s in entries and "k1" in entries[s] for s in SCENES):
            entries["avg"] = {
                m: [float(np.mean([entries[s][m][i] for s in SCENES])) for i in (0, 1)] for m in METRICS
            }
    return res


def to_markdown(res: dict[str, object]) -> str:
    """Markdown tables, one per metric."""
    titles = {
        "k1": "Most likely (K = 1)",
        "ped20": "Best-of-20, per pedestrian (ADE and FDE minimised separately)",
        "scene20": "Best-of-20, per scene (Social-GAN `evaluate_model.py` style)",
        "es": "Energy score of the 20 samples (fair form; m, lower is better; proper scoring rule)",
    }
    results: dict[str, dict[str, dict]] = res["results"]  # type: ignore[assignment]
    cols = [*SCENES, "avg", "sdd"]
    lines = []
    dagger = False
    for m in METRICS:
        lines += [f"### {titles[m]}", "", "| Model | " + " | ".join(c.upper() for c in cols) + " |"]
        lines.append("|---" * (len(cols) + 1) + "|")
        for name, entries in results.items():
            cells = []
            for c in cols:
                e = entries.get(c, {})
                if m in e:
                    flag = "†" if c == "sdd" and str(e.get("weights", "")).endswith("_all.pt") else ""
                    dagger = dagger or bool(flag)
                    cells.append(
                        f"{e[m][0]:.2f}{flag}" if m == "es" else f"{e[m][0]:.2f}/{e[m][1]:.2f}{flag}"
                    )
                else:
                    cells.append("–")
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    counts = res.get("counts", {})
    lines.append(
        "Test windows / pedestrian instances: " + ", ".join(f"{s} {c[0]}/{c[1]}" for s, c in counts.items())
    )
    if dagger:
        lines += ["", "† SDD evaluated with the model trained on all ETH/UCY recordings (cross-dataset)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Console entry point."""
    p = argparse.ArgumentParser(prog="python -m studies.evaluate", description=__doc__.splitlines()[0])
    p.add_argument("--data", default="", help="data root (default $CROSSING_DATA or <repo>/../shared/data)")
    p.add_argument("--models", default=",".join(ALL_MODELS), help=f"comma list from {ALL_MODELS}")
    p.add_argument("--scenes", default=",".join(EVAL_SCENES), help=f"comma list from {EVAL_SCENES}")
    p.add_argument("--samples", type=int, default=20, help="K for best-of-K")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--weights-dir", default=str(WEIGHTS_DIR))
    p.add_argument("--json", action="store_true", help="print JSON instead of markdown")
    p.add_argument("--save", default="", help="also write the JSON results to this file")
    p.add_argument("--merge", nargs="*", default=None, help="merge saved JSON files instead of evaluating")
    p.add_argument("--threads", type=int, default=1)
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    try:
        if a.merge is not None:
            res: dict[str, object] = {"results": {}, "counts": {}}
            for f in a.merge:
                part = json.loads(Path(f).read_text())
                res["counts"].update(part["counts"])  # type: ignore[union-attr]
                for name, entries in part["results"].items():
                    res["results"].setdefault(name, {}).update(entries)  # type: ignore[union-attr]
                res.update({k: part[k] for k in ("protocol", "num_samples", "seed") if k in part})
        else:
            models = [m for m in a.models.split(",") if m]
            scenes = [s for s in a.scenes.split(",") if s]
            for m in models:
                if m not in ALL_MODELS:
                    raise ValueError(f"--models: unknown model {m!r}; choose from {ALL_MODELS}")
            for s in scenes:
                if s not in EVAL_SCENES:
                    raise ValueError(f"--scenes: unknown scene {s!r}; choose from {EVAL_SCENES}")
            root = Path(a.data) if a.data else default_data_root()
            res = run(root, models, scenes, a.samples, a.seed, Path(a.weights_dir))
    except (ValueError, FileNotFoundError) as exc:
        print(f"studies.evaluate: error: {exc}", file=sys.stderr)
        return 2
    res = with_average(res)
    if a.save:
        write_text_atomic(Path(a.save), json.dumps(res, indent=1))
    print(json.dumps(res, indent=1) if a.json else to_markdown(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
