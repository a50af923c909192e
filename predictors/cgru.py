"""Complex-valued gated recurrent cell built from pairs of real matrices (cgRNN style).

Departure from the S-CGRU paper (Xu et al. 2023): its printed equations mix complex gates with a
``(1 - z) * h + z * h~`` update but do not say how a complex gate in ``(0, 1)`` is obtained, and applying the
holomorphic sigmoid/tanh to complex numbers has poles (unbounded gates, see ``shared/docs/dependencies.md``).
We follow Wolter & Yao, "Complex Gated Recurrent Neural Networks" (NeurIPS 2018) instead:

* the real input is lifted to ``x + 0i``; all pre-activations are complex affine maps
  ``W x + U h + b`` implemented with real matrices ``(W_re, W_im)``, ``(U_re, U_im)``;
* reset and update gates are **real** via the mod-sigmoid ``sigmoid(a * Re g + (1 - a) * Im g)`` with a
  learned ``a`` in ``(0, 1)`` per gate;
* the candidate is ``modReLU(W x + U (r * h) + b)``, ``modReLU(z) = ReLU(|z| + b) z / |z|``, which keeps the
  phase and bounds nothing but the magnitude's offset;
* the update is the convex combination ``h' = (1 - z) * h + z * h~``.

A second departure from cgRNN: we do not keep ``U`` unitary with a Stiefel-manifold optimiser (plain Adam,
orthogonal-ish initialisation and gradient clipping instead), because sequences here are only 19 steps long.
The state is exposed to the rest of the model as the real vector ``[Re h, Im h]``.
"""

from __future__ import annotations

import math

import torch
from torch import nn


class ComplexGRUCell(nn.Module):
    """Complex GRU cell with real gates (mod-sigmoid), modReLU candidate and convex update.

    Args:
        input_size: real input width ``d``.
        hidden_size: complex hidden width ``h`` (the real state width is ``2h``).

    Real degrees of freedom: ``2 * (3h² + 3dh + 3h) + h + 2`` (complex weights and biases of the three
    pre-activations, the modReLU bias and the two mod-sigmoid mixing weights).
    """

    def __init__(self, input_size: int, hidden_size: int) -> None:
        super().__init__()
        self.input_size = input_size
        self.hidden_size = hidden_size
        h = hidden_size
        # Input map: real x -> 3 complex pre-activations (r, z, candidate); columns [re(3h) | im(3h)].
        self.w = nn.Linear(input_size, 6 * h)
        # Recurrent complex matrices for the gates (r, z) and the candidate, stored as real/imag parts.
        self.u_gates_re = nn.Parameter(torch.empty(h, 2 * h))
        self.u_gates_im = nn.Parameter(torch.empty(h, 2 * h))
        self.u_cand_re = nn.Parameter(torch.empty(h, h))
        self.u_cand_im = nn.Parameter(torch.empty(h, h))
        self.modrelu_bias = nn.Parameter(torch.zeros(h))
        self.gate_mix = nn.Parameter(torch.zeros(2))  # sigmoid(0) = 0.5: equal weight to Re and Im
        self.reset_parameters()

    def reset_parameters(self) -> None:
        """Uniform input weights; recurrent complex matrices scaled so that ``|U h| ~ |h|``."""
        bound = 1.0 / math.sqrt(self.input_size)
        nn.init.uniform_(self.w.weight, -bound, bound)
        nn.init.zeros_(self.w.bias)
        for p in (self.u_gates_re, self.u_gates_im, self.u_cand_re, self.u_cand_im):
            nn.init.orthogonal_(p)
            with torch.no_grad():
                p.mul_(1.0 / math.sqrt(2.0))
        nn.init.constant_(self.modrelu_bias, 0.0)

    @staticmethod
    def _complex_block(re: torch.Tensor, im: torch.Tensor) -> torch.Tensor:
        """Real ``(2h, 2k)`` matrix acting on ``[Re h, Im h]`` as the complex ``h @ (re + i im)``."""
        return torch.cat([torch.cat([re, im], dim=1), torch.cat([-im, re], dim=1)], dim=0)

    def recurrent_blocks(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Real block matrices of the recurrent maps; compute once per sequence, not per step."""
        return (
            self._complex_block(self.u_gates_re, self.u_gates_im),
            self._complex_block(self.u_cand_re, self.u_cand_im),
        )

    def forward(
        self,
        x: torch.Tensor,
        state: torch.Tensor,
        blocks: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> torch.Tensor:
        """One step.

        Args:
            x: ``(N, d)`` real input.
            state: ``(N, 2h)`` real view ``[Re h, Im h]`` of the complex state.
            blocks: output of :meth:`recurrent_blocks` (recomputed if ``None``).

        Returns:
            The next state ``(N, 2h)`` as ``[Re h, Im h]``.
        """
        h = self.hidden_size
        ug, uc = blocks if blocks is not None else self.recurrent_blocks()
        wx = self.w(x)  # (N, 6h): [re_r, re_z, re_c, im_r, im_z, im_c]
        wx_re, wx_im = wx[:, : 3 * h], wx[:, 3 * h :]
        g = state @ ug  # (N, 4h): [re_r, re_z, im_r, im_z]
        g_re = wx_re[:, : 2 * h] + g[:, : 2 * h]
        g_im = wx_im[:, : 2 * h] + g[:, 2 * h :]
        a = torch.sigmoid(self.gate_mix).repeat_interleave(h)  # (2h,)
        gates = torch.sigmoid(a * g_re + (1.0 - a) * g_im)
        r, z = gates[:, :h], gates[:, h:]
        rh = state * torch.cat([r, r], dim=1)
        c = rh @ uc  # (N, 2h): [re, im]
        c_re = wx_re[:, 2 * h :] + c[:, :h]
        c_im = wx_im[:, 2 * h :] + c[:, h:]
        mag = torch.sqrt(c_re * c_re + c_im * c_im + 1e-8)
        scale = torch.relu(mag + self.modrelu_bias) / mag
        cand = torch.cat([c_re * scale, c_im * scale], dim=1)
        z2 = torch.cat([z, z], dim=1)
        return (1.0 - z2) * state + z2 * cand
