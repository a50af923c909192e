"""The predictor tables' findings are computed from the JSON, so the docs' comparisons cannot drift."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import torch

from predictors import metrics
from predictors.metrics import EVAL_SCENES
from studies import predictor_tables as pt
from studies.evaluate import with_average


def _data(k1: dict[tuple[str, str], float], es: dict[str, float]) -> dict[str, Any]:
    """Every row 0.5 everywhere, except the given K = 1 ADE and energy scores."""
    res = {}
    for m in pt.MODELS:
        res[m] = {}
        for s in EVAL_SCENES:
            ade = k1.get((m, s), 0.5)
            res[m][s] = {
                "weights": "x",
                "k1": [ade, 2 * ade],
                "ped20": [0.3, 0.6],
                "scene20": [0.4, 0.8],
                "es": [es.get(m, 2.0), 0.0],
            }
    ev = with_average(
        {"results": res, "counts": {s: [1, 2] for s in EVAL_SCENES}, "num_samples": 20, "seed": 0}
    )
    return {"evaluate": ev, "command": "cmd", "commit": "c" * 40, "workers": 2, "wall_seconds": 1.0}


def test_a_network_ahead_of_dcvm_is_also_compared_with_cvm_and_the_k1_comparator() -> None:
    data = _data(
        {
            ("s-gru", "zara1"): 0.44,
            ("dcvm", "zara1"): 0.48,
            ("cvm", "zara1"): 0.43,
            ("k1-ref", "zara1"): 0.45,
        },
        {},
    )
    k1 = pt.findings(data)[0]
    assert "S-GRU on ZARA1 (0.440 against 0.480; not of cvm 0.430, ahead of k1-ref 0.450)" in k1
    assert "Ahead of `k1-ref`: S-GRU on ZARA1." in k1


def test_the_energy_score_finding_ranks_dcvm_and_names_the_lowest() -> None:
    data = _data({}, {"dcvm": 1.5, "s-cgru+persist": 1.4, "kalman": 1.6})
    es = pt.findings(data)[1]
    assert "lowest `s-cgru+persist` (1.40)" in es and "1.50, rank 2 of" in es
    first = pt.findings(_data({}, {"dcvm": 1.3}))[1]
    assert "AVG: `dcvm` (spread tuned for best-of-20) 1.30, rank 1 of" in first


def test_the_summary_shows_k1_ref_at_k1_only() -> None:
    text = pt.render_summary(_data({}, {}))
    row = next(line for line in text.splitlines() if line.startswith("| K = 1 comparator"))
    assert row.endswith("| 0.50/1.00 | – | – | – | – |")
    assert "S-CGRU, persistent, σ × 1 (the model's distribution)" in text


def test_the_fingerprint_catches_a_changed_metric(
    eth_ucy_root: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Swapping the fair energy score back to the V-statistic must mark the predictor tables stale."""

    def v_statistic(samples: torch.Tensor, fut: torch.Tensor) -> torch.Tensor:
        x = samples.permute(1, 0, 2, 3).flatten(2)
        return (x - fut.flatten(1)[:, None]).norm(dim=-1).mean(1) - 0.5 * torch.cdist(x, x).mean((1, 2))

    pt.fingerprint.cache_clear()
    current = pt.fingerprint()
    monkeypatch.setattr(metrics, "energy_score", v_statistic)
    pt.fingerprint.cache_clear()
    try:
        assert pt.fingerprint() != current
    finally:
        pt.fingerprint.cache_clear()
