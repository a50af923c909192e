from __future__ import annotations

import math
from pathlib import Path

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
from predictors.pooling import HeadingTracker, grid_layout


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


def test_heading_tracker_follows_the_latest_fast_displacement() -> None:
    m = SocialRecurrent(ModelConfig(kind="s-cgru", hidden_size=4, embed_size=4, pool_frame="heading"))
    g = torch.Generator().manual_seed(5)
    rel = torch.randn(6, 8, 2, generator=g) * 0.05  # about half the steps slower than min_speed
    rel[:, 0] = 0.0
    rel[0, 1:4] = 0.01  # pedestrian 0 has no heading before step 4
    rel[1, 5:] = 0.0  # pedestrian 1 stops and keeps its heading
    looks = HeadingTracker(m.pooling_geometry(), torch.empty(2, 0, dtype=torch.long), 6, torch.float32)
    for t in range(8):
        looks.advance(rel[:, t])
        for i in range(6):  # reference: the unit vector of the latest step faster than min_speed
            fast = [s for s in range(t + 1) if float(rel[i, s].norm()) > m.config.min_speed]
            assert bool(looks.known[i]) == bool(fast)
            want = rel[i, fast[-1]] / rel[i, fast[-1]].norm() if fast else torch.tensor([1.0, 0.0])
            torch.testing.assert_close(torch.from_numpy(looks.heading[i]), want)
        if t == 1:  # the cases the test is built for: some known after one step, not all
            assert bool(looks.known.any()) and not bool(looks.known.all())


def _reference_cells(
    m: SocialRecurrent, pos: torch.Tensor, heading: torch.Tensor, ok: torch.Tensor, pairs: torch.Tensor
) -> set[tuple[int, int, int]]:
    """The pooling cells written independently with torch ops (the formulation before the kernel)."""
    c = m.config
    i, j = pairs
    d = pos[j] - pos[i]
    if c.pool_frame == "heading":
        u = heading[i]
        d = torch.stack([d[:, 0] * u[:, 0] + d[:, 1] * u[:, 1], d[:, 1] * u[:, 0] - d[:, 0] * u[:, 1]], 1)
    cxy = torch.floor((d + c.neighborhood / 2) / (c.neighborhood / c.grid_size))
    keep = ((cxy >= 0) & (cxy <= c.grid_size - 1)).all(1)
    if c.fov_deg < 360.0:
        keep &= ~ok[i] | (torch.atan2(d[:, 1], d[:, 0]).abs() <= math.radians(c.fov_deg) / 2)
    cell = (cxy[:, 1] * c.grid_size + cxy[:, 0]).long()
    return set(zip(i[keep].tolist(), j[keep].tolist(), cell[keep].tolist(), strict=True))


@pytest.mark.parametrize(("frame", "fov"), [("world", 360.0), ("heading", 360.0), ("heading", 120.0)])
def test_compiled_layout_matches_a_torch_reference_and_packs_slots(frame: str, fov: float) -> None:
    cfg = ModelConfig(kind="s-gru", hidden_size=6, embed_size=5, fov_deg=fov, pool_frame=frame)
    m = SocialRecurrent(cfg)
    g = torch.Generator().manual_seed(11)
    sse = torch.tensor([[0, 5], [5, 9], [9, 20]])
    pos = torch.rand(20, 2, generator=g) * 5.0
    heading = torch.nn.functional.normalize(torch.randn(20, 2, generator=g), dim=1)
    ok = torch.rand(20, generator=g) > 0.3
    pairs = torch.stack(window_pairs(sse, 20))
    i, j, cell, slot, most, used = grid_layout(m.pooling_geometry(), pos, heading, ok, pairs)
    got = set(zip(i.tolist(), j.tolist(), cell.tolist(), strict=True))
    assert got == _reference_cells(m, pos, heading, ok, pairs) and len(got) > 10
    # slots: one row per pair in a (len(used), most) buffer, grouped by cell, no empty cell kept
    assert used.tolist() == sorted(set(cell.tolist()))
    assert len(set(slot.tolist())) == slot.numel() and int(slot.max()) < used.numel() * most
    place = {c: k for k, c in enumerate(used.tolist())}
    assert all(s // most == place[c] for s, c in zip(slot.tolist(), cell.tolist(), strict=True))
    assert most == max(cell.tolist().count(c) for c in used.tolist())
    # the kernel does no bounds checks, so the wrapper refuses pairs outside the batch
    with pytest.raises(ValueError, match="outside"):
        grid_layout(m.pooling_geometry(), pos, heading, ok, torch.tensor([[0], [20]]))


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
    with pytest.raises(ValueError, match="min_speed"):
        ModelConfig(min_speed=-0.1)
    with pytest.raises(ValueError, match="fov_deg"):
        ModelConfig(kind="s-gru", fov_deg=90.0)  # sector needs the heading frame
    with pytest.raises(ValueError, match="even"):
        ModelConfig(kind="s-cgru", hidden_size=7, pool_frame="heading")


@pytest.mark.parametrize("kind", MODEL_KINDS)
def test_compiled_fast_path_matches_torch(kind: str) -> None:
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
        alone = m.predict(obs[:1], torch.tensor([[0, 1]])).numpy()
    fast = FastPredictor(m)
    assert abs(fast.predict(obs.numpy()) - ref).max() < 1e-4
    assert abs(fast.predict(obs[:1].numpy()) - alone).max() < 1e-4  # a window of one
    # far-apart pedestrians: empty social tensors take the shortcut path
    far = obs * 50.0
    with torch.no_grad():
        ref_far = m.predict(far, torch.tensor([[0, far.shape[0]]])).numpy()
    assert abs(fast.predict(far.numpy()) - ref_far).max() < 1e-3


def _unfused_cell_step(cell: ComplexGRUCell, x: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
    """The cell's equations term by term (real and imaginary pre-activations kept apart), as first written."""
    h = cell.hidden_size
    ug, uc = cell.recurrent_blocks()
    wx = cell.w(x)
    wx_re, wx_im = wx[:, : 3 * h], wx[:, 3 * h :]
    g = state @ ug
    g_re, g_im = wx_re[:, : 2 * h] + g[:, : 2 * h], wx_im[:, : 2 * h] + g[:, 2 * h :]
    a = torch.sigmoid(cell.gate_mix).repeat_interleave(h)
    gates = torch.sigmoid(a * g_re + (1.0 - a) * g_im)
    r, z = gates[:, :h], gates[:, h:]
    c = (state * torch.cat([r, r], dim=1)) @ uc
    c_re, c_im = wx_re[:, 2 * h :] + c[:, :h], wx_im[:, 2 * h :] + c[:, h:]
    mag = torch.sqrt(c_re * c_re + c_im * c_im + 1e-8)
    scale = torch.relu(mag + cell.modrelu_bias) / mag
    z2 = torch.cat([z, z], dim=1)
    return (1.0 - z2) * state + z2 * torch.cat([c_re * scale, c_im * scale], dim=1)


def test_fused_complex_cell_equals_the_unfused_equations() -> None:
    torch.manual_seed(2)
    cell = ComplexGRUCell(12, 8)
    with torch.no_grad():
        cell.gate_mix.normal_(0.0, 1.0)  # unequal Re/Im mixing, so folding it into the matrices matters
        cell.modrelu_bias.normal_(0.0, 0.3)
        cell.w.bias.normal_(0.0, 0.3)
    x, state = torch.randn(9, 12), torch.randn(9, 16)
    want = _unfused_cell_step(cell, x, state)
    torch.testing.assert_close(cell(x, state), want, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(cell(x, state, cell.fused_weights()), want, atol=1e-5, rtol=1e-5)
    # gradients flow to every parameter through the folded matrices, as through the unfused form
    cell(x, state).square().sum().backward()
    assert all(p.grad is not None and float(p.grad.abs().sum()) > 0.0 for p in cell.parameters())


@pytest.mark.parametrize("frame", ["world", "heading"])
def test_pooled_embedding_equals_dense_social_tensor(frame: str) -> None:
    torch.manual_seed(3)
    cfg = ModelConfig(
        kind="s-gru",
        hidden_size=6,
        embed_size=5,
        fov_deg=120.0 if frame == "heading" else 360.0,
        pool_frame=frame,
    )
    m = SocialRecurrent(cfg)
    obs, _, sse = _scene(4, seed=7)
    pos = obs[:, -1] * 0.4  # close together: many neighbours, several in the same cell
    heading = torch.nn.functional.normalize(torch.randn(pos.shape[0], 2), dim=1)
    ok = torch.rand(pos.shape[0]) > 0.3
    state = torch.randn(pos.shape[0], 6)
    pairs = window_pairs(sse, pos.shape[0])
    dense = m.pool_embed(m.social_pool(pos, heading, ok, state, pairs))
    assert int((m.social_pool(pos, heading, ok, state, pairs) != 0).any(1).sum()) > 3  # pooling happens
    geometry = m.pooling_geometry()
    groups = m.pool_groups(grid_layout(geometry, pos, heading, ok, torch.stack(pairs)))
    got = m.pooled_embedding(state, groups, m.pool_weights())
    torch.testing.assert_close(got, dense, atol=1e-5, rtol=1e-5)
    # nobody in anyone's grid: no layout, just the bias
    assert m.pool_groups(grid_layout(geometry, pos * 100.0, heading, ok, torch.stack(pairs))) is None
    far = m.pooled_embedding(state, None, m.pool_weights())
    torch.testing.assert_close(far, m.pool_embed.bias.expand_as(far))


SHIPPED = Path(__file__).resolve().parents[2] / "predictors" / "weights"


@pytest.mark.skipif(not (SHIPPED / "s-cgru_all.pt").is_file(), reason="shipped S-CGRU weights not built")
def test_shipped_s_cgru_fast_path_matches_torch_model() -> None:
    from predictors.checkpoints import load_model
    from predictors.fast_inference import FastPredictor

    m = load_model(SHIPPED / "s-cgru_all.pt")
    g = torch.Generator().manual_seed(0)
    start = torch.rand(12, 1, 2, generator=g) * 6.0
    vel = (torch.rand(12, 1, 2, generator=g) - 0.5) * 0.8
    obs = start + vel * torch.arange(8.0)[None, :, None]
    x = torch.randn(12, m.cell.input_size, generator=g)
    state = torch.randn(12, m.config.hidden_size, generator=g)
    with torch.no_grad():
        # the trained weights through the folded cell give the unfused equations' state
        torch.testing.assert_close(
            m.cell(x, state), _unfused_cell_step(m.cell, x, state), atol=1e-5, rtol=1e-5
        )
        ref = m.predict(obs, torch.tensor([[0, 12]])).numpy()
    fast = FastPredictor(m)
    assert abs(fast.predict(obs.numpy()) - ref).max() < 1e-4


def test_scale_overrides_the_val_tuned_sample_scale() -> None:
    """``scale=1.0`` draws from the learned sigma itself, whatever ``sample_scale`` the checkpoint holds."""
    torch.manual_seed(0)
    obs, _, sse = _scene()
    tuned = SocialRecurrent(ModelConfig(kind="lstm", hidden_size=16, embed_size=8, sample_scale=0.25))
    with torch.no_grad():
        mean = tuned.predict(obs, sse)
        at_one = tuned.sample(obs, sse, 6, torch.Generator().manual_seed(5), "correlated", scale=1.0)
        default = tuned.sample(obs, sse, 6, torch.Generator().manual_seed(5), "correlated")
        torch.testing.assert_close(default - mean, 0.25 * (at_one - mean), rtol=1e-4, atol=1e-6)
        assert float((at_one - mean).abs().max()) > 0.0
