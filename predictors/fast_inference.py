"""NumPy re-implementation of the most-likely rollout of one window, for the per-step observation wrapper.

Why: at 16 pedestrians the torch rollout (19 recurrent steps, about 70 tiny ops each) is dominated by
per-op dispatch cost (several microseconds per op), far above the wrapper's 2 ms budget; NumPy's per-op
cost on tiny arrays is several times lower. This path handles one window (all present pedestrians), uses
dense ``N x N`` pooling (the same cells and sector mask as :meth:`SocialRecurrent.social_pool`), and is
tested to match the torch model to float32 rounding. Sampling still goes through torch.
"""

from __future__ import annotations

import contextlib
import ctypes
import glob
import math
import os
from collections.abc import Callable, Iterator

import numpy as np

from predictors.data import OBS_LEN, PRED_LEN
from predictors.models import SocialRecurrent


def _find_openblas_thread_control() -> tuple[Callable[[], int], Callable[[int], None]] | None:
    """``(get, set)`` thread-count functions of NumPy's bundled OpenBLAS, or ``None`` if not found."""
    libs = glob.glob(os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs", "*openblas*"))
    for path in libs:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix, suffix in (("scipy_openblas_", "64_"), ("openblas_", "")):
            get = getattr(lib, f"{prefix}get_num_threads{suffix}", None)
            set_ = getattr(lib, f"{prefix}set_num_threads{suffix}", None)
            if get is not None and set_ is not None:
                set_.argtypes = [ctypes.c_int]
                return get, set_
    return None


_BLAS_THREADS = _find_openblas_thread_control()


@contextlib.contextmanager
def single_thread_blas() -> Iterator[None]:
    """Run NumPy's OpenBLAS single-threaded inside the block, then restore the previous count.

    Why: for these tiny matrices OpenBLAS's worker threads only add hand-off latency, and on a loaded
    2-core machine that turned a few-millisecond rollout into 40-170 ms of CPU time per call.
    """
    if _BLAS_THREADS is None:
        yield
        return
    get, set_ = _BLAS_THREADS
    before = int(get())
    set_(1)
    try:
        yield
    finally:
        set_(before)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 0.5 * (np.tanh(0.5 * x) + 1.0)


class FastPredictor:
    """Most-likely prediction of a :class:`SocialRecurrent` model in NumPy float32, one window at a time."""

    def __init__(self, model: SocialRecurrent) -> None:
        c = model.config
        self.config = c
        sd = {k: v.detach().cpu().numpy().astype(np.float32) for k, v in model.state_dict().items()}
        self.w_in, self.b_in = sd["input_embed.weight"].T.copy(), sd["input_embed.bias"]
        self.pooling = model.pooling
        if self.pooling:
            self.w_pool, self.b_pool = sd["pool_embed.weight"].T.copy(), sd["pool_embed.bias"]
        self.w_head, self.b_head = sd["head.weight"].T.copy(), sd["head.bias"]
        if c.kind == "s-cgru":
            h = c.hidden_size // 2
            w_x, self.b_x = sd["cell.w.weight"].T.copy(), sd["cell.w.bias"]
            ug, uc = model.cell.recurrent_blocks()
            self.ug, self.uc = ug.detach().numpy().copy(), uc.detach().numpy().copy()
            self.mod_b = sd["cell.modrelu_bias"]
            self.mix = np.repeat(_sigmoid(sd["cell.gate_mix"]), h).astype(np.float32)
        else:
            w_x, self.b_x = sd["cell.weight_ih"].T.copy(), sd["cell.bias_ih"]
            self.w_hh, self.b_hh = sd["cell.weight_hh"].T.copy(), sd["cell.bias_hh"]
        # Split the cell's input map into its displacement-embedding and social-embedding rows, so an
        # empty social tensor (no neighbour in anyone's grid: common in sparse scenes) costs nothing.
        e = c.embed_size
        self.w_x_emb = np.ascontiguousarray(w_x[:e])
        if self.pooling:
            self.w_x_soc = np.ascontiguousarray(w_x[e:])
            self.empty_soc = np.maximum(self.b_pool, 0.0) @ self.w_x_soc + self.b_x
        self.half_fov = math.radians(c.fov_deg) / 2.0

    def _pool(
        self, pos: np.ndarray, heading: np.ndarray, ok: np.ndarray, state: np.ndarray
    ) -> np.ndarray | None:
        c = self.config
        n, g = pos.shape[0], c.grid_size
        d = pos[None, :, :] - pos[:, None, :]  # d[i, j] = p_j - p_i
        if c.pool_frame == "heading":
            x = d[..., 0] * heading[:, None, 0] + d[..., 1] * heading[:, None, 1]
            y = heading[:, None, 0] * d[..., 1] - heading[:, None, 1] * d[..., 0]
        else:
            x, y = d[..., 0], d[..., 1]
        half, cell = 0.5 * c.neighborhood, c.neighborhood / g
        cx = np.floor((x + half) / cell)
        cy = np.floor((y + half) / cell)
        inside = (cx >= 0) & (cx < g) & (cy >= 0) & (cy < g)
        np.fill_diagonal(inside, False)
        if c.fov_deg < 360.0:
            inside &= (np.abs(np.arctan2(y, x)) <= self.half_fov) | ~ok[:, None]
        ii, jj = np.nonzero(inside)
        if ii.size == 0:
            return None
        m = np.zeros((n, g * g, n), np.float32)
        m[ii, (cy[ii, jj] * g + cx[ii, jj]).astype(np.int64), jj] = 1.0
        return (m.reshape(n * g * g, n) @ state).reshape(n, -1)

    def _cell(self, wx: np.ndarray, state: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        """One step from the input pre-activation ``wx`` (input map and bias already applied)."""
        kind = self.config.kind
        h = state[0]
        if kind == "s-cgru":
            k = self.config.hidden_size // 2
            gg = h @ self.ug
            g_re = wx[:, : 2 * k] + gg[:, : 2 * k]
            g_im = wx[:, 3 * k : 5 * k] + gg[:, 2 * k :]
            gates = _sigmoid(self.mix * g_re + (1.0 - self.mix) * g_im)
            r, z = gates[:, :k], gates[:, k:]
            cc = (h * np.concatenate([r, r], axis=1)) @ self.uc
            c_re = wx[:, 2 * k : 3 * k] + cc[:, :k]
            c_im = wx[:, 5 * k :] + cc[:, k:]
            mag = np.sqrt(c_re * c_re + c_im * c_im + 1e-8)
            scale = np.maximum(mag + self.mod_b, 0.0) / mag
            z2 = np.concatenate([z, z], axis=1)
            return ((1.0 - z2) * h + z2 * np.concatenate([c_re * scale, c_im * scale], axis=1),)
        gi = wx
        gh = h @ self.w_hh + self.b_hh
        if kind == "s-gru":
            n_h = h.shape[1]
            r = _sigmoid(gi[:, :n_h] + gh[:, :n_h])
            z = _sigmoid(gi[:, n_h : 2 * n_h] + gh[:, n_h : 2 * n_h])
            cand = np.tanh(gi[:, 2 * n_h :] + r * gh[:, 2 * n_h :])
            return ((1.0 - z) * cand + z * h,)
        n_h = h.shape[1]
        g = gi + gh
        i, f = _sigmoid(g[:, :n_h]), _sigmoid(g[:, n_h : 2 * n_h])
        cand, o = np.tanh(g[:, 2 * n_h : 3 * n_h]), _sigmoid(g[:, 3 * n_h :])
        c_new = f * state[1] + i * cand
        return (o * np.tanh(c_new), c_new)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        """``(N, 12, 2)`` most-likely future of ``obs (N, 8, 2)``, all pedestrians in one window."""
        with single_thread_blas():
            return self._predict(obs)

    def _predict(self, obs: np.ndarray) -> np.ndarray:
        c = self.config
        obs = np.asarray(obs, np.float32)
        n = obs.shape[0]
        h0 = np.zeros((n, c.hidden_size), np.float32)
        state: tuple[np.ndarray, ...] = (h0,) if c.kind in ("s-cgru", "s-gru") else (h0, h0.copy())
        heading = np.zeros((n, 2), np.float32)
        heading[:, 0] = 1.0
        ok = np.zeros(n, bool)
        rel = np.zeros((n, 2), np.float32)
        pos = obs[:, 0]
        out = np.zeros((n, PRED_LEN, 2), np.float32)
        raw = None
        for t in range(OBS_LEN + PRED_LEN - 1):
            if t > 0:
                new_pos = obs[:, t] if t < OBS_LEN else pos + raw[:, :2]
                rel, pos = new_pos - pos, new_pos
                if t >= OBS_LEN:
                    out[:, t - OBS_LEN] = pos
                speed = np.sqrt((rel * rel).sum(axis=1))
                moving = speed > c.min_speed
                heading = np.where(moving[:, None], rel / np.maximum(speed, 1e-9)[:, None], heading)
                ok |= moving
            wx = np.maximum(rel @ self.w_in + self.b_in, 0.0) @ self.w_x_emb
            if self.pooling:
                soc = self._pool(pos, heading, ok, state[0]) if t > 0 else None  # state is 0 at t = 0
                if soc is None:
                    wx += self.empty_soc
                else:
                    wx += np.maximum(soc @ self.w_pool + self.b_pool, 0.0) @ self.w_x_soc + self.b_x
            else:
                wx += self.b_x
            state = self._cell(wx, state)
            if t > 0:
                raw = state[0] @ self.w_head + self.b_head
                if c.cv_residual:
                    raw[:, :2] += rel
        out[:, -1] = pos + raw[:, :2]
        return out
