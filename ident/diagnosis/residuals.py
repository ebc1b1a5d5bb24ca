"""Where a model and a measurement disagree: the residual by regime, and ``resid``-style tests.

:func:`regime_breakdown` splits the free-run residual ``r = y - y_hat`` by
the regime each sample belongs to (direction of motion, just after a
reversal, input amplitude band, velocity band, part of the record) and
reports, per regime, its share of the samples and of the error energy
``sum r^2``. A regime that holds much more of the energy than of the samples
is where the model is missing something; :func:`where_text` says it in words.

:func:`residual_tests` are the classic checks of a fitted model (Ljung, *System
Identification*, 2nd ed., sec. 16.6; MATLAB's ``resid``): the
autocorrelation of the residual and its cross-correlation with past inputs,
each with a confidence band ``z / sqrt(N)``. Correlation outside the band
means the residual still holds structure a model could explain.

Whiteness has one owner, :attr:`ResidualTests.white`: the portmanteau test of
sec. 16.6 (``N sum_{k=1..M} r_k^2`` against chi^2(M)) with the finite-sample
weights of Ljung & Box (1978), ``Q = N (N + 2) sum r_k^2 / (N - k)``, at the
level ``1 - confidence``. One test at a known level: counting lags outside the
band tests each lag at that level, so its level grows with the lag count (about
2.6 % over 25 lags at 1 %, one forgiven) and it misses a correlation spread thinly
over many lags. The band stays as the picture (resid.png) and says where.
Identification's verdict (:func:`servoid.ident.identify.identify`) reads the
same test on the same residual (compare's), so the warning and the verdict agree.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2, norm

from servoid import validation
from servoid.errors import ConfigError

__all__ = [
    "Regime",
    "RegimeBreakdown",
    "regime_breakdown",
    "where_text",
    "ResidualTests",
    "residual_tests",
    "ljung_box",
    "is_white",
    "autocorrelation",
    "AUTOCORRELATION_BLOCK",
    "motion_direction",
]

#: Groups of regimes, in the order they are reported.
GROUPS = ("direction", "reversal", "input amplitude", "velocity", "time")


@dataclass(frozen=True)
class Regime:
    """One regime of a :class:`RegimeBreakdown`.

    Attributes
    ----------
    group : str
        One of :data:`GROUPS`.
    label : str
        E.g. ``"moving up"``, ``"within 5 samples after a reversal"``, ``"|u| in [0.6, 1.2)"``.
    samples : int
        Samples in the regime.
    sample_share : float
        Their share of the record, 0..1.
    energy_share : float
        Their share of the error energy ``sum r^2``, 0..1.
    rms : float
        RMS residual in the regime, unit of ``y``.
    mean : float
        Mean residual (a bias), unit of ``y``.
    """

    group: str
    label: str
    samples: int
    sample_share: float
    energy_share: float
    rms: float
    mean: float

    @property
    def concentration(self) -> float:
        """``energy_share / sample_share``: 1 means the error is spread evenly, above 1 it gathers here."""
        return self.energy_share / self.sample_share if self.sample_share > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        """``{"group", "regime", "samples", "sample_share", "energy_share", "rms", "mean"}``."""
        return {"group": self.group, "regime": self.label, "samples": self.samples, "sample_share": self.sample_share,
                "energy_share": self.energy_share, "rms": self.rms, "mean": self.mean}  # fmt: skip


@dataclass(frozen=True)
class RegimeBreakdown:
    """The residual of one free run, split by regime.

    Attributes
    ----------
    regimes : tuple of Regime
        Every regime of every group (within a group the regimes partition the record).
    residual_rms : float
        RMS of the whole residual, unit of ``y``.
    nrmse : float
        ``rms(r) / std(y)``.
    reversal_window : int
        Samples after a reversal counted as "just after".
    """

    regimes: tuple[Regime, ...]
    residual_rms: float
    nrmse: float
    reversal_window: int

    def to_dict(self) -> dict[str, Any]:
        """``{"regimes": [...], "residual_rms", "nrmse", "reversal_window"}``."""
        return {"regimes": [r.to_dict() for r in self.regimes], "residual_rms": self.residual_rms,
                "nrmse": self.nrmse, "reversal_window": self.reversal_window}  # fmt: skip

    def group(self, name: str) -> tuple[Regime, ...]:
        """The regimes of one group."""
        return tuple(r for r in self.regimes if r.group == name)

    def most_concentrated(self, *, min_energy_share: float = 0.2) -> Regime:
        """The regime whose error concentration is highest among those with a real share of the energy."""
        eligible = [r for r in self.regimes if r.energy_share >= min_energy_share and r.sample_share < 0.9]
        if not eligible:
            eligible = list(self.regimes)
        return max(eligible, key=lambda r: (r.concentration, r.energy_share))


def motion_direction(x: np.ndarray, *, threshold: float = 0.0) -> np.ndarray:
    """Direction of motion per sample: ``+1``, ``-1``, or ``0`` where ``|x(k) - x(k-1)| <= threshold``."""
    dx = np.diff(x, prepend=x[:1])
    out = np.sign(dx)
    out[np.abs(dx) <= threshold] = 0.0
    return out.astype(np.int8)


def _reversals(direction: np.ndarray) -> np.ndarray:
    """Indices where the direction of motion changes sign (standing still in between is ignored)."""
    moving = np.flatnonzero(direction != 0)
    if moving.size < 2:
        return np.empty(0, dtype=np.intp)
    d = direction[moving]
    out: np.ndarray = moving[1:][d[1:] != d[:-1]]
    return out


def _regime(group: str, label: str, mask: np.ndarray, r: np.ndarray, energy: float) -> Regime:
    n = int(np.count_nonzero(mask))
    part = r[mask]
    return Regime(
        group=group, label=label, samples=n, sample_share=n / r.size,
        energy_share=float(part @ part) / energy if energy > 0 else 0.0,
        rms=float(np.sqrt(np.mean(part**2))) if n else 0.0, mean=float(np.mean(part)) if n else 0.0,
    )  # fmt: skip


def _bands(values: np.ndarray, bands: int) -> list[tuple[float, float]]:
    edges = np.unique(np.quantile(values, np.linspace(0.0, 1.0, bands + 1)))
    return [(float(lo), float(hi)) for lo, hi in zip(edges[:-1], edges[1:])]


def regime_breakdown(
    y: Sequence[float] | np.ndarray,
    y_hat: Sequence[float] | np.ndarray,
    u: Sequence[float] | np.ndarray,
    motion: Sequence[float] | np.ndarray,
    *,
    reversal_window: int = 5,
    bands: int = 4,
    time_parts: int = 4,
    motion_threshold: float = 0.0,
    input_lag: int = 0,
) -> RegimeBreakdown:
    """Split the residual ``y - y_hat`` by regime.

    Parameters
    ----------
    y, y_hat : array_like
        Measured and simulated (free-run) output.
    u : array_like
        The input; its magnitude defines the amplitude bands.
    motion : array_like
        The position whose motion defines direction, reversals and velocity:
        the model's noise-free linear-block output ``x-hat`` (measured ``y``
        would make every noise wiggle a reversal).
    reversal_window : int
        A sample is "just after a reversal" if a reversal happened within the
        last ``reversal_window`` samples (the reversal sample included).
    bands : int
        Number of equally populated bands of ``|u|`` and of speed ``|motion(k) - motion(k-1)|``.
    time_parts : int
        Number of equal parts of the record in time.
    motion_threshold : float
        Steps of ``motion`` up to this size count as standing still.
    input_lag : int
        The amplitude bands are of ``|u(k - input_lag)|``: with the model's
        delay ``d`` this is the input that drives the output at ``k``
        (``u(0)`` stands in for the samples before the record).

    Returns
    -------
    RegimeBreakdown
    """
    y_arr = validation.signal("y", y)
    yh = validation.signal("y_hat", y_hat)
    u_arr = validation.signal("u", u)
    m_arr = validation.signal("motion", motion)
    if not (y_arr.size == yh.size == u_arr.size == m_arr.size):
        raise ConfigError(
            f"y, y_hat, u and motion must have the same length, got {y_arr.size}, {yh.size}, {u_arr.size}, {m_arr.size}"
        )
    window = validation.integer("reversal_window", reversal_window, minimum=1)
    bands = validation.integer("bands", bands, minimum=1)
    time_parts = validation.integer("time_parts", time_parts, minimum=1)
    lag = validation.integer("input_lag", input_lag, minimum=0)
    u_lagged = np.concatenate((np.full(min(lag, u_arr.size), u_arr[0]), u_arr[: u_arr.size - lag]))
    r = y_arr - yh
    energy = float(r @ r)
    n = r.size
    out: list[Regime] = []

    direction = motion_direction(m_arr, threshold=motion_threshold)
    for value, label in ((1, "moving up"), (-1, "moving down"), (0, "standing still")):
        mask = direction == value
        if mask.any():
            out.append(_regime("direction", label, mask, r, energy))

    after = np.zeros(n, dtype=bool)
    for k in _reversals(direction):
        after[k : k + window] = True
    out.append(_regime("reversal", f"within {window} samples after a reversal", after, r, energy))
    out.append(_regime("reversal", "away from reversals", ~after, r, energy))

    u_name = f"|u(k-{lag})|" if lag else "|u|"
    for group, values, name in (("input amplitude", np.abs(u_lagged), u_name),
                                ("velocity", np.abs(np.diff(m_arr, prepend=m_arr[:1])), "speed")):  # fmt: skip
        edges = _bands(values, bands)
        for i, (lo, hi) in enumerate(edges):
            last = i == len(edges) - 1
            mask = (values >= lo) & ((values <= hi) if last else (values < hi))
            out.append(_regime(group, f"{name} in [{lo:.3g}, {hi:.3g}{']' if last else ')'}", mask, r, energy))

    edges_t = np.linspace(0, n, time_parts + 1).astype(int)
    for lo, hi in zip(edges_t[:-1], edges_t[1:]):
        mask = np.zeros(n, dtype=bool)
        mask[lo:hi] = True
        out.append(_regime("time", f"samples {lo}..{hi - 1}", mask, r, energy))

    std = float(np.std(y_arr))
    rms = float(np.sqrt(energy / n))
    return RegimeBreakdown(regimes=tuple(out), residual_rms=rms, nrmse=rms / std if std > 0 else float("inf"),
                           reversal_window=window)  # fmt: skip


def where_text(breakdown: RegimeBreakdown) -> str:
    """Where the error concentrates, in words.

    For example: ``"62 % of the error energy lies within 5 samples after a
    reversal (31 % of the samples); the residual is biased +0.012 moving up
    and -0.011 moving down"``.
    """
    top = breakdown.most_concentrated()
    label = top.label
    if top.group == "direction" or top.group == "reversal":
        where = label if label.startswith(("within", "away")) else f"while {label}"
    elif top.group == "time":
        where = f"in {label}"
    else:
        where = f"where {label}"
    text = (
        f"{100 * top.energy_share:.0f} % of the error energy lies {where} "
        f"({100 * top.sample_share:.0f} % of the samples)"
    )
    up = [r for r in breakdown.group("direction") if r.label == "moving up"]
    down = [r for r in breakdown.group("direction") if r.label == "moving down"]
    if up and down and breakdown.residual_rms > 0:
        bias_up, bias_down = up[0].mean, down[0].mean
        # A bias that flips sign with the direction of motion is the fingerprint of friction or play.
        if abs(bias_up) > 0.2 * breakdown.residual_rms and abs(bias_down) > 0.2 * breakdown.residual_rms:
            text += f"; the residual is biased {bias_up:+.3g} moving up and {bias_down:+.3g} moving down"
    return text


@dataclass(frozen=True)
class ResidualTests:
    """Residual autocorrelation and cross-correlation with past inputs, with confidence bands.

    Attributes
    ----------
    lags : ndarray of int
        ``0 .. max_lag``.
    autocorrelation : ndarray
        Normalised autocorrelation of the residual at each lag (1 at lag 0).
    cross_correlation : ndarray
        Normalised cross-correlation of the residual with the input ``lag`` samples earlier.
    band : float
        Half-width ``z / sqrt(N)`` of the confidence band.
    confidence : float
        Its level (e.g. 0.99); the whiteness test's level is ``1 - confidence``.
    samples : int
        ``N``, the samples the correlations use.
    """

    lags: np.ndarray
    autocorrelation: np.ndarray
    cross_correlation: np.ndarray
    band: float
    confidence: float
    samples: int

    def to_dict(self) -> dict[str, Any]:
        """The verdicts, the band and the correlations at each lag (rounded to 1e-6)."""
        return {
            "confidence": self.confidence, "band": self.band, "white": self.white,
            "ljung_box_q": self.ljung_box_q, "ljung_box_limit": self.ljung_box_limit,
            "independent_of_input": self.independent_of_input,
            "autocorrelation_outside": self.autocorrelation_outside,
            "cross_correlation_outside": self.cross_correlation_outside,
            "autocorrelation": np.round(self.autocorrelation, 6).tolist(),
            "cross_correlation": np.round(self.cross_correlation, 6).tolist(),
        }  # fmt: skip

    def __repr__(self) -> str:
        return f"ResidualTests({self.summary()})"

    @property
    def autocorrelation_outside(self) -> int:
        """Lags >= 1 whose autocorrelation leaves the band."""
        return int(np.count_nonzero(np.abs(self.autocorrelation[1:]) > self.band))

    @property
    def cross_correlation_outside(self) -> int:
        """Lags whose cross-correlation with the input leaves the band."""
        return int(np.count_nonzero(np.abs(self.cross_correlation) > self.band))

    def _passes(self, values: np.ndarray) -> bool:
        # Chance puts a share (1 - confidence) of the lags outside the band (at
        # least one is forgiven), but never one at twice the band (z > 5).
        outside = int(np.count_nonzero(np.abs(values) > self.band))
        allowed = max(1, int(np.ceil((1 - self.confidence) * values.size)))
        return outside <= allowed and not np.any(np.abs(values) > 2.0 * self.band)

    @property
    def ljung_box_q(self) -> float:
        """The portmanteau statistic over lags ``1 .. max_lag`` (:func:`ljung_box`)."""
        return ljung_box(self.autocorrelation, self.samples)

    @property
    def ljung_box_limit(self) -> float:
        """The chi^2(``max_lag``) quantile at ``confidence`` that a white residual's statistic stays under."""
        return float(chi2.ppf(self.confidence, self.lags.size - 1))

    @property
    def white(self) -> bool:
        """The residual passes the Ljung-Box test at ``1 - confidence`` (the one whiteness rule; module docstring)."""
        return self.ljung_box_q <= self.ljung_box_limit

    def whiteness_text(self) -> str:
        """The test's numbers in words, the same wherever whiteness is reported."""
        verb = "passes" if self.white else "fails"
        return (
            f"{verb} the Ljung-Box test at {100 * (1 - self.confidence):.0f} % (Q = {self.ljung_box_q:.3g} over "
            f"{self.lags.size - 1} lags, limit {self.ljung_box_limit:.3g}; outside the {100 * self.confidence:.0f} % "
            f"band at {self.autocorrelation_outside}/{self.lags.size - 1} lags)"
        )

    @property
    def independent_of_input(self) -> bool:
        """The cross-correlation with past inputs stays within what chance allows."""
        return self._passes(self.cross_correlation)

    def summary(self) -> str:
        """One line: the whiteness test, and how many lags of the cross-correlation leave the band."""
        return (
            f"residual {self.whiteness_text()}; cross-correlation with past inputs outside the band at "
            f"{self.cross_correlation_outside}/{self.lags.size} lags"
        )


def residual_tests(
    residual: Sequence[float] | np.ndarray,
    u: Sequence[float] | np.ndarray,
    *,
    max_lag: int = 25,
    confidence: float = 0.99,
    valid: Sequence[bool] | np.ndarray | None = None,
) -> ResidualTests:
    """The ``resid`` checks: is the residual white, and independent of past inputs?

    Parameters
    ----------
    residual, u : array_like
        Residual ``y - y_hat`` and the input, same length.
    max_lag : int
        Largest lag, in samples.
    confidence : float
        Level of the band, in (0, 1); the band is ``z_{(1+confidence)/2} / sqrt(N)``.
    valid : array_like of bool, optional
        ``False`` marks samples left out (lost or late): they take part in no
        product, and ``N`` counts the others. Their residual may be NaN.

    Notes
    -----
    Under the hypothesis that the residual is white and independent of the
    input, each normalised correlation is approximately ``N(0, 1/N)``
    (Ljung, sec. 16.6), which gives the band.
    """
    u_arr = validation.signal("u", u)
    keep = None if valid is None else np.asarray(valid, dtype=np.bool_)
    if keep is None:
        r = validation.signal("residual", residual)
    else:
        r = np.asarray(residual, dtype=np.float64)
        if keep.shape != r.shape:
            raise ConfigError(f"valid and residual differ in shape: {keep.shape} against {r.shape}")
        validation.signal("residual", r[keep])
    if r.size != u_arr.size:
        raise ConfigError(f"residual and u differ in length: {r.size} against {u_arr.size}")
    max_lag = validation.integer("max_lag", max_lag, minimum=1)
    n = r.size if keep is None else int(np.count_nonzero(keep))
    if n <= 2 * max_lag:
        raise ConfigError(f"{n} samples are too few for max_lag={max_lag}: at least {2 * max_lag + 1} are needed")
    level = validation.in_unit_interval("confidence", confidence)
    # A left-out sample's residual is zero after centring: it adds nothing to any product.
    # the input's spread before the residual is centred: one temporary of the record's length at a time
    u_mean = float(u_arr.mean())
    u_ss = float(np.var(u_arr)) * u_arr.size
    rc = r - r.mean() if keep is None else np.where(keep, r - r[keep].mean(), 0.0)
    n_all = r.size
    denom_r = float(rc @ rc)
    denom_ru = float(np.sqrt(denom_r * u_ss))
    lags = np.arange(max_lag + 1)
    auto = autocorrelation(rc, max_lag)
    # rc[k:] @ (u - mean u)[:n-k] without the centred copy of u: the mean's part is mean(u) sum(rc[k:])
    cross = np.array([float(rc[k:] @ u_arr[: n_all - k]) - u_mean * float(rc[k:].sum()) for k in lags])
    cross /= denom_ru if denom_ru > 0 else 1.0
    band = float(norm.ppf(0.5 + level / 2.0) / np.sqrt(n))
    return ResidualTests(
        lags=lags, autocorrelation=auto, cross_correlation=cross, band=band, confidence=level, samples=n
    )


#: Samples per block of :func:`autocorrelation`.
AUTOCORRELATION_BLOCK = 1 << 16


def autocorrelation(r: np.ndarray, lags: int) -> np.ndarray:
    """The autocorrelation at lags ``0 .. lags`` (normalised to 1 at 0), block by block: the one computation of it.

    Each block of the centred ``r`` is correlated by FFT with itself and the
    next ``lags`` samples, and the sums add up: the same numbers as one FFT
    over the whole record, in memory independent of its length (the whole
    record's FFT of length ``2 n`` held ~56 bytes per sample, the peak of
    identify() at 10^6 samples).
    """
    x = np.asarray(r, dtype=np.float64)
    mean = float(np.mean(x))
    n = x.size
    block = max(AUTOCORRELATION_BLOCK, 4 * lags)
    ac = np.zeros(lags + 1)
    for lo in range(0, n, block):
        hi = min(n, lo + block)
        a = x[lo:hi] - mean
        b = x[lo : min(n, hi + lags)] - mean
        size = 1 << int(a.size + b.size - 1).bit_length()
        corr = np.fft.irfft(np.conj(np.fft.rfft(a, size)) * np.fft.rfft(b, size), size)
        m = min(lags + 1, b.size)
        ac[:m] += corr[:m]
    return ac / ac[0] if ac[0] > 0.0 else np.zeros(lags + 1)


def is_white(residual: np.ndarray, *, max_lag: int = 25, confidence: float = 0.99) -> bool:
    """Whether a residual on its own passes the Ljung-Box test: the rule of :attr:`ResidualTests.white`.

    For a residual without its input (a refinement's, to decide whether a
    fit at the floor ends the search); too short a residual, or a zero one,
    counts as white.

    Parameters
    ----------
    residual : ndarray
        The residual, every sample used.
    max_lag : int
        Largest lag, in samples.
    confidence : float
        ``1 -`` the test's level.
    """
    r = np.asarray(residual, dtype=np.float64)
    if r.size <= 2 * max_lag or float(np.std(r)) == 0.0:
        return True
    auto = autocorrelation(r, max_lag)
    return ljung_box(auto, r.size) <= float(chi2.ppf(confidence, max_lag))


def ljung_box(autocorrelation: np.ndarray, samples: int) -> float:
    """Ljung & Box's portmanteau statistic ``Q = N (N + 2) sum_{k=1..M} r_k^2 / (N - k)``.

    Parameters
    ----------
    autocorrelation : ndarray
        The normalised autocorrelation at lags ``0 .. M`` (1 at lag 0).
    samples : int
        ``N``, the samples it was computed from (``> M``).

    Returns
    -------
    float
        ``Q``, chi^2(M)-distributed for a white residual (Ljung, sec. 16.6).
    """
    r = np.asarray(autocorrelation, dtype=np.float64)[1:]
    k = np.arange(1, r.size + 1)
    return float(samples * (samples + 2) * np.sum(r**2 / (samples - k)))
