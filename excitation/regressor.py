"""The MRGIA's regressor along a model's own trajectory: eq. (25) with eqs (39)-(42).

What the estimator would see if its estimate were the model itself: the
true ``x``, the switching functions of that model, and ``g4``/``g5`` of eqs
(35)-(36) from the noise-free output. Its information matrix
``(1/n) sum Phi(k) h(k) h(k)^T`` tells, before a sample is sent, whether an
input can make the parameters identifiable (Lemma 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import Simulation

__all__ = ["Regressor", "regressor"]


@dataclass(frozen=True)
class Regressor:
    """``h(k)`` and ``Phi(k)`` for every sample of a simulation.

    Attributes
    ----------
    h : ndarray, shape (n, na + nb + 4)
        Rows ``h(k)^T`` of eq. (25), columns in the order of ``theta`` (eq. 15).
    phi : ndarray of bool, shape (n,)
        ``Phi(k)`` of eq. (42): the samples on which the MRGIA updates.
    names : tuple of str
        Parameter names of the columns (``a1 .. b0 .. m2, c1, c2``).
    """

    h: np.ndarray
    phi: np.ndarray
    names: tuple[str, ...]

    def information(self) -> np.ndarray:
        """``(1/n) sum_k Phi(k) h(k) h(k)^T`` over all ``n`` samples.

        Only samples with ``Phi = 1`` add information, as in eq. (48): on the
        others the MRGIA leaves ``P`` unchanged. Dividing by every sample (not
        only the updated ones) makes it the information gained per sample sent.
        """
        used = self.h[self.phi]
        n = max(self.h.shape[0], 1)
        out: np.ndarray = used.T @ used / n
        return out


def _lagged(values: np.ndarray, lag: int) -> np.ndarray:
    """``values(k - lag)``, zero before the start."""
    out = np.zeros_like(values)
    if lag < values.size:
        out[lag:] = values[: values.size - lag]
    return out


def regressor(model: BacklashModel, sim: Simulation, *, y0: float = 0.0) -> Regressor:
    """Build ``h(k)`` and ``Phi(k)`` along ``sim``, the noise-free run of ``model``.

    Parameters
    ----------
    model : BacklashModel
        The model whose switching functions are used (normally ``sim.model``).
    sim : Simulation
        Its run: ``u``, ``x`` and ``y_clean`` are used.
    y0 : float
        Backlash output before the first sample, as given to ``simulate``.

    Notes
    -----
    Per sample, as the MRGIA kernel (:mod:`servoid.ident.online._mrgia_kernel`) does
    with the estimate replaced by ``model``:

    * ``g3 = [dx(k) < 0]`` (eq. 34) and ``m(k) = 1 + (m2 - 1) g3`` (eq. 26);
    * ``g1 = [y(k-1) + c1 < x(k)]``, ``g2 = [y(k-1)/m2 - c2 > x(k)]`` (eqs 32, 33);
    * ``g4 = [y(k) > y(k-1)]``, ``g5 = [y(k) < y(k-1)]`` (eqs 35, 36);
    * ``Phi = [g1 g4 = 1 or g2 g5 = 1]`` (eq. 42);
    * ``h = [-x(k-1) .. -x(k-na), u(k-d) .. u(k-d-nb), g3 x(k),
      -0.5 m (sgn dx + 1) g1 g4, 0.5 m (1 - sgn dx) g2 g5]`` (eq. 25 read with
      the signs of eq. 14, and eqs 39-41).

    The first sample has no ``y(k-1)`` measured yet and gets ``Phi = 0``.
    """
    x, y, u = sim.x, sim.y_clean, sim.u
    x_prev = _lagged(x, 1)
    y_prev = _lagged(y, 1)
    if y.size:
        y_prev[0] = y0
    dx = x - x_prev
    g3 = dx < 0.0
    m = 1.0 + (model.m2 - 1.0) * g3
    sign = np.sign(dx)
    up = (y_prev + model.c1 < x) & (y > y_prev)
    down = (y_prev / model.m2 - model.c2 > x) & (y < y_prev)
    phi = up | down
    if phi.size:
        phi[0] = False
    columns = [-_lagged(x, i) for i in range(1, model.na + 1)]
    columns += [_lagged(u, model.delay + j) for j in range(model.nb + 1)]
    columns += [g3 * x, -0.5 * m * (sign + 1.0) * up, 0.5 * m * (1.0 - sign) * down]
    return Regressor(h=np.column_stack(columns), phi=phi, names=model.names)
