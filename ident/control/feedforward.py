"""Feedforward through the linear block: the command that makes ``x`` follow a planned path.

The linear block of eq. (1) is ``x(k) = q^-d B(q^-1) / A(q^-1) u(k)``. Given
the path ``x_d`` ``P`` samples ahead, :class:`LinearInverse` returns the
command ``u(k)`` with Tomizuka's zero-phase-error tracking controller
(ZPETC, J. Dyn. Sys. Meas. Control 109 (1987) 65-68)::

    u(k) = A(q^-1) B_u*(q^-1) / (B_a(q^-1) B_u(1)^2)  x_d(k + P),   P = d + n_u

where ``B = B_a B_u`` splits the zeros of ``B`` into those the inverse may
cancel (``B_a``, well inside the unit circle) and the rest (``B_u``, ``n_u``
of them), and ``B_u*`` is ``B_u`` with its coefficients reversed. When every
zero is cancellable (always for ``n_b = 0``, the paper's case) this is the
exact model inverse with a ``d``-sample preview, and the model's ``x``
equals ``x_d`` from the ``d``-th sample on. Otherwise the result has zero
phase error and unit gain at DC, and a small gain error at high frequency.

Units: ``u`` in the command unit, ``x_d`` in the output unit; time in samples.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, ModelError
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["LinearInverse", "CANCELLABLE_ZERO_RADIUS"]

#: Zeros of B with at least this magnitude are not cancelled. Cancelling a
#: zero outside the unit circle makes an unstable command, and one close to it
#: (|z| = 0.95, say) a lightly damped command that rings at every step.
CANCELLABLE_ZERO_RADIUS = 0.9


def _split_numerator(b: Sequence[float]) -> tuple[int, np.ndarray, np.ndarray]:
    """``(leading zeros, B_a, B_u)`` of ``B(q^-1) = b0 + b1 q^-1 + ...`` as ascending coefficient arrays."""
    coeffs = np.asarray(b, dtype=np.float64)
    lead = int(np.flatnonzero(coeffs)[0])  # b0 = 0 is one more sample of delay
    coeffs = coeffs[lead:]
    zeros = np.roots(coeffs) if coeffs.size > 1 else np.empty(0)
    keep = np.abs(zeros) < CANCELLABLE_ZERO_RADIUS
    b_a = coeffs[0] * np.real(np.poly(zeros[keep]))
    b_u = np.real(np.poly(zeros[~keep]))
    return lead, np.atleast_1d(b_a), np.atleast_1d(b_u)


class LinearInverse:
    """ZPETC feedforward through a model's linear block, one sample at a time.

    Parameters
    ----------
    model : BacklashModel
        Only its linear block (``a``, ``b``, ``delay``) is used.
    x0 : float
        The linear block's output at rest at the start (output unit); the
        command history starts at the matching steady command ``x0 / dc_gain``.

    Raises
    ------
    ModelError
        If ``sum(b) = 0``: the block has no steady gain to invert.

    Notes
    -----
    Public state: :attr:`preview` (how many samples ahead :meth:`step` wants
    ``x_d``) and :attr:`uncancelled_zeros` (the zeros of ``B`` left in, see
    the module docstring). The recursion is the ZPETC difference equation
    ``sum_j D_j u(k-j) = sum_i N_i x_d(k+P-i)`` with ``D = B_a`` and
    ``N = A B_u* / B_u(1)^2``.
    """

    def __init__(self, model: BacklashModel, *, x0: float = 0.0) -> None:
        if abs(sum(model.b)) <= 1e-12 * sum(abs(v) for v in model.b):
            raise ModelError(
                f"the linear block with b (={model.b}) has a zero at z = 1 (sum(b) = 0): a constant command "
                "holds no position, so no feedforward can follow a path"
            )
        lead, b_a, b_u = _split_numerator(model.b)
        a = np.concatenate(([1.0], model.a))
        n_u = b_u.size - 1
        self._num = tuple(float(v) for v in np.convolve(a, b_u[::-1]) / float(np.sum(b_u)) ** 2)
        self._den = tuple(float(v) for v in b_a)
        self.preview = model.delay + lead + n_u
        self.uncancelled_zeros = tuple(complex(z) for z in np.roots(b_u)) if n_u else ()
        self._dc_gain = model.dc_gain
        self.reset(x0)

    def reset(self, x0: float = 0.0) -> None:
        """Rest at ``x = x0``: the path and the command histories at their steady values."""
        x0 = validation.real("x0", x0)
        self._x_hist: deque[float] = deque([x0] * len(self._num), maxlen=len(self._num))
        u0 = x0 / self._dc_gain
        self._u_hist: deque[float] = deque([u0] * max(len(self._den) - 1, 1), maxlen=max(len(self._den) - 1, 1))

    def step(self, x_ahead: float) -> float:
        """The command ``u(k)`` for the wanted linear-block output ``x_d(k + preview)``."""
        if not math.isfinite(x_ahead):
            raise ConfigError(f"x_ahead (={x_ahead!r}) must be finite")
        self._x_hist.appendleft(float(x_ahead))
        acc = 0.0
        for n_i, x_i in zip(self._num, self._x_hist):
            acc += n_i * x_i
        for d_j, u_j in zip(self._den[1:], self._u_hist):
            acc -= d_j * u_j
        u = acc / self._den[0]
        self._u_hist.appendleft(u)
        return u
