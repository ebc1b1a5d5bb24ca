"""Watching a servo's backlash while it works: the loop of ``servoid monitor``.

:func:`run_monitor` runs an input through a driver with the sampling session
(:func:`servoid.session.run_session`, keeping no samples), feeds each
measured sample to a :class:`~servoid.ident.monitoring.wear_estimator.WearEstimator` (every
``config.factor``-th, anti-aliased, when the session samples faster than the
model's rate) and, every
``check_every`` samples, applies the alarm rule
(:class:`~servoid.ident.monitoring.alarms.Alarms`) to the dead zone ``c1 + c2``, the
down-line slope ``m2`` and the fit. It writes, in ``out``:

``estimates.csv``
    One row every ``row_every`` samples: the estimates with their standard
    deviations, the fit, how much of the recent data excited the estimator,
    the line coverage, the share of slots not on time and the active alarms
    (:func:`estimate_columns`). ``# key: value`` lines first say what ran.
``compensation.jsonl``
    One JSON object per line each time the compensation parameters moved by
    more than ``compensation_step`` (relative) since the last line, at as
    many checks in a row as an alarm needs: ``c1``,
    ``c2``, ``m2``, the smoothing band (docs/compensation.md), with their
    standard deviations. The first line is the model the monitor started from.
``model.json``
    The latest estimate as a model file (schema version 2, ``method``
    ``"mrgia-tracking"``), rewritten with each compensation line and at the
    end: what ``servoid export`` turns into a compensator.
``events.jsonl``
    Start and stop, alarms raised and cleared, recoveries of the estimator.

Memory stays constant however long it runs: the session keeps no samples,
the estimator is a fixed-size state, the files are appended to, and the
history kept for the plot (:class:`MonitorHistory`) halves its resolution
when full. The live plot is drawn in another process
(:class:`servoid.plots.monitor.LivePlot`), so that drawing it never delays
a sample.
"""

from __future__ import annotations

import csv
import logging
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO, Any

import numpy as np

from servoid.drivers.base import Driver
from servoid.errors import ConfigError, DataError, DriverError, EstimatorDiverged, ModelError
from servoid.files import read_text
from servoid.ident.control.compensate import default_band
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.monitoring.alarms import AlarmEvent, Alarms
from servoid.ident.monitoring.wear_estimator import WearEstimate, WearEstimator
from servoid.ident.online.decimate import DecimatingEstimator
from servoid.ident.serialise import dumps
from servoid.modelfile import ModelFile
from servoid.monitor_config import EXIT_ALARM, MonitorConfig
from servoid.monitor_history import HistorySnapshot, MonitorHistory
from servoid.recording import RecordingWriter, split_metadata
from servoid.session import Sample, SampleListener, SessionConfig, SessionProgress, SessionResult, run_session

__all__ = [
    "MonitorConfig",
    "MonitorProgress",
    "MonitorResult",
    "run_monitor",
    "estimate_columns",
    "read_estimates",
    "compensation_band",
    "METHOD",
    "EXIT_ALARM",
]

log = logging.getLogger("servoid.monitor_run")

#: ``method`` of the model files the monitor writes.
METHOD = "mrgia-tracking"


@dataclass(frozen=True)
class MonitorProgress:
    """What the progress callback receives.

    Attributes
    ----------
    done : int
        Slots so far.
    total : int or None
        Slots planned (None: until stopped).
    elapsed_s : float
        Session time since slot 0, seconds.
    late_share : float
        Share of slots not exchanged on time.
    estimate : WearEstimate or None
        The latest checked estimate.
    active : tuple of str
        Labels of the alarms active now.
    """

    done: int
    total: int | None
    elapsed_s: float
    late_share: float
    estimate: WearEstimate | None
    active: tuple[str, ...]


@dataclass(frozen=True)
class MonitorResult:
    """A finished (or stopped) monitoring run.

    Attributes
    ----------
    samples : int
        Slots run.
    counts : dict
        Slots per status (ok, late, missed, timeout).
    estimate : WearEstimate
        The final estimate.
    events : tuple of AlarmEvent
        Every alarm raised or cleared, in order.
    active : tuple of AlarmEvent
        Alarms still raised at the end.
    recoveries : int
        Recoveries of the estimator from a stuck zone classification.
    restarts : int
        Restarts of the estimator after a divergence.
    compensation_updates : int
        Compensation lines written after the first.
    stopped : str or None
        ``"alarm"`` (stopped at the first alarm), ``"interrupted"`` (Ctrl-C), or None.
    files : dict
        What was written, by name.
    history : HistorySnapshot
        The estimates over the run, for plots.
    session : SessionResult
        The session (counts only: it kept no samples).
    """

    samples: int
    counts: dict[str, int]
    estimate: WearEstimate
    events: tuple[AlarmEvent, ...]
    active: tuple[AlarmEvent, ...]
    recoveries: int
    restarts: int
    compensation_updates: int
    stopped: str | None
    files: dict[str, Path]
    history: HistorySnapshot
    session: SessionResult

    def to_dict(self) -> dict[str, Any]:
        """For JSON: slots, the final estimate (:meth:`WearEstimate.to_dict`), every alarm event
        (:meth:`AlarmEvent.to_dict`), those still active, counts, why it stopped, the files."""
        return {
            "samples": self.samples,
            "counts": self.counts,
            "stopped": self.stopped,
            "estimate": self.estimate.to_dict(),
            "alarms": [ev.to_dict() for ev in self.events],
            "active": [ev.bound.quantity for ev in self.active],
            "recoveries": self.recoveries,
            "restarts": self.restarts,
            "compensation_updates": self.compensation_updates,
            "files": {k: str(v) for k, v in self.files.items()},
        }

    @property
    def first_alarm(self) -> AlarmEvent | None:
        """The first alarm raised, if any."""
        return next((e for e in self.events if e.raised), None)


def estimate_columns(names: tuple[str, ...], *, truth: bool = False) -> tuple[str, ...]:
    """Columns of ``estimates.csv`` for parameters ``names`` (``a1.., b0.., m2, c1, c2``).

    ``k`` sample, ``t`` seconds from the start; each parameter and ``dead_zone``
    (``c1 + c2``) with its standard deviation ``<name>_std`` (output unit for
    ``c1``, ``c2``, ``dead_zone``); ``fit`` the free-run NRMSE of the recent
    window; ``excited`` the share of samples since the previous row that
    updated the estimate; ``coverage_up``/``coverage_down`` the line
    coverage; ``recoveries`` so far; ``late_share`` the share of slots since
    the previous row not exchanged on time; ``alarms`` the active ones
    (joined by ``+``); with a simulated servo, ``true_dead_zone`` and ``true_m2``.
    """
    cols = ["k", "t", "dead_zone", "dead_zone_std"]
    for name in names:
        cols += [name, f"{name}_std"]
    cols += ["fit", "excited", "coverage_up", "coverage_down", "recoveries", "late_share", "alarms"]
    if truth:
        cols += ["true_dead_zone", "true_m2"]
    return tuple(cols)


def read_estimates(path: str | os.PathLike[str]) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Read an ``estimates.csv``: ``(columns, metadata)``, numbers as float arrays, ``alarms`` as strings.

    Raises
    ------
    DataError
        A missing file, or one that is not an ``estimates.csv`` of ``servoid monitor``.
    """
    p = Path(path)
    meta, lines = split_metadata(read_text(p).splitlines())
    rows = list(csv.reader(lines))
    if not rows or "dead_zone" not in rows[0]:
        raise DataError(f"{p}: not an estimates.csv of servoid monitor (no dead_zone column)")
    header, body = rows[0], rows[1:]
    out: dict[str, np.ndarray] = {}
    for i, name in enumerate(header):
        cells = [r[i] for r in body]
        try:
            out[name] = np.array(cells, dtype=np.str_) if name == "alarms" else np.array(cells, dtype=np.float64)
        except ValueError as exc:
            raise DataError(f"{p}: column {name!r} holds a value that is not a number ({exc})") from None
    return out, meta


def compensation_band(model_file: ModelFile, model: BacklashModel) -> float:
    """The smoothing band for ``model``: the file's own if it was set by hand, else servoid's default for ``model``."""
    stored = model_file.band
    if stored is not None and not math.isclose(stored, default_band(model_file.model, noise_std=model_file.noise_std),
                                               rel_tol=1e-9, abs_tol=1e-15):  # fmt: skip
        return stored
    return default_band(model, noise_std=model_file.noise_std)


def run_monitor(
    driver: Driver,
    inputs: Iterable[float],
    session: SessionConfig,
    config: MonitorConfig,
    *,
    model_file: ModelFile,
    out: str | os.PathLike[str],
    total: int | None = None,
    truth_at: Callable[[int], BacklashModel] | None = None,
    on_event: Callable[[str, str], None] | None = None,
    on_progress: Callable[[MonitorProgress], None] | None = None,
    plot: str | os.PathLike[str] | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> MonitorResult:
    """Monitor an open driver until ``inputs`` end, an alarm stops it, or Ctrl-C.

    Parameters
    ----------
    driver : Driver
        An open driver (the session switches the torque on, and off at the end).
    inputs : iterable of float
        The command per slot (may be endless), driver's unit.
    session : SessionConfig
        Sample period and policies (``use_late`` also applies to the wear estimator).
    config : MonitorConfig
        WearEstimator, bounds, rule, cadences.
    model_file : ModelFile
        The servo's model file: units, compensation band, identity carried over.
    out : path
        Folder of the outputs (see the module docstring).
    total : int, optional
        Slots planned, for progress.
    truth_at : callable, optional
        ``truth_at(k)`` the true model at sample ``k`` (a simulated servo):
        adds ``true_dead_zone``, ``true_m2`` to the rows.
    on_event : callable, optional
        ``on_event(kind, line)`` for each alarm raised (``"alarm"``) or
        cleared (``"clear"``), recovery (``"recovery"``), restart
        (``"restart"``) and compensation written (``"compensation"``).
    on_progress : callable, optional
        Called with a :class:`MonitorProgress` at the session's progress interval.
    plot : path, optional
        PNG refreshed every ``config.plot_every_s`` by a separate process,
        and drawn once more at the end.
    metadata : mapping, optional
        Extra ``# key: value`` lines for ``estimates.csv``.

    Returns
    -------
    MonitorResult

    Raises
    ------
    DriverError
        When the servo fails (the torque is off, the files are complete up
        to there).
    ConfigError
        When the model and the driver disagree on the unit.
    """
    unit = driver.position_unit.unit
    if model_file.output_unit not in (unit, "unit"):
        raise ConfigError(
            f"the model is in {model_file.output_unit!r} and {driver.describe()} reports {unit!r}: "
            "monitor with a model identified in the servo's unit"
        )
    loop = _Loop(driver, session, config, model_file, Path(out), truth_at, on_event, plot, total)
    loop.estimator.warm_up()
    loop.start(metadata or {})
    return loop.result(drive(driver, loop, inputs, session, loop.progress(on_progress)))


def drive(
    driver: Driver,
    loop: Any,
    inputs: Iterable[float],
    session: SessionConfig,
    on_progress: Callable[[SessionProgress], None] | None,
    listeners: Sequence[SampleListener] = (),
) -> SessionResult:
    """Run the session with a monitor's ``loop`` as its listener until the inputs end, it stops on an alarm, or Ctrl-C.

    ``loop`` (this module's, or :mod:`servoid.monitor_loop`'s) has ``stop``,
    ``stopped_on_alarm``, ``on_sample``, ``finish(reason)`` and ``close()``: its
    files are finished whatever ends the run, and a driver's failure is raised
    after them.

    Parameters
    ----------
    driver : Driver
        An open driver.
    loop : object
        The monitor's state (the listener).
    inputs : iterable of float
        The command per slot.
    session : SessionConfig
        Sample period and policies.
    on_progress : callable, optional
        The session's progress callback.
    listeners : sequence of SampleListener
        Further listeners after ``loop`` (the cycled input's readings: :class:`servoid.monitor_loop.ReadingsGrid`).
    """
    try:
        result = run_session(driver, until_stopped(inputs, loop), session, listeners=[loop, *listeners],
                             keep_samples=False, on_progress=on_progress)  # fmt: skip
        loop.finish("alarm" if loop.stopped_on_alarm else (result.stopped or "end of input"))
    except DriverError as exc:
        loop.finish(f"{type(exc).__name__}: {exc}")
        raise
    finally:
        loop.close()
    return result


def until_stopped(inputs: Iterable[float], loop: Any) -> Iterator[float]:
    """The inputs, until ``loop.stop`` is set (an alarm with ``stop_on_alarm``)."""
    for value in inputs:
        if loop.stop:
            return
        yield value


class _Loop:
    """The state of one :func:`run_monitor` run."""

    def __init__(
        self,
        driver: Driver,
        session: SessionConfig,
        config: MonitorConfig,
        model_file: ModelFile,
        out: Path,
        truth_at: Callable[[int], BacklashModel] | None,
        on_event: Callable[[str, str], None] | None,
        plot: str | os.PathLike[str] | None,
        total: int | None,
    ) -> None:
        self.driver, self.session, self.config, self.model_file = driver, session, config, model_file
        self.out, self.truth_at, self.on_event, self.total = out, truth_at, on_event, total
        self.plot_path = None if plot is None else Path(plot)
        self.unit = driver.position_unit.unit
        self.estimator = WearEstimator(config.estimator)
        # the estimator runs at the model's rate, on the anti-aliased decimated stream (issue 15)
        self.feed: Any = self.estimator if config.factor == 1 else DecimatingEstimator(self.estimator, config.factor)
        self.alarms = Alarms(config.bounds, config.rule)
        self.history = MonitorHistory()
        self.names = self.estimator.estimate().names
        self.n = 0
        self.last: Sample | None = None
        self.stop = False
        self.stopped_on_alarm = False
        self.events: list[AlarmEvent] = []
        self.latest: WearEstimate | None = None
        self.restarts = 0
        self.recoveries_seen = 0
        self.compensation_updates = -1  # the first line is the starting model
        self.written: tuple[float, float] | None = None  # (c1 + c2, m2) of the last compensation line
        self.moved = 0  # consecutive checks with the estimate a step away from it
        self.t = 0.0
        self.row_mark = (0, 0, 0)  # (samples, updates, slots on time) at the previous row
        self.on_time = 0
        self.source = driver.describe()
        self.files: dict[str, Path] = {}
        self._csv: RecordingWriter | None = None
        self._jsonl: dict[str, IO[str]] = {}
        self._live: Any = None
        self._next_plot = 0.0

    # ---- files ------------------------------------------------------------------
    def start(self, metadata: Mapping[str, Any]) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        cfg = self.config
        ref = cfg.estimator.reference
        meta = {
            "servoid monitor": "estimates",
            "source": self.source,
            "unit": self.unit,
            "period_s": repr(self.session.period_s),
            "decimate": str(cfg.factor),
            "reference": dumps(ref.to_dict()),
            "bounds": "; ".join(f"{b.label} {b.describe()}" for b in cfg.bounds) or "none",
            "rule": f"persist={cfg.rule.persist} checks of {cfg.check_every} samples, z={cfg.rule.z:g}, "
            f"hysteresis={cfg.rule.hysteresis:g}",  # fmt: skip
            "process_noise": f"{cfg.estimator.process_noise:g} (c1 + c2)^2 per update",
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            **metadata,
        }
        path = self.out / "estimates.csv"
        self._csv = RecordingWriter(path, estimate_columns(self.names, truth=self.truth_at is not None), metadata=meta)
        self.files["estimates"] = path
        for name in ("compensation", "events"):
            path = self.out / f"{name}.jsonl"
            self._jsonl[name] = open(path, "w", encoding="utf-8")
            self.files[name] = path
        self.files["model"] = self.out / "model.json"
        self._event("start", 0, source=self.source, unit=self.unit, reference=ref.to_dict(),
                    bounds=[b.to_dict() for b in cfg.bounds],
                    rule={"persist": cfg.rule.persist, "z": cfg.rule.z, "hysteresis": cfg.rule.hysteresis,
                          "check_every": cfg.check_every})  # fmt: skip
        self._write_compensation(0, ref, None)
        if self.plot_path is not None:
            from servoid.plots.monitor import LivePlot

            self._live = LivePlot(self.plot_path)

    def close(self) -> None:
        if self._live is not None:
            self._live.close()
            self._live = None
        if self._csv is not None:
            self._csv.close()
        for fh in self._jsonl.values():
            fh.close()

    def _event(self, kind: str, k: int, **data: Any) -> None:
        fh = self._jsonl["events"]
        fh.write(dumps({"event": kind, "k": k, "t": round(self.t, 9), **data}) + "\n")
        fh.flush()

    def _announce(self, kind: str, line: str) -> None:
        log.info("%s", line)
        if self.on_event is not None:
            self.on_event(kind, line)

    # ---- the loop ---------------------------------------------------------------
    def on_sample(self, sample: Sample, usable: bool) -> None:
        """A session listener: the wear estimator takes the usable samples and skips the others."""
        if usable:
            self.on_time += 1
            try:
                self.feed.update(sample.u, sample.y)
            except EstimatorDiverged as exc:
                self._restart(sample, exc)
        else:
            self.feed.skip(sample.u)
        self.n += 1
        self.last = sample
        if self.n % self.config.check_every == 0:
            self.t = sample.t_scheduled
            self._check(sample.k)

    def _restart(self, sample: Sample, exc: EstimatorDiverged) -> None:
        self.restarts += 1
        self.estimator.restart()
        self.recoveries_seen = 0
        self._event("restart", sample.k, reason=str(exc))
        self._announce("restart", f"the estimator diverged at sample {sample.k}; restarted from the servo's model")

    def _check(self, k: int) -> None:
        est = self.estimator.estimate()
        self.latest = est
        readings = {"dead_zone": (est.dead_zone, est.dead_zone_std), "m2": (est.m2, est.m2_std), "fit": (est.fit, 0.0)}
        for event in self.alarms.check(k, readings):
            self.events.append(event)
            self.history.alarm(event)
            self._event("alarm" if event.raised else "clear", k, **event.to_dict())
            self._announce("alarm" if event.raised else "clear", event.message())
            if event.raised and self.config.stop_on_alarm:
                self.stop = self.stopped_on_alarm = True
        if est.recoveries > self.recoveries_seen:
            for rec in self.estimator.recoveries[self.recoveries_seen :]:
                self._event("recovery", rec.sample, coverage_up=rec.coverage_up, coverage_down=rec.coverage_down)
                self._announce("recovery", f"the estimator recovered from a stuck zone classification at sample "
                                           f"{rec.sample} (backlash restarted from the servo's model)")  # fmt: skip
            self.recoveries_seen = est.recoveries
        self._maybe_compensation(k, est)
        if self.n % self.config.row_every == 0:
            self._row(k, est)
        if self._live is not None and time.monotonic() >= self._next_plot:
            self._next_plot = time.monotonic() + self.config.plot_every_s
            self._live.submit(self._snapshot())

    def _maybe_compensation(self, k: int, est: WearEstimate) -> None:
        assert self.written is not None
        step = self.config.compensation_step
        dz, m2 = self.written
        if abs(est.dead_zone - dz) <= step * dz and abs(est.m2 - m2) <= step * m2:
            self.moved = 0
            return
        # as for an alarm, the change must hold for `persist` checks: a compensator
        # is not retuned on a glitch of the estimate
        self.moved += 1
        if self.moved < self.config.rule.persist:
            return
        try:
            model = self.estimator.model
        except ModelError:  # an estimate on the edge of validity (a dead zone at 0) is not a compensator
            return
        self.moved = 0
        self._write_compensation(k, model, est)
        self._announce("compensation", f"compensation at sample {k}: c1 {model.c1:.4g}, c2 {model.c2:.4g} "
                                       f"{self.unit}, m2 {model.m2:.4g}")  # fmt: skip

    def _write_compensation(self, k: int, model: BacklashModel, est: WearEstimate | None) -> None:
        band = compensation_band(self.model_file, model)
        entry: dict[str, Any] = {"k": k, "t": round(self.t, 9), "c1": model.c1, "c2": model.c2, "m2": model.m2,
                                 "dead_zone": model.c1 + model.c2, "band": band, "unit": self.unit}  # fmt: skip
        if est is not None:
            entry.update(c1_std=est.std_of("c1"), c2_std=est.std_of("c2"), m2_std=est.m2_std)
        else:
            entry["from"] = "model file"
        fh = self._jsonl["compensation"]
        fh.write(dumps(entry) + "\n")
        fh.flush()
        self.written = (model.c1 + model.c2, model.m2)
        self.compensation_updates += 1
        self._save_model(k, model, est)

    def _save_model(self, k: int, model: BacklashModel, est: WearEstimate | None) -> None:
        stderr = None if est is None else {n: float(s) for n, s in zip(est.names, est.std)}
        fit = None if est is None or math.isnan(est.fit) else est.fit
        content = replace(
            self.model_file, model=model, stderr=stderr, method=METHOD, fit_nrmse=fit, source=self.source,
            samples=self.n, identified_at="", band=compensation_band(self.model_file, model),
            sample_period_s=self.session.period_s * self.config.factor,
            servo=self.driver.identity or self.model_file.servo,
        )  # fmt: skip
        # written aside and renamed, so a reader never sees half a file
        path = self.files["model"]
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(content.to_json(), encoding="utf-8")
        os.replace(tmp, path)

    def _row(self, k: int, est: WearEstimate) -> None:
        samples, updates, on_time = self.row_mark
        span = max(self.n - samples, 1)
        excited = (est.updates - updates) / span
        late = 1.0 - (self.on_time - on_time) / span
        self.row_mark = (self.n, est.updates, self.on_time)
        values: list[Any] = [k, self.t, est.dead_zone, est.dead_zone_std]
        for v, s in zip(est.values, est.std):
            values += [float(v), float(s)]
        active = "+".join(e.bound.quantity for e in self.alarms.active.values())
        values += [est.fit, excited, est.coverage[0], est.coverage[1], est.recoveries, late, active]
        row = {"k": k, "t": self.t, "dead_zone": est.dead_zone, "dead_zone_std": est.dead_zone_std,
               "m2": est.m2, "m2_std": est.m2_std, "fit": est.fit}  # fmt: skip
        if self.truth_at is not None:
            truth = self.truth_at(k)
            values += [truth.c1 + truth.c2, truth.m2]
            row.update(true_dead_zone=truth.c1 + truth.c2, true_m2=truth.m2)
        assert self._csv is not None
        self._csv.append(*values)
        self.history.add(row)

    def _snapshot(self) -> HistorySnapshot:
        return self.history.snapshot(bounds=self.config.bounds, unit=self.unit, source=self.source,
                                     period_s=self.session.period_s)  # fmt: skip

    def progress(self, callback: Callable[[MonitorProgress], None] | None) -> Callable[[SessionProgress], None] | None:
        if callback is None:
            return None

        def report(p: SessionProgress) -> None:
            active = tuple(e.bound.label for e in self.alarms.active.values())
            callback(MonitorProgress(p.done, self.total, p.elapsed_s, p.late_share, self.latest, active))

        return report

    # ---- the end ----------------------------------------------------------------
    def finish(self, reason: str) -> None:
        """The last row, the final model and the stop event."""
        k = -1 if self.last is None else self.last.k
        if self.last is not None:
            self.t = self.last.t_scheduled
            if self.n % self.config.row_every:
                self._row(k, self.estimator.estimate())
        try:
            self._save_model(max(k, 0), self.estimator.model, self.estimator.estimate())
        except ModelError as exc:
            log.warning("the final estimate is not a valid model, model.json keeps the last one: %s", exc)
        self._event("stop", k, samples=self.n, reason=reason)
        if self.plot_path is not None:
            if self._live is not None:
                self._live.close()
                self._live = None
            from servoid.plots import save
            from servoid.plots.monitor import plot_monitor

            self.files["plot"] = save(plot_monitor(self._snapshot()), self.plot_path)

    def result(self, session: SessionResult) -> MonitorResult:
        est = self.estimator.estimate()
        return MonitorResult(
            samples=len(session), counts=session.counts, estimate=est, events=tuple(self.events),
            active=tuple(self.alarms.active.values()), recoveries=est.recoveries, restarts=self.restarts,
            compensation_updates=self.compensation_updates,
            stopped="alarm" if self.stopped_on_alarm else session.stopped, files=dict(self.files),
            history=self._snapshot(), session=session,
        )  # fmt: skip
