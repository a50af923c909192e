from __future__ import annotations

import numpy as np

from studies.sim_transfer import windows_from_tracks


def test_simulated_windows_follow_the_sgan_filter() -> None:
    # a walks frames 0..24, b frames 3..22, c only frames 0..10: windows need 20 frames of >= 2 pedestrians
    tracks = {
        1: {f: np.array([0.1 * f, 0.0]) for f in range(25)},
        2: {f: np.array([0.0, 0.1 * f]) for f in range(3, 23)},
        3: {f: np.array([1.0, 1.0]) for f in range(11)},
    }
    w = windows_from_tracks(tracks)
    assert w.num_windows == 1 and w.num_peds == 2  # only the window starting at frame 3
    assert np.allclose(w.traj[0, :, 0], 0.1 * np.arange(3, 23), atol=1e-6)
    assert windows_from_tracks({}).num_windows == 0
