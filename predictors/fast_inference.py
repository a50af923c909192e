"""Compiled (numba) most-likely rollout of one window, for the per-step observation wrapper.

Why: at 16 pedestrians the torch rollout (19 recurrent steps, about 70 tiny ops each) is dominated by
per-op dispatch cost (several microseconds per op), far above the wrapper's 2 ms budget. This path handles
one window (all present pedestrians), uses dense ``N x N`` pooling (the same cells and sector test as
:func:`predictors.pooling._grid_layout`), and is tested to match the torch model to float32 rounding. Sampling
still goes through torch.

A shipped checkpoint's unpacked arrays are also shipped as data (``<checkpoint stem>.kernel.npz``, listed in
the weights manifest, made by `save_kernel_file`): `load_kernel_file` builds the predictor from them without
importing torch (about 1.5 s of every process that only needs the most-likely paths), the same arrays
bit for bit, so the same predictions.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from crossing_common import compile_ahead
from predictors.constants import OBS_LEN, PRED_LEN

if TYPE_CHECKING:
    from predictors.models import SocialRecurrent


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

    :meth:`predict` runs the compiled :func:`_rollout_kernel` on weights unpacked once here. S-CGRU uses
    :meth:`~predictors.cgru.ComplexGRUCell.fused_weights` (its gates' mixing folded into the matrices).
    """

    def __init__(self, model: SocialRecurrent) -> None:
        import torch

        c = model.config
        self.config = c
        sd = {k: v.detach().cpu().numpy().astype(np.float32) for k, v in model.state_dict().items()}
        self.w_in, self.b_in = sd["input_embed.weight"].T.copy(), sd["input_embed.bias"]
        self.pooling = model.pooling
        if self.pooling:
            self.b_pool = sd["pool_embed.bias"]
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
        self._kernel_args = self._pack(model)

    def _pack(self, model: SocialRecurrent) -> tuple[object, ...]:
        """Arguments of :func:`_rollout_kernel` after ``obs``.

        Absent parts are 1-element dummies of the same rank, so every model kind shares one compiled
        signature.
        """
        import torch

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

    def predict(self, obs: np.ndarray) -> np.ndarray:
        """``(N, 12, 2)`` most-likely future of ``obs (N, 8, 2)``, one window, via the compiled kernel."""
        return _rollout_kernel(np.ascontiguousarray(obs, np.float32), *self._kernel_args)

    def compile_kernel(self) -> None:
        """Compile (or load) the kernel for this predictor's arguments: one prediction of a still window."""
        self.predict(np.zeros((2, OBS_LEN, 2), np.float32))


def kernel_is_cached() -> bool:
    """Whether numba's on-disk cache holds a compiled `_rollout_kernel` for this source file.

    `crossing_common.compile_ahead.is_cached`: True where numba's index cannot be read, so that nothing
    is compiled aside (`crossing_eval.tasks.warm_up`) and the kernel compiles where it is first called.
    """
    return compile_ahead.is_cached(_rollout_kernel)


KERNEL_SUFFIX = ".kernel.npz"
"""Suffix replacing ``.pt`` in the name of a checkpoint's kernel file."""
KERNEL_ARRAYS = (
    "geometry",
    "flags",
    "w_in",
    "b_in",
    "w_x_emb",
    "w_x_soc",
    "b_x",
    "w_cells",
    "b_pool",
    "empty_soc",
    "w_head",
    "b_head",
    "u_a",
    "u_b",
    "b_u",
)
"""The array arguments of :func:`_rollout_kernel` after ``kind``, in order, as named in a kernel file."""


def kernel_file(checkpoint: str | Path) -> Path:
    """The kernel file beside `checkpoint` (``s-cgru_all.pt`` → ``s-cgru_all.kernel.npz``)."""
    path = Path(checkpoint)
    return path.with_name(path.stem + KERNEL_SUFFIX)


def save_kernel_file(checkpoint: str | Path) -> Path:
    """Write the kernel file of `checkpoint` (loaded with torch, every check) beside it; returns its path.

    It records the checkpoint's sha256, so a retrained checkpoint never meets an old kernel file. Add the
    file to the manifest afterwards (``python -m studies.verify_weights --update``).
    """
    from predictors.checkpoints import load_model, sha256_file

    checkpoint = Path(checkpoint)
    fast = FastPredictor(load_model(checkpoint))
    kind, *arrays, obs_len, pred_len = fast._kernel_args
    assert (obs_len, pred_len) == (OBS_LEN, PRED_LEN) and len(arrays) == len(KERNEL_ARRAYS)
    out = kernel_file(checkpoint)
    with out.open("wb") as fh:
        np.savez(
            fh,
            kind=np.int64(kind),
            source_sha256=np.str_(sha256_file(checkpoint)),
            **dict(zip(KERNEL_ARRAYS, arrays, strict=True)),
        )
    return out


def load_kernel_file(checkpoint: str | Path) -> FastPredictor | None:
    """The shipped `checkpoint`'s predictor from its kernel file, without torch; None where there is none.

    None too (the caller then loads the checkpoint with torch) when the kernel file was made from other
    bytes than the checkpoint's, or the checkpoint is not a shipped one.

    Raises:
        predictors.checkpoints.CheckpointError: the checkpoint or its kernel file differs from the
            manifest, or holds non-finite or huge weights.
    """
    from predictors.checkpoints import (
        MAX_ABS_WEIGHT,
        CheckpointError,
        is_shipped,
        sha256_file,
        verify_shipped,
    )

    checkpoint = Path(checkpoint)
    path = kernel_file(checkpoint)
    if not (checkpoint.is_file() and path.is_file() and is_shipped(checkpoint)):
        return None
    verify_shipped(checkpoint)
    verify_shipped(path)
    with np.load(path, allow_pickle=False) as data:
        if str(data["source_sha256"]) != sha256_file(checkpoint):
            return None
        kind = int(data["kind"])
        arrays = [np.ascontiguousarray(data[name]) for name in KERNEL_ARRAYS]
    for name, a in zip(KERNEL_ARRAYS, arrays, strict=True):
        if a.dtype.kind == "f" and not (
            np.isfinite(a).all() and np.abs(a).max(initial=0.0) <= MAX_ABS_WEIGHT
        ):
            raise CheckpointError(f"{path}: non-finite or huge values in {name!r}")
    fast = FastPredictor.__new__(FastPredictor)
    fast._kernel_args = (kind, *arrays, OBS_LEN, PRED_LEN)
    return fast
