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
import torch
from numba import njit

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


Pooling = tuple[np.ndarray, np.ndarray] | None
"""One step's pooling: rows that pool someone and their ``(R*G*G, N)`` 0/1 matrix, or ``None``."""


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function (``exp`` form: several times faster than ``tanh`` in NumPy float32)."""
    e = np.exp(-x)
    e += 1.0
    return np.reciprocal(e, out=e)


def headings(rel: np.ndarray, min_speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Heading of every step of ``rel (N, T, 2)`` at once, and whether there was one.

    The unit vector of the latest displacement faster than ``min_speed`` (``(1, 0)`` before any): the
    rollout's step-by-step update unrolled into a running maximum over step indices (same values).
    """
    n, t = rel.shape[:2]
    speed = np.sqrt((rel * rel).sum(axis=2))
    unit = rel / np.maximum(speed, 1e-9)[..., None]
    last = np.maximum.accumulate(np.where(speed > min_speed, np.arange(t), -1), axis=1)
    ok = last >= 0
    heading = unit[np.arange(n)[:, None], np.maximum(last, 0)]
    heading[~ok] = (1.0, 0.0)
    return heading.astype(np.float32), ok


@njit(cache=True, nogil=True)
def _matmul_into(x: np.ndarray, w: np.ndarray, out: np.ndarray, accumulate: bool) -> None:
    """``out (+)= x @ w`` with the inner loop over ``w``'s contiguous rows (vectorised by LLVM)."""
    for i in range(x.shape[0]):
        if not accumulate:
            out[i, :] = 0.0
        for k in range(x.shape[1]):
            v = x[i, k]
            if v != 0.0:
                for j in range(w.shape[1]):
                    out[i, j] += v * w[k, j]


@njit(cache=True, nogil=True)
def _sigmoid_nb(x: np.float32) -> np.float32:
    return np.float32(1.0) / (np.float32(1.0) + np.exp(-x))


@njit(cache=True, nogil=True)
def _rollout_kernel(
    obs: np.ndarray,
    kind: int,
    geometry: np.ndarray,
    flags: np.ndarray,
    w_in: np.ndarray,
    b_in: np.ndarray,
    w_x_emb: np.ndarray,
    w_x_soc: np.ndarray,
    b_x: np.ndarray,
    w_cells: np.ndarray,
    b_pool: np.ndarray,
    empty_soc: np.ndarray,
    w_head: np.ndarray,
    b_head: np.ndarray,
    u_a: np.ndarray,
    u_b: np.ndarray,
    b_u: np.ndarray,
    obs_len: int,
    pred_len: int,
) -> np.ndarray:
    """Most-likely rollout of one window (see :class:`FastPredictor`); ``kind`` 0 S-CGRU, 1 GRU, 2 LSTM.

    ``geometry``: float32 ``[half, cell side, half fov, min speed]``; ``flags``: ``[pooling, heading
    frame, sector, cv residual, grid size]``. S-CGRU: ``u_a``/``u_b`` are the folded gate/candidate
    recurrent maps and ``b_u`` the modReLU bias; GRU/LSTM: ``u_a`` is ``weight_hh.T`` and ``b_u`` its bias.
    """
    n = obs.shape[0]
    nh = w_head.shape[0]
    ne = b_in.shape[0]
    nx = b_x.shape[0]
    half, side, half_fov, min_speed = geometry[0], geometry[1], geometry[2], geometry[3]
    pooling, heading_frame, sector, cv, g = (
        flags[0] != 0,
        flags[1] != 0,
        flags[2] != 0,
        flags[3] != 0,
        flags[4],
    )
    f0 = np.float32(0.0)
    h = np.zeros((n, nh), np.float32)
    cst = np.zeros((n, nh), np.float32)
    h_new = np.zeros((n, nh), np.float32)
    pos = obs[:, 0].copy()
    rel = np.zeros((n, 2), np.float32)
    head = np.zeros((n, 2), np.float32)
    head[:, 0] = 1.0
    ok = np.zeros(n, np.bool_)
    emb = np.empty((n, ne), np.float32)
    wx = np.empty((n, nx), np.float32)
    soc = np.empty(b_pool.shape[0], np.float32)
    gh = np.empty((n, u_a.shape[1]), np.float32)
    rh = np.empty((n, nh), np.float32)
    cc = np.empty((n, nh), np.float32)
    raw = np.zeros((n, 5), np.float32)
    out = np.empty((n, pred_len, 2), np.float32)
    for t in range(obs_len + pred_len - 1):
        if t > 0:
            for i in range(n):
                if t < obs_len:
                    px, py = obs[i, t, 0], obs[i, t, 1]
                else:
                    px, py = pos[i, 0] + raw[i, 0], pos[i, 1] + raw[i, 1]
                rel[i, 0], rel[i, 1] = px - pos[i, 0], py - pos[i, 1]
                pos[i, 0], pos[i, 1] = px, py
                if t >= obs_len:
                    out[i, t - obs_len, 0], out[i, t - obs_len, 1] = px, py
                speed = np.sqrt(rel[i, 0] * rel[i, 0] + rel[i, 1] * rel[i, 1])
                if speed > min_speed:
                    s = max(speed, np.float32(1e-9))
                    head[i, 0], head[i, 1] = rel[i, 0] / s, rel[i, 1] / s
                    ok[i] = True
        for i in range(n):  # displacement embedding
            for e in range(ne):
                v = b_in[e] + rel[i, 0] * w_in[0, e] + rel[i, 1] * w_in[1, e]
                emb[i, e] = v if v > f0 else f0
        _matmul_into(emb, w_x_emb, wx, False)
        for i in range(n):  # social share: per-pair sums, only for those with a neighbour in the grid
            found = False
            if pooling and t > 0:
                soc[:] = b_pool
                u0, u1 = head[i, 0], head[i, 1]
                for j in range(n):
                    if j == i:
                        continue
                    d0, d1 = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1]
                    if heading_frame:
                        x, y = d0 * u0 + d1 * u1, u0 * d1 - u1 * d0
                    else:
                        x, y = d0, d1
                    cx, cy = np.floor((x + half) / side), np.floor((y + half) / side)
                    if cx < 0 or cx >= g or cy < 0 or cy >= g:
                        continue
                    if sector and ok[i] and abs(np.arctan2(y, x)) > half_fov:
                        continue
                    found = True
                    c = int(cy) * g + int(cx)
                    for k in range(nh):
                        v = h[j, k]
                        if v != 0.0:
                            for e in range(soc.shape[0]):
                                soc[e] += v * w_cells[c, k, e]
            if found:
                for e in range(soc.shape[0]):
                    v = soc[e]
                    if v > f0:
                        for k in range(nx):
                            wx[i, k] += v * w_x_soc[e, k]
                for k in range(nx):
                    wx[i, k] += b_x[k]
            elif pooling:
                for k in range(nx):
                    wx[i, k] += empty_soc[k]
            else:
                for k in range(nx):
                    wx[i, k] += b_x[k]
        if kind == 0:  # S-CGRU, folded (ComplexGRUCell.fused_weights)
            hk = nh // 2
            _matmul_into(h, u_a, gh, False)
            for i in range(n):
                for k in range(nh):
                    gh[i, k] = _sigmoid_nb(wx[i, k] + gh[i, k])  # [r, z]
                for k in range(hk):
                    rh[i, k] = h[i, k] * gh[i, k]
                    rh[i, hk + k] = h[i, hk + k] * gh[i, k]
            _matmul_into(rh, u_b, cc, False)
            for i in range(n):
                for k in range(hk):
                    cr, ci = wx[i, nh + k] + cc[i, k], wx[i, nh + hk + k] + cc[i, hk + k]
                    mag = np.sqrt(cr * cr + ci * ci + np.float32(1e-8))
                    a = mag + b_u[k]
                    scale = (a if a > f0 else f0) / mag
                    z = gh[i, hk + k]
                    h_new[i, k] = h[i, k] + z * (cr * scale - h[i, k])
                    h_new[i, hk + k] = h[i, hk + k] + z * (ci * scale - h[i, hk + k])
        elif kind == 1:  # GRU
            _matmul_into(h, u_a, gh, False)
            for i in range(n):
                for k in range(nh):
                    r = _sigmoid_nb(wx[i, k] + gh[i, k] + b_u[k])
                    z = _sigmoid_nb(wx[i, nh + k] + gh[i, nh + k] + b_u[nh + k])
                    cand = np.tanh(wx[i, 2 * nh + k] + r * (gh[i, 2 * nh + k] + b_u[2 * nh + k]))
                    h_new[i, k] = cand + z * (h[i, k] - cand)
        else:  # LSTM
            _matmul_into(h, u_a, gh, False)
            for i in range(n):
                for k in range(nh):
                    ig = _sigmoid_nb(wx[i, k] + gh[i, k] + b_u[k])
                    fg = _sigmoid_nb(wx[i, nh + k] + gh[i, nh + k] + b_u[nh + k])
                    gg = np.tanh(wx[i, 2 * nh + k] + gh[i, 2 * nh + k] + b_u[2 * nh + k])
                    og = _sigmoid_nb(wx[i, 3 * nh + k] + gh[i, 3 * nh + k] + b_u[3 * nh + k])
                    cst[i, k] = fg * cst[i, k] + ig * gg
                    h_new[i, k] = og * np.tanh(cst[i, k])
        h, h_new = h_new, h
        if t > 0:
            _matmul_into(h, w_head, raw, False)
            for i in range(n):
                for k in range(5):
                    raw[i, k] += b_head[k]
                if cv:
                    raw[i, 0] += rel[i, 0]
                    raw[i, 1] += rel[i, 1]
    for i in range(n):
        out[i, pred_len - 1, 0] = pos[i, 0] + raw[i, 0]
        out[i, pred_len - 1, 1] = pos[i, 1] + raw[i, 1]
    return out


class FastPredictor:
    """Most-likely prediction of a :class:`SocialRecurrent` model in float32, one window at a time.

    :meth:`predict` runs the compiled :func:`_rollout_kernel`. :meth:`predict_numpy` is the NumPy version:
    per rollout, everything that does not depend on the recurrent state is computed for all observed steps
    at once (displacement embeddings and their share of the cell's input map, headings, the pooling
    operators of steps 1-7), so an observed step costs only the pooling product and the cell; the 12
    predicted steps still need their geometry step by step (their positions come from the model).
    S-CGRU uses :meth:`~predictors.cgru.ComplexGRUCell.fused_weights` (its gates' mixing folded into the
    matrices) in both.
    """

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
            with torch.no_grad():
                fused = [t.detach().cpu().numpy().astype(np.float32) for t in model.cell.fused_weights()]
            w_x, self.b_x, self.u_g, self.u_c = fused
            self.mod_b = sd["cell.modrelu_bias"]
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
        self._cells = np.arange(c.grid_size * c.grid_size, dtype=np.float32)
        self.cos_half_fov = math.cos(self.half_fov)
        self._kernel_args = self._pack(model)

    def _pack(self, model: SocialRecurrent) -> tuple[object, ...]:
        """Arguments of :func:`_rollout_kernel` after ``obs``.

        Absent parts are 1-element dummies of the same rank, so every model kind shares one compiled
        signature.
        """
        c = self.config
        z1, z2 = np.zeros(1, np.float32), np.zeros((1, 1), np.float32)
        if self.pooling:
            with torch.no_grad():
                w_cells = model.pool_weights().detach().cpu().numpy().astype(np.float32)
            pool = (self.w_x_soc, w_cells, self.b_pool, self.empty_soc.astype(np.float32))
        else:
            pool = (z2, np.zeros((1, 1, 1), np.float32), z1, z1)
        if c.kind == "s-cgru":
            rec = (self.u_g, self.u_c, self.mod_b)
        else:
            rec = (self.w_hh, z2, self.b_hh)
        geometry = np.array(
            [0.5 * c.neighborhood, c.neighborhood / c.grid_size, self.half_fov, c.min_speed], np.float32
        )
        flags = np.array(
            [self.pooling, c.pool_frame == "heading", c.fov_deg < 360.0, c.cv_residual, c.grid_size], np.int64
        )
        kind = {"s-cgru": 0, "s-gru": 1}.get(c.kind, 2)
        args = (kind, geometry, flags, self.w_in, self.b_in, self.w_x_emb, pool[0], self.b_x, pool[1])
        args += (pool[2], pool[3], self.w_head, self.b_head, *rec, OBS_LEN, PRED_LEN)
        return tuple(np.ascontiguousarray(a) if isinstance(a, np.ndarray) else a for a in args)

    def _operators(self, pos: np.ndarray, heading: np.ndarray, ok: np.ndarray) -> list[Pooling]:
        """Pooling of ``T`` steps at once: per step, who has a neighbour in their grid, and the 0/1 matrix.

        Each step gives the rows ``R`` that pool someone and their ``(R*G*G, N)`` pooling matrix, or
        ``None`` when nobody pools.

        ``pos``: ``(T, N)`` complex positions ``x + iy``; ``heading``: ``(T, N)`` complex unit headings;
        ``ok``: ``(T, N)``. Same cells and sector as :meth:`SocialRecurrent.pool_cells` over all ``N x N``
        pairs of the one window. The rotation into the heading frame is the complex product
        ``(p_j - p_i) * conj(u_i)``, whose real and imaginary parts are the same two-term sums; the sector
        test ``|atan2(y, x)| <= fov / 2`` is evaluated as ``x >= cos(fov / 2) |d|`` (equal but on the
        boundary, to rounding).
        """
        c = self.config
        t, n, g = pos.shape[0], pos.shape[1], c.grid_size
        d = pos[:, None, :] - pos[:, :, None]  # d[t, i, j] = p_j - p_i
        d[:, np.arange(n), np.arange(n)] = np.nan  # nobody pools itself: NaN fails every test below
        if c.pool_frame == "heading":
            d *= np.conj(heading)[:, :, None]
        x, y = d.real, d.imag
        half, cell, mid = 0.5 * c.neighborhood, c.neighborhood / g, 0.5 * (g - 1)
        cx = np.floor((x + half) / cell)
        cy = np.floor((y + half) / cell)
        inside = np.maximum(np.abs(cx - mid), np.abs(cy - mid)) < 0.5 * g  # 0 <= cx, cy < g (integers)
        if c.fov_deg < 360.0:
            inside &= (x >= self.cos_half_fov * np.abs(d)) | ~ok[:, :, None]
        has = inside.any(axis=2)  # (T, N): who pools anyone
        if not has.any():
            return [None] * t
        idx = np.where(inside, cy * g + cx, -1.0)  # (T, N, N) cell of j around i, or -1
        out: list[Pooling] = []
        for k in range(t):
            rows = np.flatnonzero(has[k])
            if rows.size == 0:
                out.append(None)
                continue
            m = (idx[k, rows, None, :] == self._cells[None, :, None]).astype(np.float32)  # (R, G*G, N)
            out.append((rows, m.reshape(rows.size * g * g, n)))
        return out

    def _input(self, wx_emb: np.ndarray, pool: Pooling, h: np.ndarray) -> np.ndarray:
        """Cell input pre-activation: displacement share ``wx_emb`` plus the social share and bias.

        Pedestrians with no neighbour in their grid get the constant empty-social-tensor share; the social
        embedding is computed only for the rows that pool someone (few, outside dense groups).
        """
        if not self.pooling:
            return wx_emb + self.b_x
        wx = wx_emb + self.empty_soc
        if pool is not None:
            rows, m = pool
            soc = (m @ h).reshape(rows.size, -1)
            wx[rows] = (
                wx_emb[rows] + np.maximum(soc @ self.w_pool + self.b_pool, 0.0) @ self.w_x_soc + self.b_x
            )
        return wx

    def _cell(self, wx: np.ndarray, state: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        """One step from the input pre-activation ``wx`` (input map and bias already applied)."""
        kind = self.config.kind
        h = state[0]
        n, n_h = h.shape
        if kind == "s-cgru":
            k = n_h // 2
            gates = _sigmoid(wx[:, :n_h] + h @ self.u_g)  # [r, z], real (mod-sigmoid folded)
            h2 = h.reshape(n, 2, k)
            c = wx[:, n_h:] + (h2 * gates[:, None, :k]).reshape(n, n_h) @ self.u_c
            c2 = c.reshape(n, 2, k)
            mag = np.sqrt(np.einsum("nik,nik->nk", c2, c2) + 1e-8)
            scale = np.maximum(mag + self.mod_b, 0.0) / mag
            return ((h2 + gates[:, None, k:] * (c2 * scale[:, None, :] - h2)).reshape(n, n_h),)
        gi = wx
        gh = h @ self.w_hh + self.b_hh
        if kind == "s-gru":
            rz = _sigmoid(gi[:, : 2 * n_h] + gh[:, : 2 * n_h])
            r, z = rz[:, :n_h], rz[:, n_h:]
            cand = np.tanh(gi[:, 2 * n_h :] + r * gh[:, 2 * n_h :])
            return (cand + z * (h - cand),)
        g = gi + gh
        s = _sigmoid(g)
        i, f, o = s[:, :n_h], s[:, n_h : 2 * n_h], s[:, 3 * n_h :]
        c_new = f * state[1] + i * np.tanh(g[:, 2 * n_h : 3 * n_h])
        return (o * np.tanh(c_new), c_new)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        """``(N, 12, 2)`` most-likely future of ``obs (N, 8, 2)``, one window, via the compiled kernel."""
        return _rollout_kernel(np.ascontiguousarray(obs, np.float32), *self._kernel_args)

    def predict_numpy(self, obs: np.ndarray) -> np.ndarray:
        """The same prediction with NumPy array operations (the reference the kernel is tested against)."""
        with single_thread_blas():
            return self._predict(obs)

    def _predict(self, obs: np.ndarray) -> np.ndarray:
        c = self.config
        obs = np.ascontiguousarray(obs, np.float32)
        n = obs.shape[0]
        # Everything the observed steps need that does not depend on the recurrent state, for all at once.
        rel_obs = np.zeros_like(obs)
        rel_obs[:, 1:] = obs[:, 1:] - obs[:, :-1]
        wx_obs = np.maximum(rel_obs @ self.w_in + self.b_in, 0.0) @ self.w_x_emb  # (N, 8, cell input)
        heading_obs, ok_obs = headings(rel_obs, c.min_speed)
        pos_c = obs.view(np.complex64)[..., 0]  # (N, 8) positions as x + iy
        head_c = heading_obs.view(np.complex64)[..., 0]
        ops: list[Pooling] = [None] * OBS_LEN
        if self.pooling and n > 1:  # step 0 pools zero states: skip it
            ops[1:] = self._operators(pos_c[:, 1:].T.copy(), head_c[:, 1:].T.copy(), ok_obs[:, 1:].T)
        h0 = np.zeros((n, c.hidden_size), np.float32)
        state: tuple[np.ndarray, ...] = (h0,) if c.kind in ("s-cgru", "s-gru") else (h0, h0.copy())
        for t in range(OBS_LEN):
            state = self._cell(self._input(wx_obs[:, t], ops[t], state[0]), state)
        heading, ok = head_c[:, -1].copy(), ok_obs[:, -1].copy()
        rel, pos = rel_obs[:, -1], obs[:, -1]
        out = np.empty((n, PRED_LEN, 2), np.float32)
        pool = self.pooling and n > 1
        for t in range(PRED_LEN):
            raw = state[0] @ self.w_head
            raw += self.b_head
            rel = raw[:, :2] + rel if c.cv_residual else raw[:, :2].copy()
            pos = pos + rel
            out[:, t] = pos
            if t == PRED_LEN - 1:
                break
            rel_c = rel.view(np.complex64)[:, 0]
            speed = np.abs(rel_c)
            moving = speed > c.min_speed
            heading = np.where(moving, rel_c / np.maximum(speed, 1e-9), heading)
            ok |= moving
            wx = np.maximum(rel @ self.w_in + self.b_in, 0.0) @ self.w_x_emb
            op = self._operators(pos.view(np.complex64).T, heading[None], ok[None])[0] if pool else None
            state = self._cell(self._input(wx, op, state[0]), state)
        return out
