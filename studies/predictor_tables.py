"""The trajectory-predictor tables of the docs, measured from the shipped weights (no training needed).

``python -m benchmarks.results predictors`` runs :func:`measure`: every row of :data:`MODELS` on every test
scene through :func:`studies.evaluate.run` (sample seed 0, the scene's own seed offset, so the numbers equal
``python -m studies.evaluate --models ... --scenes ...``), in parallel processes over (scene, model) pairs.
It writes ``benchmarks/results/predictors.json``; :func:`render_results` and :func:`render_summary` render it
into ``predictors/RESULTS.md`` and ``docs/predictors.md``, findings included, so no figure is typed by hand.
:func:`fingerprint` says when the JSON no longer describes the code: it hashes the shipped weights' manifest,
the social-force fit and a tiny fixed evaluation of every row.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from functools import cache
from pathlib import Path
from typing import Any

import torch

from predictors.checkpoints import WEIGHTS_DIR
from predictors.data import SCENES, Windows, default_data_root, load_split
from predictors.metrics import EVAL_SCENES, evaluate_one
from predictors.models import MODEL_KINDS
from predictors.social_force_predictor import FIT_FILE
from studies.evaluate import CORRELATED, PERSISTENT, make_predictor, run, with_average

MODELS: tuple[str, ...] = (
    "cvm",
    "cvm-s",
    "kalman",
    "dcvm",
    "k1-ref",
    "sf",
    "sf-qlb",
    "sf-fit",
    *MODEL_KINDS,
    *PERSISTENT,
    *CORRELATED,
)
"""The rows of the tables (``studies.evaluate`` names)."""
NETWORKS: tuple[str, ...] = MODEL_KINDS
"""The learned models, each with three sampling rows."""
LABELS: dict[str, str] = {
    "cvm": "CVM",
    "cvm-s": "CVM-S",
    "kalman": "Kalman filter",
    "dcvm": "damped CVM + Gaussian (`dcvm`, (d, s) tuned on val for best-of-20)",
    "k1-ref": "K = 1 comparator (`k1-ref`: better on val of CVM and CVM damped for K = 1)",
    "sf": "social force, simulator defaults (`sf`)",
    "sf-qlb": "social force, QLB-updated intensity (`sf-qlb`)",
    "sf-fit": "social force, fitted on train (`sf-fit`)",
    "s-cgru": "S-CGRU",
    "s-gru": "S-GRU",
    "s-lstm": "S-LSTM",
    "lstm": "vanilla LSTM",
}
"""Row names of the summary table (sampling variants: the network's name plus the scheme)."""
SCHEMES: dict[str, str] = {
    "": "autoregressive",
    "+persist": "persistent, σ × 1 (the model's distribution)",
    "+corr": "persistent, σ × val-tuned scale",
}
"""The three sampling rows of each network and how the summary names them."""
FINGERPRINT_WINDOWS = 6
"""Windows of the ETH test split in the fingerprint's tiny evaluation (all rows, sample seed 0)."""
FINGERPRINT_DECIMALS = 3
"""Decimals (metres) the tiny evaluation is rounded to before hashing. At 4 decimals a fresh install hashed
the same code differently from the install that measured the tables (float noise between library builds
crossing a rounding edge), so the tables read as stale; a change to a metric, baseline or loader moves many
values by millimetres and still shows (the test swaps the energy score)."""


def _label(name: str) -> str:
    kind, plus, variant = name.partition("+")
    if not plus:
        return LABELS[name] if name not in NETWORKS else f"{LABELS[name]}, {SCHEMES['']}"
    return f"{LABELS[kind]}, {SCHEMES['+' + variant]}"


def _part(args: tuple[str, str, str]) -> dict[str, Any]:
    """One (scene, model) evaluation in a worker process (one torch thread)."""
    root, scene, model = args
    torch.set_num_threads(1)
    return run(Path(root), [model], [scene])


def measure(workers: int = 2, data_root: Path | None = None) -> dict[str, Any]:
    """Evaluate :data:`MODELS` on every scene; the JSON-ready merged result with the AVG and the wall time."""
    root = str(data_root or default_data_root())
    big = {"univ": 0, "zara2": 1}  # the longest parts first, so the pool ends together
    parts = sorted(
        ((root, s, m) for s in EVAL_SCENES for m in MODELS),
        key=lambda p: (big.get(p[1], 2), p[2] not in NETWORKS, p[2]),
    )
    start = time.perf_counter()
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        outs = list(pool.map(_part, parts))
    merged: dict[str, Any] = {"results": {m: {} for m in MODELS}, "counts": {}}
    for out in outs:
        merged["counts"].update(out["counts"])
        for name, entries in out["results"].items():
            merged["results"][name].update(entries)
        merged.update({k: out[k] for k in ("protocol", "num_samples", "seed")})
    merged["results"] = {m: {s: merged["results"][m][s] for s in EVAL_SCENES} for m in MODELS}
    merged["counts"] = {s: merged["counts"][s] for s in EVAL_SCENES}
    return {
        "command": "python -m benchmarks.results predictors",
        "evaluate": with_average(merged),
        "models": list(MODELS),
        "workers": workers,
        "wall_seconds": round(time.perf_counter() - start, 1),
    }


@cache
def fingerprint() -> str:
    """Hash of the shipped checkpoints' sums, the social-force fit and a tiny evaluation of every row.

    The evaluation (the first :data:`FINGERPRINT_WINDOWS` windows of ETH test, ``dcvm`` and ``k1-ref``
    tuned on ETH val) runs the code path of :func:`measure`, so a change to a metric, a baseline, the
    sampling or the data loader changes it; values are rounded to :data:`FINGERPRINT_DECIMALS` so float
    noise between machines and library builds does not.
    """
    digest = hashlib.sha256()
    # The checkpoints' entries only, as the manifest file writes them: the kernel files it also lists are
    # derived from the checkpoints (`predictors.fast_inference`) and change no number here.
    manifest = json.loads((WEIGHTS_DIR / "manifest.json").read_text(encoding="utf-8"))
    checkpoints = {name: sha for name, sha in sorted(manifest.items()) if name.endswith(".pt")}
    digest.update((json.dumps(checkpoints, indent=1) + "\n").encode())
    digest.update(FIT_FILE.read_bytes())
    root = default_data_root()
    test = load_split(root, "eth", "test")
    tiny = Windows(test.traj, test.seq_start_end[:FINGERPRINT_WINDOWS])
    torch.set_num_threads(1)
    for name in MODELS:
        pred, source = make_predictor(name, "eth", WEIGHTS_DIR, root)
        scores = evaluate_one(pred, tiny, 20, 0) if pred is not None else {}
        rounded = {m: [round(v, FINGERPRINT_DECIMALS) for v in vals] for m, vals in scores.items()}
        digest.update(json.dumps([name, source, rounded], sort_keys=True).encode())
    return digest.hexdigest()[:16]


# ---------------------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------------------

TITLES: dict[str, str] = {
    "k1": "Most likely (K = 1)",
    "ped20": "Best-of-20, per pedestrian (ADE and FDE minimised separately)",
    "scene20": "Best-of-20, per scene (Social-GAN `evaluate_model.py` style)",
    "es": "Energy score of the 20 samples (fair form; m, lower is better)",
}


def _cell(entry: dict[str, Any], metric: str, digits: int = 2) -> str:
    if metric not in entry:
        return "–"
    v = entry[metric]
    flag = "†" if str(entry.get("weights", "")).endswith("_all.pt") else ""
    return f"{v[0]:.{digits}f}{flag}" if metric == "es" else f"{v[0]:.{digits}f}/{v[1]:.{digits}f}{flag}"


def _res(data: dict[str, Any]) -> dict[str, dict[str, dict[str, Any]]]:
    """The rows in the measured order (the JSON is stored with sorted keys)."""
    res = data["evaluate"]["results"]
    return {m: res[m] for m in data.get("models", res)}


def _provenance(data: dict[str, Any], json_name: str = "predictors.json") -> str:
    return (
        f"Measured with `{data['command']}` on commit `{str(data['commit'])[:12]}` from the shipped weights"
        f" (`predictors/weights/`, no training): {data['evaluate']['num_samples']} samples, sample seed"
        f" {data['evaluate']['seed']} (+1000 per scene index), {data['wall_seconds']:.0f} s on"
        f" {data['workers']} processes; rendered from `benchmarks/results/{json_name}`, do not edit by hand."
    )


def _per_scene_table(data: dict[str, Any], metric: str) -> list[str]:
    cols = [*SCENES, "avg", "sdd"]
    lines = [f"#### {TITLES[metric]}", "", "| Model | " + " | ".join(c.upper() for c in cols) + " |"]
    lines.append("|---" * (len(cols) + 1) + "|")
    for name, entries in _res(data).items():
        if metric != "k1" and name == "k1-ref":
            continue  # a point forecast: its best-of-20 and energy score are its K = 1 numbers
        lines.append(f"| {name} | " + " | ".join(_cell(entries.get(c, {}), metric) for c in cols) + " |")
    return [*lines, ""]


def _chosen(data: dict[str, Any], name: str) -> str:
    return ", ".join(f"{s} {_res(data)[name][s]['weights']}" for s in EVAL_SCENES)


def _v(data: dict[str, Any], name: str, scene: str, metric: str, i: int = 0) -> float:
    return float(_res(data)[name][scene][metric][i])


def _ade_fde(data: dict[str, Any], name: str, scene: str, metric: str) -> str:
    return f"{_v(data, name, scene, metric):.3f}/{_v(data, name, scene, metric, 1):.3f}"


def _lowest_es(data: dict[str, Any], scene: str) -> str:
    scored = [(_v(data, n, scene, "es"), n) for n in _res(data) if n != "k1-ref"]
    return min(scored)[1]


def findings(data: dict[str, Any]) -> list[str]:
    """Bullets computed from the JSON: the comparisons the docs' text relies on."""
    out = []
    # K = 1: the networks against dcvm, then against CVM and the K = 1 comparator, scene by scene.
    ahead = []
    for net in NETWORKS:
        for s in SCENES:
            m = _v(data, net, s, "k1")
            if m < _v(data, "dcvm", s, "k1"):
                refs = ", ".join(
                    f"{'ahead of' if m < _v(data, r, s, 'k1') else 'not of'} {r} {_v(data, r, s, 'k1'):.3f}"
                    for r in ("cvm", "k1-ref")
                )
                ahead.append(
                    f"{LABELS[net]} on {s.upper()} ({m:.3f} against {_v(data, 'dcvm', s, 'k1'):.3f}; {refs})"
                )
    beats_ref = [
        f"{LABELS[n]} on {s.upper()}"
        for n in NETWORKS
        for s in SCENES
        if _v(data, n, s, "k1") < _v(data, "k1-ref", s, "k1")
    ]
    nets = ", ".join(f"{LABELS[n]} {_ade_fde(data, n, 'avg', 'k1')}" for n in NETWORKS)
    out.append(
        f"K = 1 ADE/FDE, AVG: `k1-ref` {_ade_fde(data, 'k1-ref', 'avg', 'k1')}, CVM"
        f" {_ade_fde(data, 'cvm', 'avg', 'k1')}, `dcvm` {_ade_fde(data, 'dcvm', 'avg', 'k1')};"
        f" networks {nets}."
        f" A network ahead of `dcvm` at K = 1 ADE: {'; '.join(ahead) if ahead else 'none'}."
        f" Ahead of `k1-ref`: {', '.join(beats_ref) if beats_ref else 'none on any ETH/UCY scene'}."
    )
    # Energy score ranking.
    ranked = sorted((_v(data, n, "avg", "es"), n) for n in _res(data) if n != "k1-ref")
    rank = [n for _, n in ranked].index("dcvm") + 1
    lowest = ", ".join(f"{s.upper()} `{_lowest_es(data, s)}`" for s in EVAL_SCENES)
    es = _v(data, "dcvm", "avg", "es")
    dcvm = f"`dcvm` (spread tuned for best-of-20) {es:.2f}, rank {rank} of {len(ranked)}"
    best = f"lowest `{ranked[0][1]}` ({ranked[0][0]:.2f}); " if rank > 1 else ""
    out.append(f"Energy score, AVG: {best}{dcvm}. Lowest per scene: {lowest}.")
    # Sampling schemes of the networks.
    pairs = [(n, s) for n in NETWORKS for s in SCENES]
    wins_ade = sum(_v(data, f"{n}+persist", s, "ped20") < _v(data, n, s, "ped20") for n, s in pairs)
    wins_es = sum(_v(data, f"{n}+persist", s, "es") < _v(data, n, s, "es") for n, s in pairs)
    chains = "; ".join(
        f"{LABELS[n]} "
        + " → ".join(
            f"{_ade_fde(data, n + v, 'avg', 'ped20')} ({_v(data, n + v, 'avg', 'es'):.2f})" for v in SCHEMES
        )
        for n in NETWORKS
    )
    out.append(
        "Sampling, the same networks and learned σ: the persistent draw at scale 1 has a lower best-of-20 ADE"
        f" (per pedestrian) than the autoregressive draw in {wins_ade} of {len(pairs)} network-scene pairs on"
        f" ETH/UCY and a lower energy score in {wins_es} of {len(pairs)}. AVG best-of-20 ADE/FDE (energy"
        f" score), autoregressive → persistent σ × 1 → persistent σ × val-tuned scale: {chains}."
    )
    return [f"- {line}" for line in out]


def social_force_fit_table() -> list[str]:
    """The committed social-force fit (``predictors/social_force_fit.json``; part of :func:`fingerprint`)."""
    fit = json.loads(FIT_FILE.read_text(encoding="utf-8"))["scenes"]
    lines = [
        "Social-force parameters (`predictors/social_force_fit.json`, written by `python -m"
        " studies.fit_social_force`; its hash is part of this block's fingerprint):",
        "",
        "| Scene | parameters | τ (s) | A (m/s²) | B (m) | λ | sample heading σ | train K=1 ADE | val K=1 ADE"
        " | windows (train/val) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for scene, f in fit.items():
        for kind, label in (("default", "simulator default"), ("fit", "fit")):
            q = f[kind]
            params = " | ".join(
                f"{q[k]:g}" for k in ("relaxation_time", "base_strength", "ped_range", "anisotropy")
            )
            lines.append(
                f"| {scene} | {label} | {params} | {q['heading_std_deg']:g}° | {q['train_ade']:.3f}"
                f" | {q['val_ade']:.3f} | {f['train_windows']}/{f['val_windows']} |"
            )
    return [*lines, ""]


def render_results(data: dict[str, Any]) -> str:
    """The block of ``predictors/RESULTS.md``: every row on every scene, the tuned parameters, findings."""
    lines = [_provenance(data), ""]
    for metric in TITLES:
        lines += _per_scene_table(data, metric)
    counts = data["evaluate"]["counts"]
    lines += [
        "Test windows / pedestrian instances: "
        + ", ".join(f"{s} {counts[s][0]}/{counts[s][1]}" for s in EVAL_SCENES if s in counts),
        "",
        f"`dcvm` (d, s) chosen on val by best-of-20 ADE: {_chosen(data, 'dcvm')}.",
        f"`k1-ref` damping chosen on val by K = 1 ADE (`cvm`: plain CVM won): {_chosen(data, 'k1-ref')}.",
        *(
            ["† SDD evaluated with the model trained on all ETH/UCY recordings (cross-dataset)."]
            if any(str(e["sdd"].get("weights", "")).endswith("_all.pt") for e in _res(data).values())
            else []
        ),
        "",
        "S-CGRU against the comparators, per scene (3 decimals):",
        "",
        "| metric: model | " + " | ".join(s.upper() for s in SCENES) + " |",
        "|---" * (len(SCENES) + 1) + "|",
    ]
    rows = [
        ("k1", ("cvm", "k1-ref", "dcvm", "s-cgru")),
        ("ped20", ("dcvm", "s-cgru", "s-cgru+persist", "s-cgru+corr")),
        ("scene20", ("dcvm", "s-cgru", "s-cgru+persist", "s-cgru+corr")),
        ("es", ("dcvm", "s-cgru", "s-cgru+persist", "s-cgru+corr")),
    ]
    short = {
        "k1": "K = 1",
        "ped20": "best-of-20 per ped",
        "scene20": "best-of-20 per scene",
        "es": "energy score",
    }
    for metric, names in rows:
        for n in names:
            cells = " | ".join(_cell(_res(data)[n][s], metric, 3) for s in SCENES)
            lines.append(f"| {short[metric]}: {n} | {cells} |")
    lines += ["", *social_force_fit_table(), "Findings (computed from the JSON):", "", *findings(data)]
    return "\n".join(lines)


def render_summary(data: dict[str, Any]) -> str:
    """The block of ``docs/predictors.md``: the AVG of the five ETH/UCY scenes and SDD, findings."""
    lines = [
        _provenance(data),
        " Per scene: `predictors/RESULTS.md`.",
        "",
        "| model | K = 1 | best-of-20, per pedestrian | best-of-20, per scene | energy score"
        " | SDD, best-of-20 per pedestrian |",
        "|---|---|---|---|---|---|",
    ]
    lines[0] += lines.pop(1)
    for name, e in _res(data).items():
        avg = e.get("avg", {})
        cells = [_cell(avg, "k1")]
        cells += ["–"] * 3 if name == "k1-ref" else [_cell(avg, m) for m in ("ped20", "scene20", "es")]
        cells.append("–" if name == "k1-ref" else _cell(e["sdd"], "ped20"))
        lines.append(f"| {_label(name)} | " + " | ".join(cells) + " |")
    lines += ["", *findings(data)]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------------------
# The shipped checkpoints: training budget (their metadata) and what they predict (studies.diagnostics)
# ---------------------------------------------------------------------------------------------------------


def measure_checkpoints(data_root: Path | None = None) -> dict[str, Any]:
    """Per shipped checkpoint: size, its stored training metadata and `studies.diagnostics.diagnose`."""
    from predictors.checkpoints import checkpoint_meta, load_model
    from predictors.models import count_parameters
    from studies.diagnostics import diagnose

    root = data_root or default_data_root()
    torch.set_num_threads(1)
    start = time.perf_counter()
    rows: dict[str, Any] = {}
    keys = ("epochs_run", "windows_seen", "wall_s", "best_epoch", "val_ade", "val_fde")
    for path in sorted(WEIGHTS_DIR.glob("*.pt")):
        meta = checkpoint_meta(path)
        model = load_model(path)
        rows[path.name] = {
            "hidden_size": model.config.hidden_size,
            "embed_size": model.config.embed_size,
            "parameters": count_parameters(model)[0],
            **{k: meta[k] for k in keys},
            **diagnose(path, root),
        }
    return {
        "command": "python -m benchmarks.results predictor_checkpoints",
        "checkpoints": rows,
        "wall_seconds": round(time.perf_counter() - start, 1),
    }


def render_checkpoints(data: dict[str, Any]) -> str:
    """The training-budget and diagnostics table of ``predictors/RESULTS.md``."""
    lines = [
        f"Measured with `{data['command']}` on commit `{str(data['commit'])[:12]}`"
        f" ({data['wall_seconds']:.0f} s): size and training metadata stored in each shipped checkpoint, and"
        " `python -m studies.diagnostics` (≤ 300 evenly spaced windows of the checkpoint's test split, the"
        " `_all` model on ETH val; pedestrians moving ≥ 0.1 m/step); rendered from"
        " `benchmarks/results/predictor_checkpoints.json`.",
        "",
        "| Checkpoint | hidden/embed | params | epochs run (× 25 % of train) | windows seen | wall s"
        " | best epoch | val ADE/FDE | sample scale | K=1 speed / CVM speed, median [p10, p90]"
        " | heading change, median | median σ (m/step) |",
        "|---" * 12 + "|",
    ]
    for name, c in data["checkpoints"].items():
        lines.append(
            f"| {name} | {c['hidden_size']}/{c['embed_size']} | {c['parameters']:,} | {c['epochs_run']}"
            f" | {c['windows_seen']} | {c['wall_s']:.1f} | {c['best_epoch']}"
            f" | {c['val_ade']:.3f}/{c['val_fde']:.3f} | {c['sample_scale']:g}"
            f" | {c['speed_ratio_median']:.2f} [{c['speed_ratio_p10']:.2f}, {c['speed_ratio_p90']:.2f}]"
            f" | {c['heading_change_median_deg']:.1f}° | {c['sigma_median']:.2f} |"
        )
    rows = list(data["checkpoints"].values())
    stuck = [c for c in rows if c["sigma_median"] >= 0.5]
    ratio = [c["speed_ratio_median"] for c in rows]
    heading = [c["heading_change_median_deg"] for c in rows]
    lines += [
        "",
        f"- σ learned (median below 0.5 m/step) in {len(rows) - len(stuck)} of {len(rows)} checkpoints; the"
        " others kept σ near its initial 1 m/step, and their best val epochs are "
        + ", ".join(sorted({str(c["best_epoch"]) for c in stuck}))
        + ".",
        f"- K = 1 speed / CVM speed, median per checkpoint: {min(ratio):.2f}–{max(ratio):.2f}; heading"
        f" change, median: {min(heading):.1f}–{max(heading):.1f}°.",
    ]
    return "\n".join(lines)
