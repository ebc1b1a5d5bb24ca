"""The modified recursive general identification algorithm (MRGIA), eqs (17)-(42).

:class:`MRGIA` is the online estimator: ``update(u_k, y_k)`` per sample,
constant memory, explicit state (``theta``, ``P``, ``S``, ``K``, ``Sigma``, the
``x-hat`` and input histories). :func:`run_mrgia` is its batch twin over whole
arrays, with a compiled inner loop; both run the same kernel
(:mod:`servoid.ident.online._mrgia_kernel`, where each line cites its equation).

Two additions to the paper, both on by default and both switchable off
(``project=False, recover=False`` is the paper's algorithm as printed):

projection
    An update that would leave the set the model is defined on (unstable
    linear block, ``m2 <= 0``, negative dead zone) is refused. Without it an
    early, large update can make ``x-hat`` explode and freeze the gain.
recovery
    A few runs in a hundred of the paper's example (3 of 50 seeds in
    benchmarks/paper_example.py) get stuck early in a wrong zone classification: one backlash line never receives an update although the
    output keeps moving that way. The estimator watches the share of measured
    moves that the model puts on each line (its *line coverage*); when one
    stays below ``stuck_below`` after a warm-up, the backlash parameters and
    ``P`` are reset and estimation goes on. Each recovery is recorded.

Divergence (non-finite ``theta`` or ``P``) raises :class:`EstimatorDiverged`
with the sample index; a run that is still stuck at the end is reported by
:attr:`MRGIAResult.settled` and never handed out as a confident model.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, EstimatorDiverged, ModelError
from servoid.ident import defaults
from servoid.ident._jit import direct_call
from servoid.ident.models.pseudo_wiener import BacklashModel, ThetaLayout
from servoid.ident.online import _mrgia_kernel as _k
from servoid.ident.paper import PAPER_P0, PAPER_RHO_EXPONENT, PAPER_SIGMA0, paper_theta0

__all__ = [
    "MRGIAConfig",
    "MRGIA",
    "Step",
    "RecoveryEvent",
    "MRGIAResult",
    "run_mrgia",
    "noise_epsilon",
    "convergence_margin",
    "MARGIN_ROUNDING",
]


#: Samples per call of the compiled loop when progress is reported.
PROGRESS_CHUNK = 1 << 16

#: Smallest ``rho_exponent``: below about 1e-16, ``rho(1) = 2^-r`` rounds to 1 and eq. (30)'s
#: ``mu = rho(t-1)/rho(t) (1 - rho(t))`` to 0, by which eq. (21) divides.
MIN_RHO_EXPONENT = 1e-6


class Step(enum.IntEnum):
    """What one call of :meth:`MRGIA.update` did."""

    PRIMED = _k.STEP_PRIMED
    """First sample after a start or a gap: ``y(k-1)`` was unknown; nothing estimated."""
    HELD = _k.STEP_HELD
    """``Phi(k) = 0`` (eq. 42): the memory zone, nothing updated."""
    UPDATED = _k.STEP_UPDATED
    """``Phi(k) = 1``: ``theta``, ``P``, ``S``, ``K`` and ``Sigma`` updated."""
    REFUSED = _k.STEP_REFUSED
    """``Phi(k) = 1`` but the update would leave the feasible set (projection)."""


#: The members by code: a dict lookup costs a fraction of ``Step(code)``, which runs once per sample.
_STEPS: dict[int, Step] = {int(s): s for s in Step}

#: The kernel's return codes, the plain steps by position and None for those that need handling.
_STEP_OF: tuple[Step | None, ...] = tuple(_STEPS.get(code) for code in range(2 * _k.STEP_STUCK))


def _first_step(buf: np.ndarray, u: float, y: float) -> int:
    """The step compiled for ``(buffer, float, float)``, called past numba's dispatch from now on (ident/_jit.py)."""
    global _fast_step
    if _fast_step is None:
        _fast_step = direct_call(_k.mrgia_update, buf, 0.0, 0.0)  # floats, whatever this first call passes
    return _fast_step(buf, u, y)  # type: ignore[no-any-return]


_fast_step: Callable[..., Any] | None = None


@dataclass(frozen=True, kw_only=True)
class MRGIAConfig:
    """Settings of the MRGIA; the defaults are :mod:`servoid.ident.defaults` (what ``servoid identify`` runs).

    :meth:`paper` gives the paper's Section 4 settings (rho exponent 0.25, no
    projection, no recovery).

    Parameters
    ----------
    na, nb, delay : int
        Orders ``n_a >= 1``, ``n_b >= 0`` and delay ``d >= 1`` of eq. (1).
    rho_exponent : float
        ``r`` in the convergence factor ``rho(k) = (k + 1)^-r``, in
        [:data:`MIN_RHO_EXPONENT`, 1]; default 0.75. The paper uses 0.25; larger values forget more slowly
        and average output noise (:data:`servoid.ident.paper.RECOMMENDED_RHO_EXPONENT`).
    epsilon : float
        Threshold on ``|y(k) - y(k-1)|`` for the switching functions ``g4``,
        ``g5`` of eqs (37), (38), in the unit of ``y``. 0 gives eqs (35), (36)
        (noise-free data). With output noise of standard deviation ``s`` a good
        value is ``E|v| = sqrt(2/pi) s`` (:func:`noise_epsilon`).
    p0 : float
        ``P(0) = p0 I``, eq. (31).
    theta0 : sequence of float, optional
        ``theta(0)``; default the paper's ``b0 = 1``, all else 0.
    sigma0 : float
        ``Sigma(0)``.
    project : bool
        Refuse updates that leave the feasible set (servoid's addition).
    recover : bool
        Recover from a stuck zone classification (servoid's addition).
    stuck_below : float
        Line coverage below which a run counts as stuck, in (0, 1).
    coverage_window : int
        Length in samples of the exponential window of the line coverage.
    warmup : int
        Samples after a start or a recovery before the coverage is judged.
    max_recoveries : int
        After this many recoveries the run is left alone and reported unsettled.
    rho_floor : float
        Random-walk mode: ``rho(k)`` never falls below this, so the estimator
        keeps forgetting old data at the rate ``1 - rho_floor`` per update and
        follows slowly drifting parameters (0: the paper's ``rho``, which
        decays to zero, so the estimator eventually stops learning).
    process_noise : float
        Random-walk mode: ``q`` added to the diagonal of ``P`` at each update,
        i.e. the parameters are modelled as a random walk of variance ``q``
        per update (the Kalman-filter view of tracking).
    p_max : float
        Random-walk mode: cap on the diagonal of ``P``, so that directions the
        data do not excite for a long time cannot wind up (inf: no cap).
    """

    na: int = defaults.NA
    nb: int = defaults.NB
    delay: int = defaults.DELAY
    rho_exponent: float = defaults.RHO_EXPONENT
    epsilon: float = defaults.EPSILON
    p0: float = PAPER_P0
    theta0: tuple[float, ...] | None = None
    sigma0: float = PAPER_SIGMA0
    project: bool = True
    recover: bool = True
    stuck_below: float = 0.2
    coverage_window: int = 200
    warmup: int = 300
    max_recoveries: int = 20
    rho_floor: float = 0.0
    process_noise: float = 0.0
    p_max: float = float("inf")
    _theta0: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        na = validation.integer("na", self.na, minimum=1)
        nb = validation.integer("nb", self.nb, minimum=0)
        delay = validation.integer("delay", self.delay, minimum=1)
        r = validation.in_unit_interval("rho_exponent", self.rho_exponent, open_high=False)
        if r < MIN_RHO_EXPONENT:
            raise ConfigError(f"rho_exponent (={r!r}) must be >= {MIN_RHO_EXPONENT:g}: rho(k) would stay at 1")
        validation.non_negative("epsilon", self.epsilon)
        validation.positive("p0", self.p0)
        validation.positive("sigma0", self.sigma0)
        validation.in_unit_interval("stuck_below", self.stuck_below)
        validation.integer("coverage_window", self.coverage_window, minimum=1)
        validation.integer("warmup", self.warmup, minimum=0)
        validation.integer("max_recoveries", self.max_recoveries, minimum=0)
        validation.in_unit_interval("rho_floor", self.rho_floor, open_low=False)
        validation.non_negative("process_noise", self.process_noise)
        if not self.p_max > 0:
            raise ConfigError(f"p_max (={self.p_max!r}) must be > 0")
        n = na + nb + 4
        theta0 = paper_theta0(na, nb) if self.theta0 is None else tuple(self.theta0)
        if len(theta0) != n:
            raise ConfigError(f"theta0 has {len(theta0)} entries, na={na} and nb={nb} need {n}")
        th = validation.signal("theta0", theta0)
        object.__setattr__(self, "na", na)
        object.__setattr__(self, "nb", nb)
        object.__setattr__(self, "delay", delay)
        object.__setattr__(self, "rho_exponent", r)
        object.__setattr__(self, "theta0", tuple(float(v) for v in th))
        object.__setattr__(self, "_theta0", th)

    @classmethod
    def paper(
        cls, *, na: int = defaults.NA, nb: int = defaults.NB, delay: int = defaults.DELAY, epsilon: float = 0.0
    ) -> MRGIAConfig:
        """The algorithm exactly as the paper prints it: no projection, no recovery, the paper's rho exponent."""
        return cls(na=na, nb=nb, delay=delay, epsilon=epsilon, rho_exponent=PAPER_RHO_EXPONENT, project=False,
                   recover=False)  # fmt: skip

    @classmethod
    def random_walk(
        cls,
        *,
        na: int = 2,
        nb: int = 0,
        delay: int = 1,
        epsilon: float = 0.0,
        process_noise: float = 1e-7,
        p_max: float = 1.0,
        **kwargs: object,
    ) -> MRGIAConfig:
        """Settings for following slowly changing parameters (wear) for as long as the servo runs.

        The paper's ``rho(k)`` decays to zero, so the estimator eventually
        stops learning. Random-walk mode keeps the gain alive by modelling the
        parameters as a random walk: ``q`` (``process_noise``) is added to
        ``P``'s diagonal at each update, with ``rho_exponent = 1`` (no
        forgetting otherwise) and ``P``'s diagonal capped at ``p_max``.

        Notes
        -----
        Chosen by measurement (benchmarks/random_walk.py): on a drift of
        ``c1 + c2`` from 1.0 to 1.5 over 200 000 samples at SNR 40, a floor on
        ``rho`` (exponential forgetting) and a random walk track equally well
        (RMS error 0.006, lag ~500 samples, steady scatter 0.005 for a
        floor of 3e-3 or ``q = 1e-7``), but under one-sided excitation (a
        rising sawtooth: the down line visited once per period) forgetting
        let ``P``'s diagonal grow to 0.018 (1.1 for a floor of 1e-2) while
        the random walk kept it below 4e-4: forgetting grows an unexcited
        direction by ``1/lambda`` per update, the random walk by ``q``. ``q``
        sets the trade-off: larger follows faster and is noisier. It is in
        squared parameter units per update, so scale it with the units of the
        record (:class:`servoid.ident.monitoring.wear_estimator.WearEstimator` normalises the signals
        by ``c1 + c2`` so that one ``q`` fits every unit).
        """
        return cls(
            na=na, nb=nb, delay=delay, epsilon=epsilon, rho_exponent=1.0,
            process_noise=process_noise, p_max=p_max, **kwargs,  # type: ignore[arg-type]
        )  # fmt: skip

    @property
    def n_params(self) -> int:
        """Length of theta, ``na + nb + 4``."""
        return self.na + self.nb + 4

    @property
    def layout(self) -> _k.StateLayout:
        """Where each part of the estimator's state sits in its flat state vector."""
        return _k.StateLayout(self.na, self.nb, self.delay)

    @property
    def theta_layout(self) -> ThetaLayout:
        """Where each parameter sits in theta (eq. 15)."""
        return ThetaLayout(self.na, self.nb)

    def kernel_config(self) -> np.ndarray:
        """The configuration vector the compiled kernel reads."""
        cfg = np.zeros(_k.CFG_SIZE)
        cfg[_k.CFG_RHO_EXPONENT] = self.rho_exponent
        cfg[_k.CFG_EPSILON] = self.epsilon
        cfg[_k.CFG_COVERAGE_ALPHA] = 1.0 / self.coverage_window
        cfg[_k.CFG_PROJECT] = 1.0 if self.project else 0.0
        cfg[_k.CFG_STUCK_BELOW] = self.stuck_below if self.recover else 0.0
        cfg[_k.CFG_WARMUP] = self.warmup
        cfg[_k.CFG_RHO_FLOOR] = self.rho_floor
        cfg[_k.CFG_PROCESS_NOISE] = self.process_noise
        cfg[_k.CFG_P_MAX] = self.p_max
        return cfg

    def initial_state(self) -> np.ndarray:
        """The flat state vector at ``k = 0``: ``theta(0)``, ``P(0)``, ``Sigma(0)``, empty histories."""
        lay = self.layout
        state = np.zeros(lay.size)
        state[lay.theta] = self._theta0
        state[lay.P] = (self.p0 * np.eye(lay.n)).ravel()
        state[lay.scalars + _k.SC_SIGMA] = self.sigma0
        return state


def noise_epsilon(noise_std: float) -> float:
    """``E|v| = sqrt(2/pi) s`` for Gaussian noise of standard deviation ``s``: a default for ``epsilon``.

    Parameters
    ----------
    noise_std : float
        Standard deviation ``s`` of the output noise, unit of ``y``.
    """
    return float(np.sqrt(2.0 / np.pi) * validation.non_negative("noise_std", noise_std))


#: A margin above minus this is on the boundary, not below it: the paper's own plant has margin 0, and a
#: noise-free exact fit of it rounds to -5e-14 (which decided the "why" of identify's warning by its last bits).
MARGIN_ROUNDING = 1e-9


def convergence_margin(a: Sequence[float] | np.ndarray, *, points: int = 4096) -> float:
    """Margin of the MRGIA's convergence condition for a linear block with denominator ``a``.

    The MRGIA predicts ``x`` with its own estimate (an output-error,
    pseudo-linear regression), and such schemes converge when
    ``1/A(q) - 1/2`` is strictly positive real (Ljung 1977b, cited by the
    paper), i.e. when ``|A(e^jw) - 1| < 1`` at every frequency. Returns
    ``1 - max_w |sum_i a_i e^(-j w i)|``: positive means the condition holds.

    Notes
    -----
    The condition is sufficient, not necessary. Measured on the paper's
    example and on double-pole plants (benchmarks/paper_example.py): every
    plant with a margin >= 0 converged on every seed; double real poles at
    0.6 (margin -0.56) and beyond never did, which is what a position loop
    sampled much faster than its bandwidth looks like. The paper's own plant
    sits exactly on the boundary (margin 0). Where the margin is negative,
    trust the refined model (:func:`servoid.ident.identify` also refines
    from a start that does not depend on the MRGIA) or sample more slowly.

    Parameters
    ----------
    a : array_like
        Denominator coefficients ``a_1 .. a_na`` of eq. (1).
    points : int
        Frequencies on ``[0, pi]`` at which the maximum is taken.
    """
    arr = validation.signal("a", a)
    w = np.linspace(0.0, np.pi, points)
    z = np.exp(-1j * np.outer(w, np.arange(1, arr.size + 1)))
    return float(1.0 - np.max(np.abs(z @ arr)))


@dataclass(frozen=True)
class RecoveryEvent:
    """One recovery from a stuck zone classification.

    Attributes
    ----------
    sample : int
        Index of the sample after which the run was judged stuck.
    coverage_up, coverage_down : float
        Line coverages at that moment (see :func:`MRGIA.coverage`).
    theta_before : tuple of float
        The estimate that was abandoned.
    """

    sample: int
    coverage_up: float
    coverage_down: float
    theta_before: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """``{"sample", "coverage_up", "coverage_down"}`` (the abandoned theta stays in Python)."""
        return {"sample": self.sample, "coverage_up": self.coverage_up, "coverage_down": self.coverage_down}


class MRGIA:
    """The online MRGIA estimator, one sample at a time.

    Parameters
    ----------
    config : MRGIAConfig, optional
        Orders, delay and settings; default the paper's.

    Examples
    --------
    >>> est = MRGIA(MRGIAConfig(na=2, nb=0, delay=1))
    >>> for u_k, y_k in zip(u, y):        # doctest: +SKIP
    ...     est.update(u_k, y_k)
    >>> est.model                          # doctest: +SKIP
    """

    def __init__(self, config: MRGIAConfig | None = None) -> None:
        self.config = config if config is not None else MRGIAConfig()
        self._lay = self.config.layout
        self._cfg = self.config.kernel_config()
        self._na, self._nb, self._d = self.config.na, self.config.nb, self.config.delay
        self._recoveries: list[RecoveryEvent] = []
        # one buffer for the kernel (state, configuration, scratch, orders): an update is one call with
        # one array; state, _cfg and _work are views of it
        lay = self._lay
        self._buf = np.zeros(lay.buffer_size)
        self._buf[lay.orders] = (self._na, self._nb, self._d)
        self.state = self._buf[lay.state]
        self._cfg = self._buf[lay.cfg]
        self._work = self._buf[lay.work]
        self.state[:] = self.config.initial_state()
        self._cfg[:] = self.config.kernel_config()
        step = _fast_step if _fast_step is not None else _first_step
        self._step: Callable[[float, float], int] = partial(step, self._buf)

    # -- stepping -----------------------------------------------------------------
    def update(self, u: float, y: float) -> Step:
        """Process the sample ``(u(k), y(k))``.

        Returns
        -------
        Step
            What happened: primed, held (memory zone), updated or refused.

        Raises
        ------
        ConfigError
            If ``u`` or ``y`` is not finite (use :meth:`skip` for a lost sample).
        EstimatorDiverged
            If this sample would make ``theta`` or ``P`` non-finite; the state
            is left as it was before the sample.
        """
        try:
            code = self._step(u, y)  # the compiled entry converts numbers as float() does; the kernel checks finiteness
        except TypeError:
            code = self._step(float(u), float(y))  # float() names what is not a number
        step = _STEP_OF[code]
        if step is not None:
            return step
        if code == _k.STEP_DIVERGED:
            raise EstimatorDiverged(_diverged_message(self.samples), sample=self.samples)
        if code == _k.STEP_NOT_FINITE:
            raise ConfigError(
                f"sample {self.samples}: u (={u!r}) and y (={y!r}) must be finite; use skip(u) for a lost measurement"
            )
        self._recover(self.samples - 1)  # flagged STEP_STUCK
        return _STEPS[code - _k.STEP_STUCK]

    def skip(self, u: float) -> None:
        """Advance over a sample whose measurement was lost (late, missed, timed out).

        The internal model is propagated with the commanded ``u``; nothing is
        estimated and the next sample only re-primes ``y(k-1)``.
        """
        _k.mrgia_skip(self.state, self._na, self._nb, self._d, float(u))

    def reset(self) -> None:
        """Return to ``k = 0`` with the configured initial values and settings.

        The kernel's configuration vector is rebuilt too: reaching
        ``max_recoveries`` switches recovery off for the rest of a run, not for
        good.
        """
        self.state[:] = self.config.initial_state()
        self._cfg[:] = self.config.kernel_config()
        self._recoveries.clear()

    def warm_up(self) -> None:
        """Compile the kernels now, on a scratch estimator: a first compile inside a sampling loop stalls it for seconds."""
        scratch = MRGIA(self.config)
        for u, y in ((0.1, 0.0), (-0.1, 0.05), (0.2, -0.02)):
            scratch.update(u, y)
        scratch.skip(0.0)
        _ = scratch.coverage

    def current(self) -> dict[str, float]:
        """The current estimate by name, ``m2`` itself (for progress lines)."""
        lay = self.config.theta_layout
        return dict(zip(lay.names, (float(v) for v in lay.values(self.theta))))

    def result(self, theta_history: np.ndarray, coverage_history: np.ndarray, record_every: int) -> MRGIAResult:
        """This estimator's state as an :class:`MRGIAResult`, with histories a recorder kept.

        Parameters
        ----------
        theta_history : ndarray, shape (n_rows, n_params)
            Theta after samples ``record_every - 1``, ``2 record_every - 1``, ...
        coverage_history : ndarray, shape (n_rows, 2)
            Line coverage (up, down) at the same samples.
        record_every : int
            Sampling of the histories.
        """
        return _result(self, theta_history, coverage_history, record_every)

    def _recover(self, sample: int) -> None:
        up, down = self.coverage
        if len(self._recoveries) >= self.config.max_recoveries:
            self._cfg[_k.CFG_STUCK_BELOW] = 0.0  # leave it alone; `settled` reports it
            return
        self._recoveries.append(RecoveryEvent(sample, up, down, tuple(self.theta.tolist())))
        _k.mrgia_recover(
            self.state, self._na, self._nb, self._d, self.config._theta0, self.config.p0, self.config.sigma0
        )

    # -- state --------------------------------------------------------------------
    @property
    def theta(self) -> np.ndarray:
        """Current estimate ``[a_1..a_na, b_0..b_nb, m2 - 1, c1, c2]`` (eq. 24); a copy."""
        return np.array(self.state[self._lay.theta])

    @property
    def P(self) -> np.ndarray:
        """Covariance matrix ``P(k)`` (eq. 21); a copy."""
        n = self._lay.n
        return np.array(self.state[self._lay.P].reshape(n, n))

    @property
    def K(self) -> np.ndarray:
        """Gain vector ``K(k)`` of the last update (eq. 20); a copy."""
        return np.array(self.state[self._lay.K])

    @property
    def S(self) -> float:
        """``S(k)`` of the last update (eq. 19)."""
        return float(self.state[self._lay.scalars + _k.SC_S])

    @property
    def sigma(self) -> float:
        """``Sigma-hat(k)``, the running mean of the squared prediction error (eq. 22)."""
        return float(self.state[self._lay.scalars + _k.SC_SIGMA])

    @property
    def x_history(self) -> np.ndarray:
        """``x-hat(k-1) .. x-hat(k-na)``, newest first (eq. 27); a copy."""
        return np.array(self.state[self._lay.x_history])

    @property
    def u_history(self) -> np.ndarray:
        """``u(k-1) .. u(k-d-nb)``, newest first; a copy."""
        return np.array(self.state[self._lay.u_history])

    @property
    def samples(self) -> int:
        """Number of samples processed (updated, held, primed or skipped)."""
        return int(self.state[self._lay.scalars + _k.SC_T])

    @property
    def updates(self) -> int:
        """Number of samples with ``Phi(k) = 1`` whose update was applied."""
        return int(self.state[self._lay.scalars + _k.SC_UPDATES])

    @property
    def last_error(self) -> float:
        """Prediction error ``e-hat(k)`` of the last applied update (eq. 17)."""
        return float(self.state[self._lay.scalars + _k.SC_ERROR])

    @property
    def coverage(self) -> tuple[float, float]:
        """Line coverage ``(up, down)``: share of recent measured moves that the model put on each line.

        Both approach 1 as the zone classification settles; a side whose
        output rarely moved reports 1.
        """
        up, down = _k.line_coverage(self.state, self._na, self._nb, self._d)
        return float(up), float(down)

    @property
    def settled(self) -> bool:
        """True when both line coverages are at or above ``stuck_below``."""
        return min(self.coverage) >= self.config.stuck_below

    @property
    def recoveries(self) -> tuple[RecoveryEvent, ...]:
        """Recoveries from a stuck zone classification so far."""
        return tuple(self._recoveries)

    @property
    def model(self) -> BacklashModel:
        """The current estimate as a :class:`BacklashModel`.

        Raises
        ------
        ModelError
            If the estimate is not a valid model (for example ``c1 <= 0`` or an
            unstable linear block), with the offending value named.
        """
        return _theta_model(self.theta, self.config)


def _diverged_message(sample: int) -> str:
    return (
        f"the MRGIA diverged at sample {sample}: theta or P became non-finite (check the input's scaling, or lower p0)"
    )


def _theta_model(theta: np.ndarray, config: MRGIAConfig) -> BacklashModel:
    try:
        return BacklashModel.from_theta(theta, na=config.na, nb=config.nb, delay=config.delay)
    except ModelError as exc:
        raise ModelError(f"the MRGIA estimate is not a valid model: {exc}") from exc


@dataclass(frozen=True)
class MRGIAResult:
    """Outcome of :func:`run_mrgia` over a whole record.

    Attributes
    ----------
    config : MRGIAConfig
        The settings used.
    theta : ndarray, shape (n_params,)
        Final estimate (eq. 24).
    theta_history : ndarray, shape (n_rows, n_params)
        Estimate after samples ``record_every - 1``, ``2 record_every - 1``, ...
    coverage_history : ndarray, shape (n_rows, 2)
        Line coverage (up, down) at the same samples.
    record_every : int
        Sampling of the histories.
    samples, updates : int
        Samples processed and updates applied.
    recoveries : tuple of RecoveryEvent
        Recoveries from a stuck zone classification.
    coverage : tuple of float
        Final line coverage (up, down).
    settled : bool
        Whether both final coverages are at or above ``config.stuck_below``.
        An unsettled result is not trustworthy even if its numbers look sane.
    """

    config: MRGIAConfig
    theta: np.ndarray
    theta_history: np.ndarray
    coverage_history: np.ndarray
    record_every: int
    samples: int
    updates: int
    recoveries: tuple[RecoveryEvent, ...]
    coverage: tuple[float, float]
    settled: bool

    def __repr__(self) -> str:
        values = ", ".join(f"{n}={v:.4g}" for n, v in zip(self.names, self.values()))
        state = "settled" if self.settled else "NOT settled"
        return f"MRGIAResult({self.samples} samples, {state}, {len(self.recoveries)} recoveries; {values})"

    @property
    def history_samples(self) -> np.ndarray:
        """Sample index (0-based) of each row of :attr:`theta_history`."""
        return np.arange(1, self.theta_history.shape[0] + 1) * self.record_every - 1

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names matching the columns of :meth:`values_history`."""
        return BacklashModel.parameter_names(self.config.na, self.config.nb)

    def values(self) -> np.ndarray:
        """Final estimate in the order of :attr:`names`, with ``m2`` itself (not ``m2 - 1``)."""
        return self.config.theta_layout.values(self.theta)

    def values_history(self) -> np.ndarray:
        """:attr:`theta_history` with the ``m2 - 1`` column shifted to ``m2``."""
        return self.config.theta_layout.values(self.theta_history)

    @property
    def model(self) -> BacklashModel:
        """The final estimate as a validated :class:`BacklashModel` (raises :class:`ModelError` if invalid)."""
        return _theta_model(self.theta, self.config)

    def to_dict(self) -> dict[str, Any]:
        """The online estimate for JSON: ``model`` (null, with ``model_error``, when invalid), counts, settings.

        Keys: ``model``, ``values`` (by name, ``m2`` itself), ``samples``,
        ``updates``, ``settled``, ``line_coverage`` (``up``, ``down``),
        ``recoveries`` (the sample of each), ``rho_exponent``, ``epsilon``.
        """
        out: dict[str, Any] = {}
        try:
            out["model"] = self.model.to_dict()
        except ModelError as exc:
            out.update(model=None, model_error=str(exc))
        out.update(
            values=dict(zip(self.names, self.values().tolist())), samples=self.samples, updates=self.updates,
            settled=self.settled, line_coverage={"up": self.coverage[0], "down": self.coverage[1]},
            recoveries=[r.sample for r in self.recoveries], rho_exponent=self.config.rho_exponent,
            epsilon=self.config.epsilon,
        )  # fmt: skip
        return out


def run_mrgia(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    config: MRGIAConfig | None = None,
    *,
    valid: Sequence[bool] | np.ndarray | None = None,
    record_every: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> MRGIAResult:
    """Run the MRGIA over whole arrays (compiled inner loop).

    Parameters
    ----------
    u, y : array_like
        Input and measured output, same length, finite.
    config : MRGIAConfig, optional
        Orders and settings; default the paper's.
    valid : array_like of bool, optional
        ``False`` marks samples whose measurement was lost: they are skipped as
        by :meth:`MRGIA.skip` (their ``y`` is ignored and may be NaN).
    record_every : int
        Keep every ``record_every``-th estimate in the histories.
    progress : callable, optional
        Called as ``progress(done, total)`` every ``PROGRESS_CHUNK`` samples.

    Returns
    -------
    MRGIAResult

    Raises
    ------
    ConfigError
        For arrays of different length, non-finite values, or too few samples
        for the orders.
    EstimatorDiverged
        With the index of the sample at which ``theta`` or ``P`` became
        non-finite; ``exc.partial`` holds the :class:`MRGIAResult` up to there.

    Notes
    -----
    Gives the same numbers as feeding the samples one by one to
    :meth:`MRGIA.update` and :meth:`MRGIA.skip` (tested).
    """
    cfg = config if config is not None else MRGIAConfig()
    u_arr = validation.signal("u", u)
    every = validation.integer("record_every", record_every, minimum=1)
    if valid is None:
        valid_arr = np.ones(u_arr.size, dtype=np.bool_)
        y_arr = validation.signal("y", y)
    else:
        valid_arr = np.asarray(valid, dtype=np.bool_)
        if valid_arr.shape != u_arr.shape:
            raise ConfigError(f"valid has shape {valid_arr.shape}, u has {u_arr.shape}")
        y_raw = np.asarray(y, dtype=np.float64)
        if y_raw.shape != u_arr.shape:
            raise ConfigError(f"y has shape {y_raw.shape}, u has {u_arr.shape}")
        y_arr = np.where(valid_arr, y_raw, 0.0)
        validation.signal("y (valid samples)", y_arr)
    if y_arr.size != u_arr.size:
        raise ConfigError(f"u and y differ in length: {u_arr.size} against {y_arr.size}")
    minimum = cfg.n_params + cfg.delay + cfg.nb + 1
    if u_arr.size < minimum:
        raise ConfigError(
            f"{u_arr.size} samples are too few for na={cfg.na}, nb={cfg.nb}, delay={cfg.delay}: "
            f"at least {minimum} are needed"
        )

    est = MRGIA(cfg)
    n = u_arr.size
    rows = n // every
    theta_hist = np.full((rows, cfg.n_params), np.nan)
    cov_hist = np.full((rows, 2), np.nan)
    start = 0
    while start < n:
        stop = min(n, start + PROGRESS_CHUNK) if progress is not None else n
        status, k = _k.mrgia_run(
            est._buf, cfg.na, cfg.nb, cfg.delay,
            u_arr[start:stop], y_arr[start:stop], valid_arr[start:stop],
            theta_hist, cov_hist, every, start,
        )  # fmt: skip
        if status == 2:
            at = start + int(k)
            partial = _result(est, theta_hist[: at // every], cov_hist[: at // every], every)
            exc = EstimatorDiverged(_diverged_message(at), sample=at)
            exc.partial = partial  # type: ignore[attr-defined]
            raise exc
        if status == 1:
            est._recover(start + int(k))
            start += int(k) + 1
        else:
            start = stop
        if progress is not None:
            progress(start, n)
    return _result(est, theta_hist, cov_hist, every)


def _result(est: MRGIA, theta_hist: np.ndarray, cov_hist: np.ndarray, every: int) -> MRGIAResult:
    return MRGIAResult(
        config=est.config,
        theta=est.theta,
        theta_history=theta_hist,
        coverage_history=cov_hist,
        record_every=every,
        samples=est.samples,
        updates=est.updates,
        recoveries=est.recoveries,
        coverage=est.coverage,
        settled=est.settled,
    )
