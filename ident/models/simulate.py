"""Simulate the pseudo-Wiener model, with optional measurement noise."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.models.kernels import ZONE_DOWN, ZONE_MEMORY, ZONE_UP, rest_kernel, simulate_kernel
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["Simulation", "simulate", "free_run", "noise_std_for_snr"]


@dataclass(frozen=True)
class Simulation:
    """A simulated record.

    Attributes
    ----------
    model : BacklashModel
        The plant.
    u : ndarray
        Input.
    x : ndarray
        Output of the linear block (not measurable on a real servo).
    y_clean : ndarray
        Output of the backlash, noise-free.
    y : ndarray
        Measured output: ``y_clean`` plus Gaussian measurement noise.
    zone : ndarray of int8
        Per sample: ``1`` up line, ``-1`` down line, ``0`` memory zone.
    noise_std : float
        Standard deviation of the added noise (0 when noise-free).
    snr : float or None
        The requested signal-to-noise ratio, if any.
    """

    model: BacklashModel
    u: np.ndarray
    x: np.ndarray
    y_clean: np.ndarray
    y: np.ndarray
    zone: np.ndarray
    noise_std: float
    snr: float | None

    def __repr__(self) -> str:
        noise = f"noise std {self.noise_std:.4g}" + (f" (SNR {self.snr:g})" if self.snr is not None else "")
        return f"Simulation({self.u.size} samples, {noise if self.noise_std > 0 else 'noise-free'}; {self.model!r})"

    @property
    def zone_shares(self) -> dict[str, float]:
        """Share of samples on the up line, the down line and in the memory zone."""
        n = max(self.zone.size, 1)
        return {
            "up": float(np.count_nonzero(self.zone == ZONE_UP)) / n,
            "down": float(np.count_nonzero(self.zone == ZONE_DOWN)) / n,
            "memory": float(np.count_nonzero(self.zone == ZONE_MEMORY)) / n,
        }

    @property
    def beyond_crossing(self) -> int:
        """Number of samples whose ``x`` lies beyond the crossing of the up and down lines.

        There the paper's model is ambiguous and servoid's direction rule
        applies (see :mod:`servoid.ident.models.pseudo_wiener`); 0 when ``m2 == 1``.
        """
        cross = self.model.lines_cross_at
        if cross is None:
            return 0
        beyond = self.x < cross if self.model.m2 > 1.0 else self.x > cross
        return int(np.count_nonzero(beyond))


def noise_std_for_snr(y_clean: np.ndarray, snr: float) -> float:
    """Noise standard deviation giving ``snr``, the paper's ``sqrt(var(y) / var(v))``.

    Parameters
    ----------
    y_clean : ndarray
        The noise-free output.
    snr : float
        Signal-to-noise ratio, ``> 0``.
    """
    snr = validation.positive("snr", snr)
    std = float(np.std(y_clean))
    if std == 0.0:
        raise ConfigError("the noise-free output is constant, so an SNR cannot be set; raise the input amplitude")
    return std / snr


def _run(
    model: BacklashModel, u: np.ndarray, y0: float, delta0: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x = np.empty_like(u)
    y = np.empty_like(u)
    zone = np.empty(u.shape, dtype=np.int8)
    a, b = np.asarray(model.a), np.asarray(model.b)
    if delta0 is None:
        simulate_kernel(a, b, model.delay, model.m2, model.c1, model.c2, u, y0, x, y, zone)
    else:
        rest_kernel(a, b, model.delay, model.m2, model.c1, model.c2, u, y0, delta0, x, y, zone)
    return x, y, zone


def simulate(
    model: BacklashModel,
    u: Sequence[float] | np.ndarray,
    *,
    snr: float | None = None,
    noise_std: float | None = None,
    rng: np.random.Generator | int | None = None,
    y0: float = 0.0,
    delta0: float | None = None,
) -> Simulation:
    """Simulate ``model`` from rest on the input ``u``.

    Parameters
    ----------
    model : BacklashModel
        The plant.
    u : array_like
        Input, finite, 1-D.
    snr : float, optional
        Add Gaussian measurement noise with this signal-to-noise ratio, defined
        as in the paper: the square root of the ratio of the output and noise
        variances (so ``noise_std = std(y_clean) / snr``).
    noise_std : float, optional
        Add Gaussian noise with this standard deviation instead.
    rng : numpy.random.Generator or int, optional
        Source of the noise (or its seed); required when noise is requested.
    y0 : float
        Backlash output before the first sample (``x`` starts at 0).
    delta0 : float, optional
        Start at rest with the linear block at ``x = y0 + delta0`` instead
        (:func:`free_run`).

    Returns
    -------
    Simulation
    """
    u_arr = validation.signal("u", u)
    y0 = validation.real("y0", y0)
    d0 = None if delta0 is None else validation.real("delta0", delta0)
    if snr is not None and noise_std is not None:
        raise ConfigError("give snr or noise_std, not both")
    x, y_clean, zone = _run(model, u_arr, y0, d0)
    std = 0.0
    if snr is not None:
        std = noise_std_for_snr(y_clean, snr)
    elif noise_std is not None:
        std = validation.non_negative("noise_std", noise_std)
    y = y_clean
    if std > 0.0:
        if rng is None:
            raise ConfigError("noise requested without rng: pass rng=np.random.default_rng(seed) or a seed")
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        y = y_clean + gen.normal(0.0, std, size=y_clean.size)
    return Simulation(
        model=model, u=u_arr, x=x, y_clean=y_clean, y=y, zone=zone, noise_std=std,
        snr=None if snr is None else float(snr),
    )  # fmt: skip


def free_run(
    model: BacklashModel, u: Sequence[float] | np.ndarray, *, y0: float = 0.0, delta0: float | None = None
) -> np.ndarray:
    """Noise-free output of ``model`` driven by ``u`` from rest (the free-run simulation ``y-hat``).

    Parameters
    ----------
    model : BacklashModel
        The model.
    u : array_like
        Input.
    y0 : float
        Backlash output before the first sample.
    delta0 : float, optional
        Where in the play the record starts: the linear block then starts at
        rest at ``x = y0 + delta0`` (:func:`~servoid.ident.models.kernels.rest_kernel`,
        what :func:`servoid.ident.identify.identify` fits). None: ``x`` starts at 0.
    """
    d0 = None if delta0 is None else validation.real("delta0", delta0)
    return _run(model, validation.signal("u", u), validation.real("y0", y0), d0)[1]
