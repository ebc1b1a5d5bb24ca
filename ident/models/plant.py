"""The backlash servo stepped one sample at a time: the physics of every simulated servo.

:class:`Plant` is what the simulated driver and the emulators (serial
firmware, CAN drives, Dynamixel) put behind their protocols. It gives the same
numbers as :func:`servoid.ident.models.simulate` (tested), and its model can be
swapped while it runs without losing the state, to simulate wear.
"""

from __future__ import annotations

from collections import deque

from servoid import validation
from servoid.errors import ModelError
from servoid.ident.models.kernels import backlash_step
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["Plant"]


class Plant:
    """A :class:`BacklashModel` with state, advanced by :meth:`step`.

    Parameters
    ----------
    model : BacklashModel
        Initial parameters.
    y0 : float
        Backlash output before the first sample.
    """

    def __init__(self, model: BacklashModel, *, y0: float = 0.0) -> None:
        self._model = model
        self._y0 = validation.real("y0", y0)
        self.reset()

    def reset(self) -> None:
        """Return to rest: zero input and ``x`` history, backlash output ``y0``."""
        m = self._model
        self._x_hist: deque[float] = deque([0.0] * m.na, maxlen=m.na)
        self._u_hist: deque[float] = deque([0.0] * (m.delay + m.nb), maxlen=m.delay + m.nb)
        self.x = 0.0
        self.y = self._y0

    @property
    def model(self) -> BacklashModel:
        """Current parameters."""
        return self._model

    @model.setter
    def model(self, new: BacklashModel) -> None:
        """Change the parameters in place (for wear); the orders must stay the same."""
        old = self._model
        if (new.na, new.nb, new.delay) != (old.na, old.nb, old.delay):
            raise ModelError(
                f"a running plant keeps its orders: (na, nb, delay) = ({old.na}, {old.nb}, {old.delay}), "
                f"got ({new.na}, {new.nb}, {new.delay})"
            )
        self._model = new

    def step(self, u: float) -> float:
        """Apply the input ``u(k)`` and return the noise-free output ``y(k)``.

        ``x(k)`` depends on ``u(k - d)`` and earlier, so the output responds to
        ``u`` from the ``d``-th call on.
        """
        m = self._model
        x = 0.0
        for a_i, x_i in zip(m.a, self._x_hist):
            x -= a_i * x_i
        # _u_hist[0] is u(k-1): u(k-d-j) sits at index d-1+j
        for j, b_j in enumerate(m.b):
            x += b_j * self._u_hist[m.delay - 1 + j]
        y, _zone = backlash_step(x, self.x, self.y, m.m2, m.c1, m.c2)
        self._x_hist.appendleft(x)
        self._u_hist.appendleft(float(u))
        self.x = x
        self.y = float(y)
        return self.y
