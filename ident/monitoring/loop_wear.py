"""Following the wear of a play inside the loop: the play alone refitted on short windows, a CUSUM on it.

The wear estimator (:mod:`~servoid.ident.monitoring.wear_estimator`) is the
MRGIA in random-walk mode: it tracks the pseudo-Wiener model only. For a
model whose play sits in the loop (``play_in_loop``), or wherever the
servo-loop model is the structure, :class:`LoopWearTracker` follows the play
with :class:`~servoid.ident.online.window.WindowRefit`:

1. **Baseline.** The first :data:`FIRST_FIT_S` of servo time refit the whole
   model file's loop (every parameter free, from the file's values): the
   servo as it is when monitoring begins. Every later estimate holds this
   refit's loop, so the monitor follows its own baseline, not the file's.
   The play is refitted with the rest unless holding it at the file's fits
   the window better (:func:`first_refit`: on 10 s of gentle sines the play
   trades against the break-away friction along a flat valley, and the free
   search stopped at a chance point of it, the XM430 twin's -11 % where its
   file said +17 %: every window play inherits that level). With
   ``hold_loop`` (what ``servoid monitor`` runs) the loop's gains
   (:data:`LOOP_GAINS`) stay the file's and only the play and the constant
   force are refitted: wear changes the play, not the loop, and the gains
   the 10 s refit moves along that valley (1 % of ``kp`` is 7 % of play on
   the XM430 twin) set the window plays' level. A file's horn (its inertia
   and contact) is never refitted here: the window refits hold it as
   identified. On the twins' data files the raw tracking of a growing play
   over tracking seeds 1 / 2 / 4 / 5 went from 8.0-15.7 to 9.0-9.3 % (XM430),
   0.4-11.4 to 7.2-7.3 % (STS3215), 0.7-4.1 to 0.4-0.7 % (CiA 402) and
   0.5-4.9 to 0.6-1.2 % (ODrive): the level no longer moves with the seed; it
   is the file's loop's on the monitoring input (``benchmarks/monitor_loop.py``,
   docs/monitor.md).
   When that refit puts the play outside the file's 95 % interval, or the
   file says its play is not identifiable, :attr:`LoopWearTracker.doubt`
   says so: the file's play is not the servo's, and only changes from the
   monitor's own baseline mean anything (the benchmark's model files were
   +113 % and -90 % off; the play-only estimates holding a loop fitted with
   them tracked the raw play to 58-84 % and its growth to 14-16 %).
2. **Play only.** Wear changes the play, not the loop: every
   :data:`PLAY_EVERY_S` the last :data:`PLAY_WINDOW_S` (its first
   :data:`PLAY_BURN_IN_S` simulated, not scored) are refitted with every
   parameter but the play held at the baseline's
   (:func:`~servoid.ident.monitoring.play_fit.fit_play`, a search over a grid of
   plays): one unknown, a few milliseconds, on a window short enough to see a
   step within a second. Each is a row (:class:`PlayRow`);
   the tracking estimate is the mean of the last :data:`TRACK_S` of them
   (the window plays scatter; the mean lags a growth by ``TRACK_S / 2``).
   A window counts (baseline, CUSUM, tracking) only when its scored readings
   reverse at least :data:`MIN_REVERSALS` times by more than twice the held
   play (:attr:`~servoid.ident.online.window.WindowRow.reversals`): each
   reversal is the motor crossing the play, all a window knows of it. On the
   XM430 twin held at the wrong place, every false alarm of 10^6 quiet
   samples (5) came from stretches of slow segments of the gentle sines whose
   windows hold one reversal or none, reading +10 ... +24 % for 6-12 s; with
   the rule, none (``benchmarks/monitor_loop.py``, docs/monitor.md). Nor
   does a window that begins before ``steady_s``, where the monitor's input
   changes from the identification's sines to its steady sine: its held-loop
   bias is the other input's. Counted, the windows across the switch entered
   the baseline (on the XM430 twin at 4 rad/s^2: 1.14 -> 0.92x the play
   within 2 s, the baseline's scatter 5.4 % against 1.2 % after them, tau 5.7
   against 1.0, the threshold 21 against 3.1, the alarm 7.25 s after a +20 %
   step against 1.25 s).
3. **Scatter.** The play-only estimates of the next ``baseline_s`` give the
   median play, their scatter and the correlation time ``tau`` of the
   overlapping windows. The CUSUM's ``sigma`` is the upper
   :data:`SIGMA_CONFIDENCE` bound of that scatter given ``n / tau`` independent
   estimates (chi-squared): a threshold set with a scatter that came out
   small by chance gave 3 false alarms in 10^6 samples on the STS3215 twin
   where it promised one in 10^8; with ``rebase`` the bounds on the play are moved by the
   median over the model file's play (``servoid monitor``'s ``--dead-zone P%``:
   the structure's bias on a physical servo is the same in every window, and
   an alarm on wear must not see it).
   Heavy tails: every window play is clipped to :data:`CLIP` robust scales
   (1.4826 MAD of the baseline's plays) beyond the bounds before the CUSUM, and
   ``sigma``, ``tau`` and the drift (the clipped plays' mean's distance to the
   nearer bound, not the median's) are measured on the clipped baseline: one
   wild window adds at most ``CLIP`` robust scales to a sum, and the threshold is
   never below that (a threshold set for a small scatter was 0: one window past
   a bound raised the alarm), while a play past a bound still counts in full.
4. **Alarm.** From then on each (clipped) estimate feeds a CUSUM with its reference at
   the bound (:class:`~servoid.ident.monitoring.cusum.Cusum`), its threshold
   from one false alarm per :data:`FALSE_ALARM_SAMPLES` samples on average
   (:func:`~servoid.ident.monitoring.cusum.threshold` with ``sigma`` and ``tau``).
   A check linear in the residuals was measured against it
   (``benchmarks/monitor_loop.py``, docs/monitor.md): the Gauss-Newton step of the
   play on the newest 0.25 s of each window; its means over 2 s scatter as much as
   the window plays' (7.6 / 4.8 / 7.9 % against 7.5 / 3.6 / 8.2 % on the ODrive,
   STS3215, XM430 twins), it under-reads large steps (a linearisation), and it
   was dropped.

With ``calibrate`` (off in ``servoid monitor``) the window plays are read relative to the model file's:
the first :data:`CALIBRATE_S` of counted ones (not counted otherwise) give their median, and every later
one is multiplied by the file's play over it. The held loop reads a horn servo's play low on the steady
sine (0.83-0.90x the play it reads on the identification's sines on the XM430 twin's massless file,
0.92-0.94x on the STS3215's horn file; the twins' velocity filter is no part of it: their PID firmware
does not use it; the cause is the firmware's loop on whole counts of the horn's encoder, where a steady sine
reverses at one place of the grid: :mod:`~servoid.excitation.monitor_input`), and the calibration removes that exactly, but the level is then the file's, and wear
before or during the calibration is read as the file's play (docs/monitor.md, "The window plays read
relative to the file").

Memory is bounded: the window keeps at most two windows of samples (the first
fit's ``FIRST_FIT_S``) and :data:`~servoid.ident.online.window.HISTORY_ROWS`
refits; the tracker keeps its last :data:`ROWS_KEPT` rows and the
``baseline_s`` of plays. Measured in ``benchmarks/monitor_loop.py``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.monitoring.alarms import AlarmEvent, Bound
from servoid.ident.monitoring.cusum import Cusum, correlation_time, false_alarm_checks, threshold
from servoid.ident.monitoring.play_fit import fit_play
from servoid.ident.online.window import MAX_NFEV, WindowConfig, WindowRefit, WindowResult, WindowRow

__all__ = [
    "LoopWearTracker",
    "PlayRow",
    "PLAY",
    "BASELINE_S",
    "FIRST_FIT_S",
    "PLAY_WINDOW_S",
    "PLAY_BURN_IN_S",
    "PLAY_EVERY_S",
    "TRACK_S",
    "FALSE_ALARM_SAMPLES",
    "SIGMA_CONFIDENCE",
    "CLIP",
    "MIN_REVERSALS",
    "ROWS_KEPT",
    "play_config",
    "file_doubt",
    "first_refit",
    "LOOP_GAINS",
    "CALIBRATE_S",
]

#: The quantity name of the play in the alarm rule's readings and bounds.
PLAY = "dead_zone"
#: Servo seconds of the first fit: the whole loop refitted from the model file's (the baseline).
FIRST_FIT_S = 10.0
#: Servo seconds of play-only estimates after it that give the median, scatter and correlation.
BASELINE_S = 20.0
#: Each play-only estimate's window, its burn-in and the period of the estimates, servo s: the
#: window holds 3-6 reversals of gentle sines (2.5-5 a second on the twins), the burn-in lets the
#: loop's state (started at rest) reach the servo's, and the short window sees a step within 1 s.
PLAY_WINDOW_S = 1.6
PLAY_BURN_IN_S = 0.4
PLAY_EVERY_S = 0.25
#: Servo seconds of window plays averaged into the tracking estimate.
TRACK_S = 5.0
#: Mean samples between false alarms the CUSUM's threshold is set for (100x the issue's 10^6).
FALSE_ALARM_SAMPLES = 1e8
#: The confidence of the upper bound on the baseline's scatter that the CUSUM uses.
SIGMA_CONFIDENCE = 0.95
#: Window plays are clipped to this many robust scales (1.4826 MAD of the baseline's) beyond the bounds.
CLIP = 3.0
#: Fewest reversals of a window's scored readings (by more than twice the held play: the motor
#: crossing it, :attr:`~servoid.ident.online.window.WindowRow.reversals`) for its play to count.
MIN_REVERSALS = 2
#: The loop's parameters a first fit with ``hold_loop`` holds at the model file's (:func:`first_refit`).
LOOP_GAINS = ("kp", "kv", "fc", "fs", "vs", "veps")
#: Servo seconds of counted window plays a tracker with ``calibrate`` reads the model file's play on
#: (:class:`LoopWearTracker`; 10 estimates, 3-10 independent on the twins' steady sine).
CALIBRATE_S = 2.5
#: Rows the tracker keeps (the last ones; a caller copies new ones with :meth:`LoopWearTracker.rows_since`).
ROWS_KEPT = 4096


def play_config(sample_period_s: float) -> WindowConfig:
    """The window settings of the play-only estimate at a stream's period (the module's constants).

    Parameters
    ----------
    sample_period_s : float
        The stream's period, s.
    """
    return WindowConfig(sample_period_s, window_s=PLAY_WINDOW_S, every_s=PLAY_EVERY_S, first_s=FIRST_FIT_S,
                        burn_in_s=PLAY_BURN_IN_S)  # fmt: skip


def first_refit(
    u: np.ndarray,
    y: np.ndarray,
    score: np.ndarray,
    start: ServoLoopModel,
    *,
    max_nfev: int = MAX_NFEV,
    hold_loop: bool = False,
) -> tuple[ServoLoopModel, float]:
    """The monitor's first fit of the whole loop from the model file's: the play free, unless holding it fits better.

    The first :data:`FIRST_FIT_S` of gentle sines do not size a play that trades against the
    break-away friction: along that valley the fit is flat (on the XM430 twin's files the free
    refit's play ranged -42 ... +12 % of the truth on five seeds, its free-run NRMSE within
    0-3 % of the refit with the play held at the file's), and the local search stops where
    the valley's roughness stops it, sometimes higher than the file's play would have fitted
    (seeds 1 / 5 / 6 of the XM430's 20 s data file: NRMSE 0.01128 / 0.01172 / 0.01457 free,
    0.01108 / 0.01146 / 0.01450 held). Every window play holds this loop and inherits its
    play's level. So both are fitted (:func:`~servoid.ident.offline.loop_fit.refit_loop` with
    every parameter free, and with the play held at the start's) and the play-held refit is kept
    only where it fits the window strictly better: the free search then ended above a point of
    its own space, and the file's play, sized on a longer record, stands. Where the play moves
    the fit down (a play worn since the file), the free refit is kept, as before.

    Parameters
    ----------
    u, y, score : ndarray
        The first window (set points, readings, scored samples), as :func:`refit_loop` takes them.
    start : ServoLoopModel
        The model file's loop.
    max_nfev : int
        scipy's ``max_nfev`` of each refit (the window's :attr:`WindowConfig.max_nfev`).
    hold_loop : bool
        Hold the loop's :data:`LOOP_GAINS` at the start's (the model file's) and refit the play and the
        constant force alone (one refit): wear changes the play, not the loop, and 10 s of sines
        do not place the gains that trade against the play (the module's text).

    Returns
    -------
    tuple
        The kept model and its free-run NRMSE on the scored samples.
    """
    from servoid.ident.offline.loop_fit import refit_loop

    if hold_loop:
        fit = refit_loop(u, y, start, score=score, max_nfev=max_nfev, hold=LOOP_GAINS)
        return fit.model, fit.fit_nrmse

    free = refit_loop(u, y, start, score=score, max_nfev=max_nfev)
    held = refit_loop(u, y, start, score=score, max_nfev=max_nfev, hold=("play",))
    kept = held if held.fit_nrmse < free.fit_nrmse else free
    return kept.model, kept.fit_nrmse


def file_doubt(
    file_play: float, refit_play: float, interval: tuple[float, float] | None, identifiable: bool | None
) -> str | None:
    """Why a model file's play is not the servo's, from the monitor's first refit of the whole loop; None when no reason.

    Parameters
    ----------
    file_play : float
        The model file's play.
    refit_play : float
        The play of the first refit (from the file's loop, on the monitor's own first window).
    interval : tuple of float, optional
        The file's 95 % interval of the play (``None`` or a NaN end: none).
    identifiable : bool, optional
        Whether the file calls its play identifiable.
    """
    why = []
    if identifiable is False:
        why.append("the model file says its play is not identifiable")
    if interval is not None and all(v is not None and math.isfinite(v) for v in interval):
        low, high = float(interval[0]), float(interval[1])
        if not low <= refit_play <= high:
            why.append(f"the first {FIRST_FIT_S:g} s refit moved the play from {file_play:.4g} to {refit_play:.4g} "
                       f"({refit_play / file_play - 1.0:+.0%}), outside the file's 95 % interval "
                       f"[{low:.4g}, {high:.4g}]")  # fmt: skip
    return "; ".join(why) or None


@dataclass(frozen=True)
class PlayRow:
    """One estimate of :class:`LoopWearTracker`.

    Attributes
    ----------
    window : WindowRow
        The refit (the first: the whole loop; then the play alone).
    mean : float
        The tracking estimate: the mean window play over the last :data:`TRACK_S`.
    statistic : float
        The CUSUM after this estimate, in standard deviations (NaN before the baseline is known).
    counted : bool
        Whether the window's play counted (baseline, CUSUM, tracking estimate): it held at least
        the tracker's ``min_reversals`` and began after its ``steady_s``.
    """

    window: WindowRow
    mean: float
    statistic: float
    counted: bool = True


class LoopWearTracker:
    """An :class:`~servoid.ident.online.estimator.Estimator` that follows the play of a servo-loop model and raises alarms.

    Parameters
    ----------
    start : ServoLoopModel
        The model the monitor starts from (a model file's loop).
    bounds : sequence of Bound
        The alarm bounds; the play's quantity is :data:`PLAY` (others are ignored).
    config : WindowConfig, optional
        Windows and periods (default :func:`play_config` at the start's period); its ``first_s``
        is the baseline fit of the whole loop.
    baseline_s : float
        Servo seconds of estimates after the first fit that give the median, scatter and correlation.
    background, wait : bool
        As :class:`~servoid.ident.online.window.WindowRefit`.
    rebase : bool
        Scale the bounds on the play, once the baseline is known, by the median estimate over
        the start's play (see the module docstring). The scaled bounds are :attr:`bounds`.
    false_alarm_samples : float
        Mean samples between false alarms the CUSUM's threshold is set for.
    interval : tuple of float, optional
        The model file's 95 % interval of the play (``None`` or NaN where it has none).
    identifiable : bool, optional
        Whether the model file calls its play identifiable (``None``: it does not say).
    fresh : bool
        The first fit searches both places of the play from scratch
        (:func:`~servoid.ident.offline.loop_fit.fit_loop` on the first ``first_s``) instead of
        refitting the start's loop; the start then gives only the bounds' reference play
        (measured in ``benchmarks/monitor_loop.py --fresh``; not what ``servoid monitor`` does).
    min_reversals : int
        Fewest reversals a window's readings must hold for its play to count (:data:`MIN_REVERSALS`).
    steady_s : float
        Servo seconds from the stream's start at which the monitoring input settles (``servoid
        monitor``'s steady sine after the identification's sines); a window that begins before it
        does not count (its held-loop bias is another input's; see the module docstring).

    hold_loop : bool
        The first fit holds the start's loop gains (:func:`first_refit`'s ``hold_loop``): the play
        and the constant force alone are refitted (``servoid monitor``'s choice; False: the whole
        loop, as before).
    calibrate : bool
        Read the window plays relative to the model file's: the first :data:`CALIBRATE_S` of
        counted window plays (after ``steady_s``; they do not count otherwise) give their median ``m``,
        and every later window play is multiplied by ``start.play / m`` (:attr:`scale`), so the
        monitor reports the file's play times the change of its own reading since then. It removes
        the held loop's bias on the monitoring input (the horn servos' window plays read 0.83-0.94x
        the play the loop was identified with), assumes the play is the file's while it calibrates,
        and takes the file's error as its own (docs/monitor.md, "The window plays read relative to
        the file"). False (default): the window plays as fitted, as before.
    """

    def __init__(
        self,
        start: ServoLoopModel,
        bounds: Sequence[Bound],
        config: WindowConfig | None = None,
        *,
        baseline_s: float = BASELINE_S,
        background: bool = True,
        wait: bool = False,
        rebase: bool = False,
        false_alarm_samples: float = FALSE_ALARM_SAMPLES,
        interval: tuple[float, float] | None = None,
        identifiable: bool | None = None,
        fresh: bool = False,
        min_reversals: int = MIN_REVERSALS,
        steady_s: float = 0.0,
        hold_loop: bool = False,
        calibrate: bool = False,
    ) -> None:
        config = config or play_config(start.sample_period_s)
        first = functools.partial(first_refit, max_nfev=config.max_nfev, hold_loop=hold_loop)
        self.window = WindowRefit(config, start=None if fresh else start, background=background, wait=wait,
                                  later=fit_play, first=first)  # fmt: skip
        cfg = self.window.config
        self.bounds = tuple(b for b in bounds if b.quantity == PLAY)
        self._rebase = bool(rebase)
        self._start_play = start.play
        self.baseline_s = validation.positive("baseline_s", baseline_s)
        self.false_alarm_samples = validation.positive("false_alarm_samples", false_alarm_samples)
        self.min_reversals = validation.integer("min_reversals", min_reversals, minimum=0)
        self.steady_s = validation.non_negative("steady_s", steady_s)
        self.events: list[AlarmEvent] = []
        self.alarms = Cusum(self.bounds, math.inf)  # replaced when the baseline is known
        self._seen = 0
        self._first: WindowRow | None = None
        self._baseline: list[float] = []
        self._recent: deque[float] = deque(maxlen=max(1, round(TRACK_S / cfg.every_s)))
        self._rows: list[PlayRow] = []
        self._gone = 0
        self._std = self._scatter = self._median = self._tau = self._h = self._robust = self._drift = math.nan
        self._interval = interval
        self._identifiable = identifiable
        self.doubt: str | None = None
        """Why the model file's play is not to be trusted, once the first refit shows it (else None)."""
        self._calibrate = bool(calibrate)
        self._calibration: list[float] = []  # the counted window plays read while calibrating
        self._calibrated_from = math.nan  # the first one's time, s
        self._scale = math.nan  # the model file's play over their median, once known

    def update(self, u: float, y: float) -> None:
        """Take a measured sample."""
        self.window.update(u, y)
        self._check()

    def skip(self, u: float) -> None:
        """Take a sample whose measurement is not to be used."""
        self.window.skip(u)
        self._check()

    def _check(self) -> None:
        new = self.window.rows_since(self._seen)  # per sample: only the refits not seen yet are copied
        self._seen += len(new)
        for row in new:
            self._take(row)

    def _take(self, row: WindowRow) -> None:
        stat = math.nan
        counted = True
        if self._first is None:  # the baseline fit of the whole loop
            self._first = row
            mean = row.play
            self.doubt = file_doubt(self._start_play, row.play, self._interval, self._identifiable)
        elif 0 <= row.reversals < self.min_reversals or row.t_s - self.window.config.window_s < self.steady_s - 1e-9:
            # too few crossings of the play, or the window began on the input before the steady one: it does not count
            counted = False
            mean = self._rows[-1].mean if self._rows else row.play
            stat = self.alarms.statistic(PLAY) if self.bounds and not math.isnan(self._std) else math.nan
        elif self._calibrate and self._calibrating(row):
            counted = False  # read on the file's play, not counted
            mean = self._rows[-1].mean if self._rows else row.play
        else:
            if self._calibrate:
                row = dataclasses.replace(row, play=row.play * self._scale)
            self._recent.append(row.play)
            mean = float(np.mean(self._recent))
            if math.isnan(self._std):
                self._baseline.append(row.play)
                # (a calibration's windows do not count: the baseline waits as long for as many)
                span = self.baseline_s + (CALIBRATE_S if self._calibrate else 0.0)
                if row.t_s - self._first.t_s >= span - 1e-9 and len(self._baseline) >= 4:
                    self._set_baseline()
            else:
                k = int(round(row.t_s / self.window.config.sample_period_s))
                self.events += self.alarms.check(k, {PLAY: (self._clip(row.play), self._std)})
                stat = self.alarms.statistic(PLAY) if self.bounds else math.nan
        self._rows.append(PlayRow(row, mean, stat, counted))
        if len(self._rows) > 2 * ROWS_KEPT:
            del self._rows[:-ROWS_KEPT]
            self._gone += ROWS_KEPT

    def _calibrating(self, row: WindowRow) -> bool:
        """Whether a counted window play is one of the calibration's (:data:`CALIBRATE_S`); sets :attr:`scale` at its end."""
        if not math.isnan(self._scale):
            return False
        if math.isnan(self._calibrated_from):
            self._calibrated_from = row.t_s
        if row.t_s - self._calibrated_from < CALIBRATE_S - 1e-9 or not self._calibration:
            self._calibration.append(row.play)
            return True
        self._scale = self._start_play / float(np.median(self._calibration))
        self._calibration = []
        return False

    @property
    def scale(self) -> float:
        """What the window plays are multiplied by (``calibrate``: the model file's play over the calibration's median;
        NaN before it is known; 1 without ``calibrate``)."""
        return self._scale if self._calibrate else 1.0

    def _set_baseline(self) -> None:
        plays = np.asarray(self._baseline)
        from scipy.stats import chi2

        self._median = float(np.median(plays))
        self._robust = max(1.4826 * float(np.median(np.abs(plays - self._median))), 1e-9 * abs(self._median), 1e-300)
        self._baseline = []
        if self._rebase and self._start_play > 0.0:
            scale = self._median / self._start_play
            self.bounds = tuple(dataclasses.replace(b, low=b.low * scale, high=b.high * scale) for b in self.bounds)
        plays = np.array([self._clip(p) for p in plays])
        self._scatter = max(float(np.std(plays, ddof=1)), 1e-9 * abs(self._median), 1e-300)
        mean = float(np.mean(plays))
        self._drift = min((d for b in self.bounds for d in (mean - b.low, b.high - mean) if math.isfinite(d)),
                          default=math.nan)  # fmt: skip
        cfg = self.window.config
        self._tau = correlation_time(plays, math.ceil((cfg.window_s - cfg.burn_in_s) / cfg.every_s))
        dof = max(plays.size / self._tau - 1.0, 1.0)
        self._std = self._scatter * math.sqrt(dof / float(chi2.ppf(1.0 - SIGMA_CONFIDENCE, dof)))
        # and never below one clipped estimate's largest increment: no single window raises the alarm alone
        single = 1.000001 * CLIP * self._robust / self._std  # (a hair above: the clipped increment equals it)
        self._h = (max(threshold(self.kappa, self.false_alarm_checks, self._tau), single)
                   if self.bounds else math.nan)  # fmt: skip
        self.alarms = Cusum(self.bounds, self._h if self.bounds else 0.0)

    def _clip(self, play: float) -> float:
        """A window play clipped to :data:`CLIP` robust scales beyond the bounds (or the baseline's median, if further out)."""
        if not math.isfinite(self._robust):
            return play
        low = max((b.low for b in self.bounds), default=-math.inf)
        high = min((b.high for b in self.bounds), default=math.inf)
        lo, hi = min(self._median, low) - CLIP * self._robust, max(self._median, high) + CLIP * self._robust
        return float(np.clip(play, lo, hi))

    @property
    def kappa(self) -> float:
        """The nearest bound's distance inside from the baseline's mean clipped play, in ``sigma`` (NaN before).

        A mean already on or beyond a bound takes 0.25: the CUSUM then adds up at every check
        and raises soon whatever the threshold. No floor otherwise: a floor set the odrive
        twin's threshold (its window plays scatter by 58 %) for a bound 2x as far as it was,
        and it raised a false alarm in 10^6 samples.
        """
        if math.isnan(self._drift) or math.isnan(self._std):
            return math.nan
        return self._drift / self._std if self._drift > 0.0 else 0.25

    @property
    def false_alarm_checks(self) -> float:
        """Mean estimates between false alarms the threshold is set for."""
        return self.false_alarm_samples / self.window.config.samples(self.window.config.every_s)

    @property
    def interval(self) -> tuple[float, float]:
        """The model file's 95 % interval of the play the first refit is judged by (NaN: none)."""
        low, high = self._interval if self._interval is not None else (math.nan, math.nan)
        return (math.nan if low is None else float(low), math.nan if high is None else float(high))

    @property
    def start_play(self) -> float:
        """The play of the model the tracker started from (the model file's)."""
        return self._start_play

    @property
    def median(self) -> float:
        """The baseline's median window play (NaN before it is known): the monitor's own start, against which
        ``servoid monitor``'s ``dead_zone_rel`` reads the wear since monitoring began."""
        return self._median

    @property
    def std(self) -> float:
        """The CUSUM's ``sigma``: the upper bound on the scatter of the baseline's play estimates (NaN before)."""
        return self._std

    def baseline(self) -> Mapping[str, float]:
        """The baseline's ``median`` play, the ``scatter`` of its estimates and the upper bound ``std`` the CUSUM uses, their correlation ``tau``, ``kappa``, the threshold ``h`` and the ``false_alarm_samples`` it implies (NaN before)."""
        implied = (
            false_alarm_checks(self.kappa, self._h, self._tau) * self.window.config.samples(self.window.config.every_s)
            if math.isfinite(self._h) and math.isfinite(self.kappa)
            else math.nan
        )
        return {"median": self._median, "scatter": self._scatter, "std": self._std, "tau": self._tau,
                "kappa": self.kappa, "h": self._h, "false_alarm_samples": implied}  # fmt: skip

    @property
    def active(self) -> dict[str, AlarmEvent]:
        """The alarms raised and not cleared, by quantity."""
        return self.alarms.active

    def rows_since(self, start: int) -> tuple[PlayRow, ...]:
        """The estimates after the first ``start`` (the last :data:`ROWS_KEPT` at most).

        Parameters
        ----------
        start : int
            How many rows the caller has seen.
        """
        self._check()
        return tuple(self._rows[max(0, start - self._gone) :])

    def warm_up(self) -> None:
        """Compile the servo-loop simulation now."""
        self.window.warm_up()

    def current(self) -> Mapping[str, float]:
        """The last estimate's play, the tracking estimate, the loop gains and the play's scatter."""
        now = dict(self.window.current())
        if not now:
            return now
        return {**now, "play_mean": self._rows[-1].mean if self._rows else math.nan, "play_std": self._std}

    def result(self) -> WindowResult:
        """Wait for a running refit, check it, and stop the worker (no extra final window)."""
        out = self.window.result(final=False)
        self._check()
        return out
