from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from predictors.data import (
    SEQ_LEN,
    Windows,
    default_data_root,
    iterate_batches,
    load_split,
    read_trajectory_file,
    relative,
    windows_from_rows,
    windows_from_tracks,
)

DATA = default_data_root()
needs_data = pytest.mark.skipif(
    not (DATA / "eth_ucy").is_dir(), reason=f"shared data not found at {DATA} (set CROSSING_DATA)"
)


def _rows(tracks: dict[int, tuple[int, int]], step: float = 10.0) -> np.ndarray:
    """Rows frame ped x y for pedestrians present from frame index a to b (exclusive), walking along x."""
    rows = []
    for pid, (a, b) in tracks.items():
        for t in range(a, b):
            rows.append([t * step, pid, 0.5 * t, float(pid)])
    rows.sort()
    return np.asarray(rows)


def test_read_rejects_bad_line_naming_file(tmp_path: Path) -> None:
    f = tmp_path / "bad.txt"
    f.write_text("1\t2\t3.0\t4.0\n5\t6\t7.0\n")
    with pytest.raises(ValueError, match=r"bad\.txt:2"):
        read_trajectory_file(f)
    f.write_text("1\t2\tx\t4.0\n")
    with pytest.raises(ValueError, match=r"bad\.txt:1"):
        read_trajectory_file(f)
    with pytest.raises(FileNotFoundError, match=r"missing\.txt"):
        read_trajectory_file(tmp_path / "missing.txt")


def test_windows_keep_only_complete_tracks_and_two_peds() -> None:
    # ped 1 and 2 complete over frames 0..24, ped 3 only 0..10 (never complete), so 6 windows of 2 peds.
    w = windows_from_rows(_rows({1: (0, 25), 2: (0, 25), 3: (0, 10)}))
    assert w.num_windows == 25 - SEQ_LEN + 1
    assert np.all(w.seq_start_end[:, 1] - w.seq_start_end[:, 0] == 2)
    # positions of window 3 are frames 3..22 of ped 1 (x = 0.5 t)
    np.testing.assert_allclose(w.traj[6, :, 0], 0.5 * np.arange(3, 23))
    # a single complete pedestrian gives no window
    assert windows_from_rows(_rows({1: (0, 25), 3: (0, 10)})).num_windows == 0


def test_windows_from_tracks_drop_gaps() -> None:
    t, p = 30, 3
    pos = np.random.default_rng(0).normal(size=(t, p, 2))
    present = np.ones((t, p), bool)
    present[15, 2] = False  # a gap: ped 2 only complete in windows not covering sample 15
    w = windows_from_tracks(pos, present)
    sizes = w.seq_start_end[:, 1] - w.seq_start_end[:, 0]
    assert w.num_windows == t - SEQ_LEN + 1
    assert list(sizes) == [2] * w.num_windows  # every window covers sample 15 when t=30
    np.testing.assert_allclose(w.traj[0], pos[:SEQ_LEN, 0].astype(np.float32))


def test_batches_keep_windows_whole_and_rotation_preserves_distances() -> None:
    w = windows_from_rows(_rows({1: (0, 40), 2: (0, 40), 3: (5, 40)}))
    rng = np.random.default_rng(1)
    n = 0
    for b in iterate_batches(w, 7, rng=rng, rotate=True):
        sse = b.seq_start_end
        assert int(sse[0, 0]) == 0 and int(sse[-1, 1]) == b.obs.shape[0]
        assert bool((sse[1:, 0] == sse[:-1, 1]).all())
        n += b.obs.shape[0]
        step = (b.obs[:, 1] - b.obs[:, 0]).norm(dim=-1)
        np.testing.assert_allclose(step.numpy(), 0.5, rtol=1e-5)
    assert n == w.num_peds


def test_relative_is_backward_difference() -> None:
    w = windows_from_rows(_rows({1: (0, 20), 2: (0, 20)}))
    import torch

    rel = relative(torch.as_tensor(w.traj))
    assert float(rel[:, 0].abs().max()) == 0.0
    np.testing.assert_allclose(rel[:, 1:, 0].numpy(), 0.5)


def test_concat_and_subset_roundtrip() -> None:
    a = windows_from_rows(_rows({1: (0, 22), 2: (0, 22)}))
    b = windows_from_rows(_rows({1: (0, 21), 2: (0, 21), 3: (0, 21)}))
    c = Windows.concat([a, b])
    assert c.num_windows == a.num_windows + b.num_windows
    assert c.num_peds == a.num_peds + b.num_peds
    s = c.subset(np.array([c.num_windows - 1]))
    np.testing.assert_array_equal(s.traj, b.subset(np.array([b.num_windows - 1])).traj)


@needs_data
def test_eth_test_window_count_matches_reference() -> None:
    w = load_split(DATA, "eth", "test")
    assert (w.num_windows, w.num_peds) == (70, 181)  # prediction.md §1 [measured]


@needs_data
def test_unknown_scene_and_split_errors() -> None:
    with pytest.raises(ValueError, match="scene"):
        load_split(DATA, "nowhere", "test")
    with pytest.raises(ValueError, match="split"):
        load_split(DATA, "eth", "dev")
