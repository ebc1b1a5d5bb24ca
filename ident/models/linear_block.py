"""The linear block of a pseudo-Wiener model as a transfer function: its polynomials, frequency and step responses.

The linear block of eq. (1) is ``G(z) = z^-d B(z^-1) / A(z^-1)`` with
``A = 1 + a_1 z^-1 + ... + a_na z^-na`` and ``B = b_0 + ... + b_nb z^-nb``;
it maps the input ``u`` to the (unmeasurable) position ``x`` before the
backlash, in ``x``'s unit per unit of ``u``. The backlash that follows is
nonlinear and has no transfer function: a Bode or step view of the model is
a view of this block, with the play (``c1 + c2``) said beside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, MissingDependency

if TYPE_CHECKING:  # pragma: no cover
    # only the model's attributes are read; BacklashModel.to_control imports this module
    from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["polynomials", "FrequencyResponse", "frequency_response", "step_response", "to_control"]


def polynomials(model: BacklashModel) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator of the linear block in descending powers of ``z``.

    ``G(z) = z^-d B(z^-1) / A(z^-1)`` multiplied above and below by ``z^n``,
    ``n = max(na, d + nb)``: the form python-control and ``scipy.signal``'s
    ``dlti`` take.

    Parameters
    ----------
    model : BacklashModel
        The model whose linear block is wanted.

    Returns
    -------
    num, den : ndarray
        ``num`` has ``n - d + 1`` entries (``b`` followed by zeros), ``den``
        ``n + 1`` (``1, a_1 .. a_na`` followed by zeros).
    """
    n = max(model.na, model.delay + model.nb)
    num = np.concatenate((np.asarray(model.b, dtype=np.float64), np.zeros(n - model.delay - model.nb)))
    den = np.concatenate(([1.0], np.asarray(model.a, dtype=np.float64), np.zeros(n - model.na)))
    return num, den


@dataclass(frozen=True)
class FrequencyResponse:
    """The linear block's frequency response.

    Attributes
    ----------
    frequency : ndarray
        Normalised frequency in cycles per sample, ``(0, 0.5]`` (``0.5`` is Nyquist).
    response : ndarray of complex
        ``G(e^{j 2 pi f})``, in ``x``'s unit per unit of ``u``.
    """

    frequency: np.ndarray
    response: np.ndarray

    @property
    def magnitude_db(self) -> np.ndarray:
        """``20 log10 |G|`` (dB)."""
        out: np.ndarray = 20.0 * np.log10(np.maximum(np.abs(self.response), 1e-300))
        return out

    @property
    def phase_deg(self) -> np.ndarray:
        """Unwrapped phase of ``G`` in degrees, the delay's included."""
        out: np.ndarray = np.degrees(np.unwrap(np.angle(self.response)))
        return out


def frequency_response(model: BacklashModel, *, points: int = 400, lowest: float = 1e-4) -> FrequencyResponse:
    """The linear block's frequency response on a logarithmic grid up to Nyquist.

    Parameters
    ----------
    model : BacklashModel
        The model.
    points : int
        Number of frequencies, at least 2.
    lowest : float
        Lowest frequency in cycles per sample, in ``(0, 0.5)``.

    Returns
    -------
    FrequencyResponse
    """
    points = validation.integer("points", points, minimum=2)
    lowest = validation.positive("lowest", lowest)
    if lowest >= 0.5:
        raise ConfigError(f"lowest (={lowest!r}) must be below 0.5 cycles per sample (Nyquist)")
    f = np.logspace(np.log10(lowest), np.log10(0.5), points)
    z_inv = np.exp(-2j * np.pi * f)
    # Evaluated in z^-1 as eq. (1) is written: B(z^-1) z^-d / A(z^-1).
    b = np.polynomial.polynomial.polyval(z_inv, np.asarray(model.b))
    a = np.polynomial.polynomial.polyval(z_inv, np.concatenate(([1.0], model.a)))
    return FrequencyResponse(frequency=f, response=b * z_inv**model.delay / a)


def step_response(model: BacklashModel, samples: int) -> np.ndarray:
    """The linear block's response ``x(k)`` to a unit step of ``u`` at ``k = 0``, from rest.

    Parameters
    ----------
    model : BacklashModel
        The model.
    samples : int
        Length of the response, at least 1.

    Returns
    -------
    ndarray
        ``x(0) .. x(samples - 1)``, in ``x``'s unit per unit of ``u``; it
        settles at :attr:`BacklashModel.dc_gain`.
    """
    from scipy.signal import lfilter

    n = validation.integer("samples", samples, minimum=1)
    b = np.concatenate((np.zeros(model.delay), model.b))
    out: np.ndarray = lfilter(b, np.concatenate(([1.0], model.a)), np.ones(n))
    return out


def to_control(model: BacklashModel, dt: float | bool = True) -> Any:
    """The linear block as a python-control ``TransferFunction`` (discrete time).

    Parameters
    ----------
    model : BacklashModel
        The model.
    dt : float or True
        Sample period in seconds; ``True`` for a discrete-time system whose
        period is not known.

    Returns
    -------
    control.TransferFunction
        ``G(z)`` of :func:`polynomials`, input ``u``, output ``x``.

    Raises
    ------
    MissingDependency
        Without python-control (``pip install 'servoid[control]'``).
    """
    if dt is not True:
        dt = validation.positive("dt", dt)
    try:
        import control
    except ImportError:
        raise MissingDependency("to_control() needs python-control: pip install 'servoid[control]'") from None
    num, den = polynomials(model)
    return control.TransferFunction(num, den, dt, inputs="u", outputs="x")
