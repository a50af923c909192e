from __future__ import annotations

import math

import pytest
import torch

from predictors.cgru import ComplexGRUCell
from predictors.models import (
    MODEL_KINDS,
    ModelConfig,
    SocialRecurrent,
    bivariate_nll,
    count_parameters,
    default_config,
    replicate,
    sample_gaussian,
    window_pairs,
)


def _scene(n_windows: int = 3, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    sizes = torch.randint(2, 6, (n_windows,), generator=g)
    ends = torch.cumsum(sizes, 0)
    sse = torch.stack([ends - sizes, ends], 1)
    n = int(ends[-1])
    start = torch.randn(n, 1, 2, generator=g) * 2.0
    vel = torch.randn(n, 1, 2, generator=g) * 0.4
    t = torch.arange(20, dtype=torch.float32)[None, :, None]
    traj = start + vel * t + 0.02 * torch.randn(n, 20, 2, generator=g)
    return traj[:, :8], traj[:, 8:], sse


def test_window_pairs_match_brute_force() -> None:
    sse = torch.tensor([[0, 3], [3, 4], [4, 8]])
    i, j = window_pairs(sse, 8)
    got = set(zip(i.tolist(), j.tolist(), strict=True))
    want = {(a, b) for s, e in sse.tolist() for a in range(s, e) for b in range(s, e) if a != b}
    assert got == want
    with pytest.raises(ValueError, match="seq_start_end"):
        window_pairs(sse, 9)


def test_replicate_offsets() -> None:
    sse = torch.tensor([[0, 2], [2, 5]])
    assert replicate(sse, 5, 2).tolist() == [[0, 2], [2, 5], [5, 7], [7, 10]]


def test_parameter_counts_match_social_lstm_reference() -> None:
    counts = {k: count_parameters(SocialRecurrent(default_config(k))) for k in MODEL_KINDS}
    assert counts["s-lstm"] == (264_069, 264_069)  # prediction.md §3, quancore/social-lstm defaults
    assert counts["s-gru"] == (231_045, 231_045)
    assert counts["s-cgru"][0] < counts["s-gru"][0] < counts["s-lstm"][0]
    assert counts["s-cgru"][0] == counts["s-cgru"][1]  # built from real matrices: numel = real DoF
    h, d = 64, 128
    cell = ComplexGRUCell(d, h)
    assert count_parameters(cell)[0] == 2 * (3 * h * h + 3 * d * h + 3 * h) + h + 2


def _pool_model(fov: float, frame: str = "heading") -> SocialRecurrent:
    cfg = ModelConfig(
        kind="s-gru", hidden_size=1, grid_size=4, neighborhood=4.0, fov_deg=fov, pool_frame=frame
    )
    return SocialRecurrent(cfg)


def test_fov_pooling_keeps_front_and_drops_back() -> None:
    m = _pool_model(90.0)
    pos = torch.tensor([[0.0, 0.0], [1.5, 0.2], [-1.5, 0.2]])  # ped 0 walks +x, one ahead, one behind
    heading = torch.tensor([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    state = torch.tensor([[1.0], [10.0], [100.0]])
    pairs = window_pairs(torch.tensor([[0, 3]]), 3)
    ok = torch.ones(3, dtype=torch.bool)
    out = m.social_pool(pos, heading, ok, state, pairs)
    assert float(out[0].sum()) == 10.0  # only the neighbour in front
    # without a known heading the full grid is used
    out2 = m.social_pool(pos, heading, torch.zeros(3, dtype=torch.bool), state, pairs)
    assert float(out2[0].sum()) == 110.0
    # turning ped 0 around swaps which neighbour is visible
    heading[0] = torch.tensor([-1.0, 0.0])
    assert float(m.social_pool(pos, heading, ok, state, pairs)[0].sum()) == 100.0


def test_heading_frame_pooling_is_rotation_invariant_and_windowed() -> None:
    m = _pool_model(120.0)
    g = torch.Generator().manual_seed(1)
    pos = torch.randn(6, 2, generator=g)
    vel = torch.randn(6, 2, generator=g)
    heading = vel / vel.norm(dim=1, keepdim=True)
    state = torch.randn(6, 1, generator=g)
    ok = torch.ones(6, dtype=torch.bool)
    sse = torch.tensor([[0, 3], [3, 6]])
    pairs = window_pairs(sse, 6)
    a = m.social_pool(pos, heading, ok, state, pairs)
    r = torch.tensor([[math.cos(0.7), -math.sin(0.7)], [math.sin(0.7), math.cos(0.7)]])
    b = m.social_pool(pos @ r.T, heading @ r.T, ok, state, pairs)
    torch.testing.assert_close(a, b, atol=1e-5, rtol=0)
    # moving the second window far away changes nothing for the first window
    pos2 = pos.clone()
    pos2[3:] += 0.1
    c = m.social_pool(pos2, heading, ok, state, pairs)
    torch.testing.assert_close(a[:3], c[:3])


def test_bivariate_nll_matches_torch_distribution() -> None:
    g = torch.Generator().manual_seed(0)
    raw = torch.randn(7, 5, generator=g) * 0.5
    target = torch.randn(7, 2, generator=g)
    mu, sx, sy, rho = raw[:, :2], raw[:, 2].exp(), raw[:, 3].exp(), 0.99 * raw[:, 4].tanh()
    cov = torch.stack(
        [torch.stack([sx * sx, rho * sx * sy], -1), torch.stack([rho * sx * sy, sy * sy], -1)], -2
    )
    ref = -torch.distributions.MultivariateNormal(mu, cov).log_prob(target).mean()
    torch.testing.assert_close(bivariate_nll(raw, target), ref, atol=1e-5, rtol=1e-5)
    s = sample_gaussian(raw[:1].expand(20000, 5), torch.Generator().manual_seed(1))
    emp = torch.cov(s.T)
    torch.testing.assert_close(emp, cov[0], atol=0.05, rtol=0.05)


def test_complex_cell_stays_finite_and_zero_candidate_keeps_zero_state() -> None:
    cell = ComplexGRUCell(4, 8)
    x = torch.randn(5, 4)
    h = torch.zeros(5, 16)
    for _ in range(50):
        h = cell(x, h)
    assert torch.isfinite(h).all()
    # with zero input weights and zero state the candidate is 0, and the convex update keeps the state at 0
    with torch.no_grad():
        cell.w.weight.zero_()
        assert float(cell(torch.randn(5, 4), torch.zeros(5, 16)).abs().max()) == 0.0


@pytest.mark.parametrize("kind", MODEL_KINDS)
def test_models_train_sample_and_are_deterministic(kind: str) -> None:
    torch.manual_seed(0)
    obs, fut, sse = _scene()
    m = SocialRecurrent(
        ModelConfig(
            kind=kind,
            hidden_size=16,
            embed_size=8,
            **({"pool_frame": "heading", "fov_deg": 120.0} if kind == "s-cgru" else {}),
        )
    )
    opt = torch.optim.Adam(m.parameters(), lr=1e-2)
    first = m.loss(obs, fut, sse).item()
    for _ in range(25):
        loss = m.loss(obs, fut, sse)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert m.loss(obs, fut, sse).item() < first - 0.5
    with torch.no_grad():
        pred = m.predict(obs, sse)
        assert pred.shape == fut.shape
        for mode in ("autoregressive", "independent", "correlated"):
            s1 = m.sample(obs, sse, 5, torch.Generator().manual_seed(3), mode=mode)
            s2 = m.sample(obs, sse, 5, torch.Generator().manual_seed(3), mode=mode)
            assert s1.shape == (5, *fut.shape)
            torch.testing.assert_close(s1, s2)
            assert float((s1[0] - s1[1]).abs().max()) > 0.0
        # the sampled spread is centred on the most-likely path for the Gaussian-noise modes
        many = m.sample(obs, sse, 4000, torch.Generator().manual_seed(0), mode="correlated")
        standard_error = many.std(0) / math.sqrt(4000)
        assert bool(((many.mean(0) - pred).abs() < 5.0 * standard_error + 1e-4).all())
        with pytest.raises(ValueError, match="mode"):
            m.sample(obs, sse, 2, torch.Generator(), mode="magic")


def test_prediction_of_one_window_ignores_other_windows() -> None:
    obs, _, sse = _scene(2, seed=4)
    m = SocialRecurrent(default_config("s-cgru")).eval()
    with torch.no_grad():
        both = m.predict(obs, sse)
        s, e = sse[0].tolist()
        alone = m.predict(obs[s:e], torch.tensor([[0, e - s]]))
    torch.testing.assert_close(both[s:e], alone, atol=1e-5, rtol=0)


def test_config_validation() -> None:
    with pytest.raises(ValueError, match="kind"):
        ModelConfig(kind="transformer")
    with pytest.raises(ValueError, match="fov_deg"):
        ModelConfig(kind="s-gru", fov_deg=90.0)  # sector needs the heading frame
    with pytest.raises(ValueError, match="even"):
        ModelConfig(kind="s-cgru", hidden_size=7, pool_frame="heading")


@pytest.mark.parametrize("kind", MODEL_KINDS)
def test_numpy_fast_path_matches_torch(kind: str) -> None:
    from dataclasses import replace

    from predictors.fast_inference import FastPredictor

    torch.manual_seed(1)
    cfg = replace(default_config(kind), hidden_size=16, embed_size=8, cv_residual=True)
    m = SocialRecurrent(cfg).eval()
    with torch.no_grad():
        for p in m.head.parameters():
            p.normal_(0.0, 0.1)
        obs, _, _ = _scene(1, seed=5)
        obs = obs * 0.5  # keep neighbours inside the 4 m grid so pooling matters
        ref = m.predict(obs, torch.tensor([[0, obs.shape[0]]])).numpy()
    got = FastPredictor(m).predict(obs.numpy())
    assert abs(got - ref).max() < 1e-4
    # far-apart pedestrians: empty social tensors take the shortcut path
    far = obs * 50.0
    with torch.no_grad():
        ref_far = m.predict(far, torch.tensor([[0, far.shape[0]]])).numpy()
    assert abs(FastPredictor(m).predict(far.numpy()) - ref_far).max() < 1e-3
