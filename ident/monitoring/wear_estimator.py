"""Following a servo's backlash while it works: the MRGIA in random-walk mode, with uncertainty and fit.

:class:`WearEstimator` is the estimator of ``servoid monitor``. It wraps the MRGIA
in random-walk mode (:meth:`MRGIAConfig.random_walk`: parameters as a random walk,
so the gain never vanishes; ``P`` capped and positive definite; updates only
where eq. (42) gives ``Phi = 1``) and adds what watching a servo for months
needs:

a known start
    ``theta(0)`` is the servo's identified model and ``P(0)`` small, so the
    estimates are sensible from the first sample and alarms need no warm-up.
one set of settings for every unit
    The estimator runs on ``u / s`` and ``y / s`` with ``s = c1 + c2`` of that
    model. The random-walk settings were measured where ``c1 + c2 = 1``
    (``benchmarks/random_walk.py``); normalising keeps them right whether the
    servo reports rad or encoder counts. A single ``q`` on unnormalised
    signals is wrong for one of the two kinds of parameter: sized for dead
    zones of 0.05 rad it freezes the linear block, and a wrong linear block
    biases the dead zones (the bench servo, noise-free, after its dead zones
    grew by half: 0.8 % low for good, against exact; benchmarks/random_walk.py).
uncertainty
    In random-walk mode the MRGIA is a Kalman filter (``mu = 1``, ``S = h'Ph +
    Sigma``, ``K = Ph / S``), so ``P`` is the covariance of the estimate:
    :meth:`WearEstimator.estimate` reports ``sqrt(diag P)`` (and the standard
    deviation of ``c1 + c2`` with the covariance of ``c1`` and ``c2``) in the
    servo's units. It assumes the parameters wander by ``q`` per update, so it
    is larger than the scatter of an estimate that holds still (measured
    1.75x on the paper's plant at SNR 40): a cautious figure.
fit
    The free-run output of the current estimate (the MRGIA's own ``x-hat``,
    eq. 27, through the estimated backlash) against the measured one, as a
    normalised RMS error ``rms(y - y_hat) / std(y)`` over an exponential
    window of ``fit_window`` samples: the same measure as ``servoid
    identify``'s free-run NRMSE, but recent.

Recovery from a stuck zone classification (see :mod:`servoid.ident.online.mrgia`)
stays on: it returns the backlash parameters to the servo's model and ``P``
to ``p0``, which is where a monitor would restart anyway; each is counted and
reported. Memory is constant: a few arrays of the size of ``theta``.

Units: ``u`` in the command unit, ``y``, ``c1``, ``c2`` and standard
deviations of them in the output unit; time in samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.defaults import DEFAULT_PROCESS_NOISE
from servoid.ident.models.kernels import backlash_step
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.online.mrgia import MRGIA, MRGIAConfig, RecoveryEvent, Step, noise_epsilon

__all__ = ["WearEstimatorConfig", "WearEstimate", "WearEstimator"]

#: Default P(0) relative to (c1 + c2)^2: a standard deviation of 10 % of the
#: dead zone, enough to absorb the wear since the model was identified.
DEFAULT_P0 = 1e-2


@dataclass(frozen=True, kw_only=True)
class WearEstimatorConfig:
    """What :class:`WearEstimator` starts from and how fast it follows.

    Parameters
    ----------
    reference : BacklashModel
        The servo's model (from ``model.json``): the start of the estimate
        and the scale ``s = c1 + c2`` of the normalisation.
    noise_std : float
        Standard deviation of the output noise, output unit; sets the
        threshold ``epsilon = E|v|`` of eqs (37), (38) (0: noise-free).
    epsilon : float, optional
        That threshold itself, output unit (instead of ``noise_std``).
    process_noise : float
        Random-walk variance of the parameters per update, relative to
        ``s^2``: larger follows wear faster and scatters more.
    p0 : float
        ``P(0)`` relative to ``s^2``.
    p_max : float
        Cap on ``P``'s diagonal, relative to ``s^2``.
    fit_window : int
        Samples in the exponential window of the fit.
    recover : bool
        Recover from a stuck zone classification (see :mod:`servoid.ident.online.mrgia`).
    """

    reference: BacklashModel
    noise_std: float = 0.0
    epsilon: float | None = None
    process_noise: float = DEFAULT_PROCESS_NOISE
    p0: float = DEFAULT_P0
    p_max: float = 1.0
    fit_window: int = 5000
    recover: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.reference, BacklashModel):
            raise ConfigError(f"reference (={self.reference!r}) must be a BacklashModel")
        validation.non_negative("noise_std", self.noise_std)
        if self.epsilon is not None:
            validation.non_negative("epsilon", self.epsilon)
        validation.positive("process_noise", self.process_noise)
        validation.positive("p0", self.p0)
        validation.positive("p_max", self.p_max)
        validation.integer("fit_window", self.fit_window, minimum=1)

    @property
    def scale(self) -> float:
        """``s = c1 + c2`` of the reference, output unit: the unit the estimator works in."""
        return self.reference.c1 + self.reference.c2

    def mrgia_config(self) -> MRGIAConfig:
        """The MRGIA settings, in normalised units (signals divided by :attr:`scale`)."""
        ref, s = self.reference, self.scale
        eps = self.epsilon if self.epsilon is not None else noise_epsilon(self.noise_std)
        theta0 = ref.theta
        theta0[ref.layout.c1 : ref.layout.c2 + 1] /= s
        return MRGIAConfig.random_walk(
            na=ref.na, nb=ref.nb, delay=ref.delay, epsilon=eps / s, process_noise=self.process_noise,
            p_max=self.p_max, p0=self.p0, theta0=tuple(theta0), recover=self.recover,
        )  # fmt: skip


@dataclass(frozen=True)
class WearEstimate:
    """The wear estimator's estimate at one moment, in the servo's units.

    Attributes
    ----------
    sample : int
        Samples processed so far (updated, held or skipped).
    updates : int
        Samples that updated the estimate (``Phi = 1``, eq. 42).
    names : tuple of str
        ``a1.., b0.., m2, c1, c2``.
    values, std : ndarray
        The estimate and its standard deviation, in the order of ``names``
        (``m2`` itself; ``c1``, ``c2`` in the output unit).
    dead_zone, dead_zone_std : float
        ``c1 + c2`` and its standard deviation (with the covariance of the two), output unit.
    fit : float
        Free-run NRMSE over the recent window (NaN until the window is full).
    coverage : tuple of float
        Line coverage (up, down) of the zone classification (:attr:`MRGIA.coverage`).
    recoveries : int
        Recoveries from a stuck zone classification so far.
    """

    sample: int
    updates: int
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    dead_zone: float
    dead_zone_std: float
    fit: float
    coverage: tuple[float, float]
    recoveries: int

    def value(self, name: str) -> float:
        """One parameter by name (``"c1"``, ``"m2"``, ``"a1"`` ...)."""
        return float(self.values[self._index(name)])

    def std_of(self, name: str) -> float:
        """The standard deviation of one parameter, by name."""
        return float(self.std[self._index(name)])

    def _index(self, name: str) -> int:
        if name not in self.names:
            raise ConfigError(f"no parameter {name!r}; the estimate has {', '.join(self.names)}")
        return self.names.index(name)

    def to_dict(self) -> dict[str, Any]:
        """For JSON: values and standard deviations by name, the dead zone, the fit, coverage, counts.

        ``fit`` is null until the fit's window is full (``fit_reason`` says so).
        """
        out: dict[str, Any] = {
            "sample": self.sample, "updates": self.updates,
            "values": dict(zip(self.names, self.values.tolist())), "std": dict(zip(self.names, self.std.tolist())),
            "dead_zone": self.dead_zone, "dead_zone_std": self.dead_zone_std, "fit": self.fit,
            "coverage": {"up": self.coverage[0], "down": self.coverage[1]}, "recoveries": self.recoveries,
        }  # fmt: skip
        if math.isnan(self.fit):
            out["fit_reason"] = "fewer samples measured than the fit's window"
        return out

    @property
    def c1(self) -> float:
        """``c1``, output unit."""
        return self.value("c1")

    @property
    def c2(self) -> float:
        return self.value("c2")

    @property
    def m2(self) -> float:
        return self.value("m2")

    @property
    def m2_std(self) -> float:
        return self.std_of("m2")


class WearEstimator:
    """The MRGIA in random-walk mode on normalised signals, with a running fit (see the module docstring).

    Parameters
    ----------
    config : WearEstimatorConfig
        Start, noise and random-walk settings.

    Examples
    --------
    >>> estimator = WearEstimator(WearEstimatorConfig(reference=model, noise_std=0.03))   # doctest: +SKIP
    >>> for u_k, y_k in zip(u, y):                                            # doctest: +SKIP
    ...     estimator.update(u_k, y_k)
    >>> estimator.estimate().dead_zone                                           # doctest: +SKIP
    """

    def __init__(self, config: WearEstimatorConfig) -> None:
        self.config = config
        self._inv_scale = 1.0 / config.scale
        self.estimator = MRGIA(config.mrgia_config())
        lay = self.estimator.config.layout
        self._x_at = lay.x_history.start  # x-hat(k), newest first, in the estimator's public state
        self._theta = self.estimator.config.theta_layout
        self._i_m2 = self._theta.m2
        self._alpha = 1.0 / config.fit_window
        self._reset_fit()

    def _reset_fit(self) -> None:
        self._x_prev = 0.0
        self._y_hat = 0.0
        self._err2 = 0.0  # exponentially weighted mean of (y - y_hat)^2, normalised units
        self._y_mean = 0.0
        self._y_sq = 0.0
        self._fit_seen = 0

    # -- stepping -----------------------------------------------------------------
    def update(self, u: float, y: float) -> Step:
        """Process a measured sample ``(u(k), y(k))`` (servo units).

        Raises
        ------
        EstimatorDiverged
            As :meth:`MRGIA.update` (the state is left as it was); :meth:`restart` starts again.
        """
        yn = y * self._inv_scale
        step = self.estimator.update(u * self._inv_scale, yn)
        y_hat = self._advance_output()
        a = self._alpha
        if self._fit_seen == 0:
            self._y_mean, self._y_sq = yn, yn * yn
        e = yn - y_hat
        self._err2 += a * (e * e - self._err2)
        self._y_mean += a * (yn - self._y_mean)
        self._y_sq += a * (yn * yn - self._y_sq)
        self._fit_seen += 1
        return step

    def skip(self, u: float) -> None:
        """Advance over a sample whose measurement was lost (see :meth:`MRGIA.skip`)."""
        self.estimator.skip(u * self._inv_scale)
        self._advance_output()

    def _advance_output(self) -> float:
        """The free-run output of the current estimate at this sample (normalised)."""
        state = self.estimator.state
        x = state[self._x_at]
        i = self._i_m2
        self._y_hat = backlash_step(x, self._x_prev, self._y_hat, 1.0 + state[i], state[i + 1], state[i + 2])[0]
        self._x_prev = x
        return float(self._y_hat)

    def restart(self) -> None:
        """Start again from the reference model (after a divergence)."""
        self.estimator.reset()
        self._reset_fit()

    def warm_up(self) -> None:
        """Compile the kernels now, on a scratch estimator: a first compile inside a sampling loop stalls it for seconds."""
        scratch = WearEstimator(self.config)
        for u, y in ((0.1, 0.0), (-0.1, 0.05), (0.2, -0.02)):
            scratch.update(u, y)
        scratch.skip(0.0)
        scratch.estimate()

    def current(self) -> dict[str, float]:
        """The current estimate by name, servo units (for progress lines)."""
        e = self.estimate()
        return dict(zip(e.names, (float(v) for v in e.values)))

    # -- state --------------------------------------------------------------------
    @property
    def samples(self) -> int:
        """Samples processed (updated, held or skipped)."""
        return self.estimator.samples

    @property
    def recoveries(self) -> tuple[RecoveryEvent, ...]:
        """Recoveries from a stuck zone classification (the abandoned estimate in normalised units)."""
        return self.estimator.recoveries

    @property
    def fit(self) -> float:
        """Free-run NRMSE over the recent window; NaN until ``fit_window`` samples were measured."""
        if self._fit_seen < self.config.fit_window:
            return math.nan
        var = self._y_sq - self._y_mean * self._y_mean
        return math.sqrt(self._err2 / var) if var > 0.0 else math.nan

    def estimate(self) -> WearEstimate:
        """The current estimate with standard deviations, in the servo's units."""
        est, s = self.estimator, self.config.scale
        cfg = est.config
        theta, P = est.theta, est.P
        unit = np.ones(cfg.n_params)
        lay = self._theta
        unit[lay.c1 : lay.c2 + 1] = s  # c1, c2 were estimated in units of s
        values = lay.values(theta * unit)
        cov = P * np.outer(unit, unit)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        c1, c2 = lay.c1, lay.c2
        dz_var = cov[c1, c1] + cov[c2, c2] + 2.0 * cov[c1, c2]
        return WearEstimate(
            sample=est.samples, updates=est.updates, names=BacklashModel.parameter_names(cfg.na, cfg.nb),
            values=values, std=std, dead_zone=float(values[c1] + values[c2]),
            dead_zone_std=math.sqrt(max(dz_var, 0.0)), fit=self.fit, coverage=est.coverage,
            recoveries=len(est.recoveries),
        )  # fmt: skip

    @property
    def model(self) -> BacklashModel:
        """The current estimate as a validated model in the servo's units (raises :class:`ModelError`)."""
        e = self.estimate()
        cfg = self.estimator.config
        return BacklashModel.from_theta(self._theta.theta(e.values), na=cfg.na, nb=cfg.nb, delay=cfg.delay)
