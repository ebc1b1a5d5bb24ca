"""Watching a servo whose play sits in its loop: ``servoid monitor`` on a servo-loop model file.

The wear estimator of :mod:`servoid.monitor_run` is the MRGIA: it tracks the
pseudo-Wiener model only. A model file whose answer is the servo-loop model
(``structure.form`` ``servo_loop``: the play inside the position loop, or the
loop model with the play at the output) is followed instead by
:class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker`: the file's loop
refitted once with its gains held (the play and the constant force on the first
10 s, ``hold_loop``; a horn held as identified), then the play alone on short
windows (1.6 s every 0.25 s), a CUSUM on it once their scatter is known (20 s
later). :func:`run_loop_monitor` runs the session with it and writes, in ``out``:

``estimates.csv``
    One row per estimate (the first: the whole loop's refit): ``k``, ``t``,
    the window's play (``dead_zone``: the CUSUM's input) and the CUSUM's
    ``sigma`` (``dead_zone_std``: the upper 95 % bound on the scatter of the
    baseline's window plays; empty before it is known), the tracking
    estimate (``dead_zone_mean``: the mean of the last 5 s of window plays), the
    window's play over the baseline's median (``dead_zone_rel``: the wear since
    monitoring began, what the CUSUM judges; empty before the baseline), the
    CUSUM's statistic in standard deviations (``cusum``; the alarm is raised
    above the threshold the ``baseline`` event gives), the loop gains ``kp``,
    ``kv`` (held after the first row), the window's free-run NRMSE and floor, its
    ``reversals`` (a window with fewer than
    :data:`~servoid.ident.monitoring.loop_wear.MIN_REVERSALS` does not count), the
    estimate's wall time, the active alarms (and ``true_play`` for a simulated twin).
``events.jsonl``
    Start and stop; ``baseline`` (the median play, its scatter and the bound on it, the correlation
    of the estimates, the threshold and the mean samples between false alarms
    it implies, the bounds where they went); alarms raised and cleared.
``model.json``
    The model file with the held loop and the tracking estimate's play,
    rewritten at each alarm and at the end.

With the cycled sine (:data:`~servoid.excitation.monitor_input.CYCLED`, ``--input cycled``; off by default)
``events.jsonl`` also holds an ``input`` event when the steady part starts: the count the first fit's readings
showed (:class:`ReadingsGrid`), or why there was none and the steady sine ran instead.

Memory is bounded: the session keeps no samples, the tracker two windows
(the first fit's 10 s) and its last 4096 rows.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from servoid.drivers.base import Driver
from servoid.excitation.monitor_input import CYCLED, STEADY, GridCount, coast_accel, grid_count
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.monitoring.alarms import AlarmEvent, Bound
from servoid.ident.monitoring.loop_wear import PLAY, LoopWearTracker, PlayRow
from servoid.ident.online.probe_design import GENTLE
from servoid.ident.serialise import dumps
from servoid.modelfile import ModelFile
from servoid.monitor_run import drive
from servoid.recording import RecordingWriter
from servoid.session import Sample, SessionConfig, SessionProgress, SessionResult

__all__ = [
    "refusal",
    "design_sines",
    "ReadingsGrid",
    "short_horn",
    "HORN_RECORD_S",
    "HOLD_LOOP",
    "CALIBRATE",
    "LoopMonitorResult",
    "run_loop_monitor",
    "LOOP_COLUMNS",
    "METHOD",
]

#: ``method`` of the model files this monitor writes.
METHOD = "window-tracking"

#: Columns of ``estimates.csv`` (the module's text); ``true_play`` is added for a simulated twin.
LOOP_COLUMNS = ("k", "t", "dead_zone", "dead_zone_std", "dead_zone_mean", "dead_zone_rel", "cusum", "kp", "kv", "fit",
                "floor", "reversals", "refit_s", "alarms")  # fmt: skip


#: The monitor's first fit holds the model file's loop gains and refits the play alone
#: (:class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker`'s ``hold_loop``; docs/monitor.md).
HOLD_LOOP = True

#: The window plays read relative to the model file's play
#: (:class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker`'s ``calibrate``): off. It takes the file's error,
#: and wear before or during its calibration, as its own (``benchmarks/monitor_loop.py --calibrate``; docs/monitor.md,
#: "the window plays read relative to the file").
CALIBRATE = False

#: Servo seconds of gentle sines identification's horn stage needs to size a play in the loop on a compliant
#: contact (``benchmarks/horn_live.py``: the STS3215 twin's play -23.4 % on 20 s, -1.6 % on 40 s; docs/online.md).
HORN_RECORD_S = 40.0


def short_horn(model_file: ModelFile) -> float | None:
    """The seconds of record a model file's horn play was sized on, where shorter than the horn stage needs; else None.

    A file whose play sits in the loop on a compliant contact (identification's horn stage kept) sized that
    play on ``samples`` readings: under :data:`HORN_RECORD_S` its play is chance (the STS3215 twin's 20 s data
    file -23.4 %, and the monitor's raw tracking 24.0 %; from 40 s -1.6 % and 4.6 %, docs/monitor.md). The
    monitor judges wear against its own baseline either way; its raw play is the file's.

    Parameters
    ----------
    model_file : ModelFile
        The servo's model file.

    Returns
    -------
    float or None
        The record's length, s; None for a play outside the loop, a massless load, or a record long enough
        (or of unknown length).
    """
    from servoid.ident.models.structure_names import PLAY_IN_LOOP
    from servoid.loop_compensation import has_loop, loop_model

    if model_file.structure != PLAY_IN_LOOP or not has_loop(model_file) or not loop_model(model_file).compliant:
        return None
    if not model_file.samples or not model_file.sample_period_s:
        return None
    seconds = model_file.samples * model_file.sample_period_s
    return seconds if seconds < HORN_RECORD_S - model_file.sample_period_s else None


def design_sines(model_file: ModelFile, period_s: float) -> tuple[float, float, float] | None:
    """The identification's largest amplitude and highest peak acceleration, and the steady sine's bound, from the model file's design.

    What the monitor's steady sine is built from
    (:func:`~servoid.excitation.monitor_input.monitor_stream`): the ``design`` section that ``servoid
    identify --driver`` writes (the probe's gentle sines: ``amplitude``, ``accel`` per sample squared at
    the live run's rate, ``estimator_rate_hz`` times ``factor``).

    Parameters
    ----------
    model_file : ModelFile
        The servo's model file.
    period_s : float
        The monitor's sample period, s.

    Returns
    -------
    (float, float, float) or None
        The amplitude (unit of ``u``), the acceleration and the steady sine's highest
        (:func:`~servoid.excitation.monitor_input.coast_accel`: the slow phase's for a play outside the
        loop, else ``inf``), both in unit of ``u`` per sample squared at ``period_s``; None when the file
        holds no gentle-sines design (``identify --data``, a design of held steps, ``--no-probe``).
    """
    design = model_file.extra.get("design")
    if not isinstance(design, dict) or design.get("shape") != GENTLE:
        return None
    try:
        amplitude, accel = float(design["amplitude"]), float(design["accel"])
        rate_hz = float(design["estimator_rate_hz"]) * int(design["factor"])
    except (KeyError, TypeError, ValueError):
        return None
    if not all(math.isfinite(v) and v > 0.0 for v in (amplitude, accel, rate_hz)):
        return None
    try:
        slow = float(design.get("slow_accel", 0.0))
    except (TypeError, ValueError):
        slow = 0.0
    scale = (rate_hz * period_s) ** 2
    return amplitude, accel * scale, coast_accel(model_file.structure, slow) * scale


class ReadingsGrid:
    """The cycled sine's count, from the readings the first fit used: a session listener, and the count's source.

    It keeps the usable readings from the session's start until it is called, when
    :func:`~servoid.excitation.monitor_input.monitor_stream` starts the steady part (after the first fit's
    identification sines), and takes the loop encoder's count from them
    (:func:`~servoid.excitation.monitor_input.grid_count`): no second experiment. It keeps at most the
    samples before the steady part (the first fit's 10 s and the rest of their segment), then none.

    Parameters
    ----------
    amplitude : float
        The steady sine's amplitude, unit of ``u``.
    steps : int
        Places of the cycle (reported with the count).
    """

    def __init__(self, amplitude: float, steps: int) -> None:
        self.amplitude, self.steps = float(amplitude), int(steps)
        self._readings: list[float] | None = []
        self.grid: GridCount | None = None

    def on_sample(self, sample: Sample, usable: bool) -> None:
        """Keep a usable reading until the count is taken."""
        if self._readings is not None and usable:
            self._readings.append(sample.y)

    def __call__(self) -> float:
        """The count (NaN when the readings show none: the steady sine runs), taken once."""
        if self.grid is None:
            import numpy as np

            self.grid = grid_count(np.array(self._readings or (), dtype=np.float64), self.amplitude)
            self._readings = None
        return self.grid.count

    def describe(self, unit: str) -> str:
        """One line: which steady sine runs and why (empty before the count is taken)."""
        grid = self.grid
        if grid is None:
            return ""
        if grid.found:
            return (f"servoid monitor: the steady sine cycles its amplitude over {self.steps} places a count / "
                    f"{self.steps} apart (the encoder's count {grid.count:.6g} {unit}, from the first fit's "
                    f"{grid.readings} readings)")  # fmt: skip
        return f"servoid monitor: the steady sine at one amplitude, not cycled: {grid.why}"

    def event(self) -> dict[str, Any]:
        """The ``input`` event's data."""
        assert self.grid is not None
        found = self.grid.found
        return {"input": CYCLED if found else STEADY, "steps": self.steps if found else 1, **self.grid.to_dict()}


@dataclass(frozen=True)
class LoopMonitorResult:
    """A finished (or stopped) monitoring run of a servo-loop model.

    Attributes
    ----------
    samples : int
        Slots run.
    counts : dict
        Slots per status (ok, late, missed, timeout).
    play, play_std : float
        The last tracking estimate (the mean of the last 5 s of window plays) and the scatter of
        the baseline's window plays (NaN before it is known).
    refits : int
        Estimates done (the first: the whole loop's refit).
    dropped : int
        Windows left out because the previous refit still ran.
    events : tuple of AlarmEvent
        Every alarm raised or cleared, in order.
    active : tuple of AlarmEvent
        Alarms still raised at the end.
    stopped : str or None
        ``"alarm"``, ``"refused"`` (the model file's play is off and the bounds are absolute: see
        :func:`run_loop_monitor`), ``"interrupted"`` or None.
    files : dict
        What was written, by name.
    session : SessionResult
        The session (counts only).
    doubt : str or None
        Why the model file's play is not the servo's (:attr:`LoopWearTracker.doubt`), or None.
    grid : GridCount or None
        The cycled sine's count as the first fit's readings showed it (:class:`ReadingsGrid`); None without the
        cycled sine, or before its steady part started.
    """

    samples: int
    counts: dict[str, int]
    play: float
    play_std: float
    refits: int
    dropped: int
    events: tuple[AlarmEvent, ...]
    active: tuple[AlarmEvent, ...]
    stopped: str | None
    files: dict[str, Path]
    session: SessionResult
    doubt: str | None = None
    grid: GridCount | None = None

    def to_dict(self) -> dict[str, Any]:
        """For JSON: slots, the play, refits, every alarm event, those still active, why it stopped, the files."""
        return {
            "samples": self.samples, "counts": self.counts, "stopped": self.stopped, "estimator": "window",
            "estimate": {"dead_zone": self.play, "dead_zone_std": self.play_std},
            "refits": self.refits, "dropped": self.dropped, "alarms": [ev.to_dict() for ev in self.events],
            "active": [ev.bound.quantity for ev in self.active], "files": {k: str(v) for k, v in self.files.items()},
            "doubt": self.doubt,
            "grid": None if self.grid is None else self.grid.to_dict(),
        }  # fmt: skip

    @property
    def first_alarm(self) -> AlarmEvent | None:
        """The first alarm raised, if any."""
        return next((e for e in self.events if e.raised), None)


def run_loop_monitor(
    driver: Driver,
    inputs: Iterable[float],
    session: SessionConfig,
    *,
    start: ServoLoopModel,
    model_file: ModelFile,
    bounds: Sequence[Bound],
    out: str | os.PathLike[str],
    stop_on_alarm: bool = False,
    wait: bool = False,
    rebase: bool = False,
    true_play: Callable[[int], float] | None = None,
    on_event: Callable[[str, str], None] | None = None,
    on_progress: Callable[[SessionProgress], None] | None = None,
    metadata: Mapping[str, Any] | None = None,
    steady_s: float = 0.0,
    grid: ReadingsGrid | None = None,
) -> LoopMonitorResult:
    """Monitor an open driver with the servo-loop tracker until ``inputs`` end, an alarm stops it, or Ctrl-C.

    Parameters
    ----------
    driver : Driver
        An open driver.
    inputs : iterable of float
        The command per slot (may be endless), driver's unit.
    session : SessionConfig
        Sample period and policies; ``start`` must be at its period.
    start : ServoLoopModel
        The model file's loop, where the tracker starts.
    model_file : ModelFile
        The servo's model file (rewritten with the latest loop into ``model.json``).
    bounds : sequence of Bound
        Bounds on the play (quantity ``dead_zone``); others are not checked here. The CUSUM of
        :class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker` watches them (its threshold
        from a false-alarm rate, not the MRGIA monitor's rule).
    out : path
        Folder of the outputs.
    stop_on_alarm : bool
        End the run at the first alarm raised.
    wait : bool
        A servo on a virtual clock: a window that falls due waits for the last refit.
    rebase : bool
        The bounds are relative to the model file's play: move them to the baseline's median play
        (:class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker`'s ``rebase``; a ``baseline``
        event says where they went).

        When the first refit shows the file's play is not the servo's
        (:attr:`~servoid.ident.monitoring.loop_wear.LoopWearTracker.doubt`), a ``doubt`` event
        (and ``on_event("doubt", line)``) says so and what follows: with relative bounds (or none)
        the run goes on **re-baselined** on the monitor's own refit -- wear is a change from the
        servo as it is, which the refit and the baseline's median measure, whatever the file's
        bias -- and the estimates' absolute play is the monitor's, not the file's; with absolute
        bounds it **refuses** (stops, ``stopped="refused"``): an absolute bound compared with a play
        the monitor has just shown it cannot place would raise, or miss, alarms with confidence.
    true_play : callable, optional
        ``true_play(k)`` the true play at sample ``k`` (a simulated twin): a column of the rows.
    on_event : callable, optional
        ``on_event(kind, line)`` for each alarm raised (``"alarm"``) or cleared (``"clear"``).
    on_progress : callable, optional
        The session's progress callback.
    metadata : mapping, optional
        Extra ``# key: value`` lines for ``estimates.csv``.
    steady_s : float
        Servo seconds from the start at which ``inputs`` settle on the monitoring input (the steady
        sine after the identification's sines): windows that begin before it do not count
        (:class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker`'s ``steady_s``).
    grid : ReadingsGrid, optional
        The cycled sine's count source (the one ``inputs`` calls): it takes the session's readings, and an ``input``
        event (and ``on_event("input", line)``) says what it found once it has been called.

    Returns
    -------
    LoopMonitorResult

    Raises
    ------
    servoid.errors.DriverError
        When the servo fails (the torque is off, the files are complete up to there).
    """
    loop = _LoopRun(
        driver, session, start, model_file, [b for b in bounds if b.quantity == PLAY], Path(out),
        stop_on_alarm, wait, true_play, on_event, rebase, steady_s, grid,
    )  # fmt: skip
    loop.tracker.warm_up()
    loop.start(metadata or {})
    return loop.result(drive(driver, loop, inputs, session, on_progress, () if grid is None else (grid,)))


def refusal(why: str) -> str:
    """The one line of a run that refused the model file (``stopped == "refused"``), after ``why`` (its doubt).

    Parameters
    ----------
    why : str
        :attr:`LoopMonitorResult.doubt`.
    """
    return (f"refused to monitor: {why}; an absolute bound on the play needs a model file that places it "
            "(identify the servo again, or give the bound in %, which follows the monitor's own baseline)")  # fmt: skip


class _LoopRun:
    """The state of one :func:`run_loop_monitor` run."""

    def __init__(
        self,
        driver: Driver,
        session: SessionConfig,
        start: ServoLoopModel,
        model_file: ModelFile,
        bounds: list[Bound],
        out: Path,
        stop_on_alarm: bool,
        wait: bool,
        true_play: Callable[[int], float] | None,
        on_event: Callable[[str, str], None] | None,
        rebase: bool,
        steady_s: float,
        grid: ReadingsGrid | None = None,
    ) -> None:
        self.driver, self.session, self.model_file, self.out = driver, session, model_file, out
        self.grid, self.grid_said = grid, False
        self.bounds, self.stop_on_alarm = bounds, stop_on_alarm
        self.true_play, self.on_event = true_play, on_event
        interval = tuple(math.nan if v is None else float(v) for v in model_file.play_interval)
        self.tracker = LoopWearTracker(start, bounds, wait=wait, rebase=rebase, interval=(interval[0], interval[1]),
                                       identifiable=model_file.identifiable, steady_s=steady_s,
                                       hold_loop=HOLD_LOOP, calibrate=CALIBRATE)  # fmt: skip
        self.rebase = rebase
        self.based = self.doubted = self.refused = False
        self.rows_seen = self.events_seen = 0
        self.stop = self.stopped_on_alarm = False
        self.last: Sample | None = None
        self.n = 0
        self.mean = math.nan  # the last tracking estimate
        self.files: dict[str, Path] = {}
        self._csv: RecordingWriter | None = None
        self._events: IO[str] | None = None

    def start(self, metadata: Mapping[str, Any]) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        cfg = self.tracker.window.config
        meta = {
            "servoid monitor": "estimates (servo-loop model, window refit)",
            "source": self.driver.describe(), "unit": self.driver.position_unit.unit,
            "period_s": repr(self.session.period_s), "window_s": repr(cfg.window_s), "every_s": repr(cfg.every_s),
            "baseline_s": repr(self.tracker.baseline_s),
            "bounds": "; ".join(f"{b.label} {b.describe()}" for b in self.bounds) or "none",
            "first_s": repr(cfg.first_s), "burn_in_s": repr(cfg.burn_in_s),
            "rule": f"CUSUM at the bounds, threshold for {self.tracker.false_alarm_samples:g} samples between false alarms",
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), **metadata,
        }  # fmt: skip
        columns = LOOP_COLUMNS + (("true_play",) if self.true_play is not None else ())
        self.files["estimates"] = self.out / "estimates.csv"
        self._csv = RecordingWriter(self.files["estimates"], columns, metadata=meta)
        self.files["events"] = self.out / "events.jsonl"
        self._events = open(self.files["events"], "w", encoding="utf-8")
        self.files["model"] = self.out / "model.json"
        self._event("start", 0, source=self.driver.describe(), estimator="window", window=cfg.to_dict(),
                    bounds=[b.to_dict() for b in self.bounds])  # fmt: skip

    def close(self) -> None:
        self.tracker.window.close()
        if self._csv is not None:
            self._csv.close()
        if self._events is not None:
            self._events.close()

    def _event(self, kind: str, k: int, **data: Any) -> None:
        assert self._events is not None
        t = k * self.session.period_s
        self._events.write(dumps({"event": kind, "k": k, "t": round(t, 9), **data}) + "\n")
        self._events.flush()

    def on_sample(self, sample: Sample, usable: bool) -> None:
        """A session listener: the tracker takes the usable samples and skips the others; new refits are written."""
        if usable:
            self.tracker.update(sample.u, sample.y)
        else:
            self.tracker.skip(sample.u)
        self.n += 1
        self.last = sample
        self._drain()

    def _drain(self) -> None:
        new = self.tracker.rows_since(self.rows_seen)
        for row in new:
            self._row(row)
            self.mean = row.mean
        self.rows_seen += len(new)
        if not self.grid_said and self.grid is not None and self.grid.grid is not None:
            self.grid_said = True
            self._event("input", self.last.k if self.last else 0, **self.grid.event())
            if self.on_event is not None:
                self.on_event("input", self.grid.describe(self.driver.position_unit.unit))
        if not self.doubted and self.tracker.doubt is not None:
            self._doubt(self.tracker.doubt)
        if not self.based and not math.isnan(self.tracker.std):
            self.based = True
            self._event("baseline", self.last.k if self.last else 0,
                        **{f"play_{k}" if k in ("median", "scatter", "std") else k: v
                           for k, v in self.tracker.baseline().items()},
                        bounds=[b.to_dict() for b in self.tracker.bounds])  # fmt: skip
        for event in self.tracker.events[self.events_seen :]:
            self._event("alarm" if event.raised else "clear", event.sample, **event.to_dict())
            if self.on_event is not None:
                self.on_event("alarm" if event.raised else "clear", event.message())
            if event.raised:
                self._save_model()
                if self.stop_on_alarm:
                    self.stop = self.stopped_on_alarm = True
        self.events_seen = len(self.tracker.events)

    def _doubt(self, why: str) -> None:
        """Say that the file's play is off and what the run does about it (:func:`run_loop_monitor`'s ``rebase``)."""
        self.doubted = True
        refuse = bool(self.bounds) and not self.rebase
        action = "refuse" if refuse else "rebaseline"
        first = self.tracker.rows_since(0)[0].window if self.rows_seen else None
        self._event("doubt", self.last.k if self.last else 0, reason=why, action=action,
                    file_play=self.tracker.start_play, refit_play=None if first is None else first.play)  # fmt: skip
        if refuse:  # the caller says why in one line (:func:`refusal`)
            self.stop = self.refused = True
        elif self.on_event is not None:
            self.on_event("doubt", f"servoid monitor: {why}: re-baselined on the monitor's own refit; the play it "
                                   "reports is its own, and wear is judged as a change from it")  # fmt: skip

    def _row(self, tracked: PlayRow) -> None:
        row = tracked.window
        k = int(round(row.t_s / self.session.period_s))
        model = self.tracker.window.model
        active = "+".join(e.bound.quantity for e in self.tracker.active.values())
        median = self.tracker.median  # NaN before the baseline: an empty cell
        rel = row.play / median if median > 0.0 else math.nan
        values: list[Any] = [k, row.t_s, row.play, self.tracker.std, tracked.mean, rel, tracked.statistic,
                             model.kp if model else math.nan, model.kv if model else math.nan, row.nrmse, row.floor,
                             row.reversals, row.seconds, active]  # fmt: skip
        if self.true_play is not None:
            values.append(self.true_play(k))
        assert self._csv is not None
        self._csv.append(*values)

    def _save_model(self) -> None:
        model = self.tracker.window.model
        if model is None or not self.mean > 0.0 or not model.play > 0.0:
            return
        scale = self.mean / model.play  # the held loop with the tracking estimate's play
        model = dataclasses.replace(model, c1=model.c1 * scale, c2=model.c2 * scale)
        content = dataclasses.replace(
            self.model_file, loop=model.params(), play=model.play, play_interval=(None, None),
            method=METHOD, source=self.driver.describe(), samples=self.n, identified_at="",
        )  # fmt: skip
        path = self.files["model"]
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(content.to_json(), encoding="utf-8")
        os.replace(tmp, path)

    def finish(self, reason: str) -> None:
        """Collect the last refit, write the final model and the stop event."""
        self.tracker.result()
        self._drain()
        self._save_model()
        k = -1 if self.last is None else self.last.k
        self._event("stop", k, samples=self.n, reason=reason)

    def result(self, session: SessionResult) -> LoopMonitorResult:
        w = self.tracker.window
        return LoopMonitorResult(
            samples=len(session), counts=session.counts, play=self.mean,
            play_std=self.tracker.std, refits=self.rows_seen, dropped=w.dropped, events=tuple(self.tracker.events),
            active=tuple(self.tracker.active.values()),
            stopped="refused" if self.refused else "alarm" if self.stopped_on_alarm else session.stopped,
            files=dict(self.files), session=session, doubt=self.tracker.doubt,
            grid=None if self.grid is None else self.grid.grid,
        )  # fmt: skip
