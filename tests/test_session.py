"""The sampling session, on the simulated servo in virtual time (exact and repeatable)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid.drivers.base import Limits
from servoid.drivers.clock import VirtualClock
from servoid.drivers.sim import SimDriver
from servoid.errors import ConfigError, DriverError
from servoid.ident import MRGIA, MRGIAConfig, run_mrgia
from servoid.recording import read_recording
from servoid.session import COLUMNS, SessionConfig, run_session, usable

T = 0.001  # s


def servo(**options) -> SimDriver:
    return SimDriver(servo="model", clock=VirtualClock(), seed=3, **options)


def excitation(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-0.2, 0.2, n)


def test_a_slow_servo_makes_late_and_missed_slots_never_a_burst():
    # every reply takes 1.2 periods: the session falls behind, flags, and skips
    with servo(latency=1.2 * T) as s:
        result = run_session(s, excitation(300), SessionConfig(period_s=T))
    status, t_actual = result.status, result.t_actual
    sent = np.isfinite(t_actual)
    assert result.counts["missed"] > 50 and result.counts["late"] > 50
    assert np.all(np.diff(t_actual[sent]) >= 1.2 * T - 1e-12)  # one exchange at a time, never bunched up
    assert np.all(t_actual[sent] - result.t[sent] < T / 2)  # a slot half a period gone is skipped, not sent
    assert set(status[~sent]) == {"missed"} and np.all(np.isnan(result.y[~sent]))
    # a missed slot held the previous command: that is what the servo had
    k = int(np.flatnonzero(status == "missed")[0])
    assert result.u[k] == result.u[k - 1]


def test_on_time_samples_are_ok_and_late_ones_are_flagged():
    with servo(latency=0.3 * T) as s:
        result = run_session(s, excitation(200), SessionConfig(period_s=T))
    assert result.counts == {"ok": 200, "late": 0, "missed": 0, "timeout": 0}
    with servo(latency=0.3 * T, jitter=0.4 * T) as s:
        result = run_session(s, excitation(500), SessionConfig(period_s=T))
    lateness = result.t_actual - result.t
    # late: started more than T/10 after the slot, or answered after the next slot began
    off_time = (lateness > T / 10) | (result.t_actual + result.exchange_s - result.t > T)
    late = result.status == "late"
    assert late.any() and np.all(off_time[late])
    assert not np.any(off_time[result.status == "ok"])
    assert np.any(late & (lateness <= T / 10))  # the jitter made some replies come after the next slot began


@pytest.mark.parametrize("use_late", [False, True])
def test_the_online_estimate_is_the_batch_estimate_over_the_used_samples(use_late):
    est = MRGIA(MRGIAConfig(na=2, nb=0, delay=1))
    with servo(jitter=0.25 * T, drop=0.01, timeout=3 * T) as s:
        result = run_session(s, excitation(3000), SessionConfig(period_s=T, use_late=use_late), estimator=est)
    counts = result.counts
    assert counts["late"] > 0 and counts["timeout"] > 0 and counts["missed"] > 0
    valid = result.valid
    # the simulated servo carries the slot: the guard window follows the timeouts only
    assert np.array_equal(valid, usable(result.status, use_late=use_late, guard=10, after=("timeout",)))
    after_timeout = np.zeros(valid.size, dtype=bool)
    for k in np.flatnonzero(result.status == "timeout"):
        after_timeout[k + 1 : k + 11] = True
    assert valid[(result.status == "late") & ~after_timeout].all() == use_late
    batch = run_mrgia(result.u, np.where(valid, result.y, np.nan), MRGIAConfig(na=2, nb=0, delay=1), valid=valid)
    np.testing.assert_array_equal(est.theta, batch.theta)
    assert est.model.max_relative_error(s.truth) < 0.05


def test_the_recording_is_written_as_samples_arrive_and_reads_back(tmp_path):
    path = tmp_path / "live.csv"
    seen_rows = []

    def watch(progress):
        seen_rows.append((progress.done, len(path.read_text().splitlines())))

    with servo(drop=0.02, timeout=2 * T) as s:
        result = run_session(s, excitation(400), SessionConfig(period_s=T, progress_every_s=0.05),
                             recording=path, on_progress=watch, estimator=MRGIA(MRGIAConfig()))  # fmt: skip
    header = [line for line in path.read_text().splitlines() if not line.startswith("#")][0]
    assert tuple(header.split(",")) == COLUMNS
    # at each progress call the file already held every sample so far
    assert all(lines >= done for done, lines in seen_rows[:-1]) and len(seen_rows) > 3
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.u, result.u)
    np.testing.assert_array_equal(rec.status, result.status)
    np.testing.assert_array_equal(np.isnan(rec.y), np.isnan(result.y))
    assert rec.metadata["unit"] == "rad" and rec.metadata["period_s"] == "0.001"


def test_a_samples_line_is_the_text_the_writer_writes_for_its_row(tmp_path):
    from servoid.recording import RecordingWriter
    from servoid.session import Sample

    samples = [Sample(7, 0.007, 0.0071234567891, 0.1, 0.30000000000000004, math.nan, "late", 1e-5, 2.5e16, True),
               Sample(8, np.float64(1 / 3), -0.0, -np.float64(2.0) ** -40, 1e300, 5e-324, "ok")]  # fmt: skip
    with RecordingWriter(tmp_path / "a.csv", COLUMNS) as w:
        for sample in samples:
            w.append(*sample.row())
    rows = (tmp_path / "a.csv").read_text().splitlines(keepends=True)[1:]
    assert rows == [sample.line() for sample in samples]


def test_ctrl_c_stops_keeps_the_file_and_switches_the_torque_off(tmp_path):
    path = tmp_path / "live.csv"
    calls = iter(range(10**6))

    def interrupt_at_100(reference: float) -> float:
        if next(calls) == 100:
            raise KeyboardInterrupt
        return reference

    with servo() as s:
        result = run_session(s, excitation(1000), SessionConfig(period_s=T), recording=path,
                             command_filter=interrupt_at_100)  # fmt: skip
        assert not s.torque_enabled and not s.device.plant.enabled
    assert result.stopped == "interrupted" and len(result) == 100
    assert len(read_recording(path)) == 100


def test_the_command_filter_sets_what_is_sent():
    with servo() as s:
        result = run_session(s, excitation(50), SessionConfig(period_s=T), command_filter=lambda r: 0.5 * r)
    rows = result.samples
    assert all(row.u == pytest.approx(0.5 * row.reference) for row in rows)


def test_progress_reports_counts_and_the_current_estimate():
    reports = []
    gen = (v for v in excitation(2000))  # an iterator without a length
    with servo() as s:
        run_session(s, gen, SessionConfig(period_s=T, progress_every_s=0.1), estimator=MRGIA(MRGIAConfig()),
                    on_progress=reports.append)  # fmt: skip
    last = reports[-1]
    assert last.done == 2000 and last.total is None and last.late_share == 0.0
    assert set(last.estimate) == {"a1", "a2", "b0", "m2", "c1", "c2"}
    assert last.estimate["c1"] == pytest.approx(0.02, rel=1e-3)


def test_bad_input_is_named():
    with pytest.raises(ConfigError, match="late_tolerance_s .* half the period"):
        SessionConfig(period_s=T, late_tolerance_s=T)
    with pytest.raises(ConfigError, match="period_s"):
        SessionConfig(period_s=0.0)
    with pytest.raises(DriverError, match="not open"):
        run_session(servo(), [0.0], SessionConfig(period_s=T))
    with servo() as s:
        with pytest.raises(ConfigError, match=r"excitation\[3\] \(=nan\) is not finite"):
            run_session(s, [0.0, 0.1, 0.2, math.nan], SessionConfig(period_s=T))
        assert not s.torque_enabled
        with pytest.raises(ConfigError, match=r"excitation\[2\] \(=inf\) is not finite"):
            run_session(s, np.array([0.0, 0.1, math.inf]), SessionConfig(period_s=T))  # an array: checked before
        assert not s.torque_enabled


def test_a_streaming_session_hands_out_every_sample_and_keeps_none():
    seen = []
    est = MRGIA(MRGIAConfig(na=2, nb=0, delay=1))
    with servo(jitter=0.25 * T, drop=0.01, timeout=3 * T) as s:
        result = run_session(s, excitation(2000), SessionConfig(period_s=T), estimator=est,
                             on_sample=seen.append, keep_samples=False)  # fmt: skip
    with servo(jitter=0.25 * T, drop=0.01, timeout=3 * T) as s:
        kept = run_session(s, excitation(2000), SessionConfig(period_s=T))
    assert result.samples == () and len(result) == 2000 and result.counts == kept.counts
    assert result.counts["timeout"] > 0 and result.late_share == pytest.approx(kept.late_share)
    assert [x.k for x in seen] == list(range(2000)) and tuple(seen) == kept.samples
    assert est.samples == 2000  # the estimator saw each sample before the callback did
    # the rule applied to the streamed statuses gives the session's own mask
    statuses = [x.status for x in seen]
    assert (
        usable(statuses, guard=kept.config.guard_samples, after=kept.config.guard_after).tolist() == kept.valid.tolist()
    )


def test_usable_rule_leaves_a_guard_window_after_each_unusable_sample():
    from servoid.session import UsableRule, usable

    status = ["ok", "late", "ok", "ok", "ok", "missed", "ok", "timeout", "ok", "ok", "ok", "ok"]
    assert usable(status, guard=0).tolist() == [s == "ok" for s in status]
    assert usable(status, guard=2).tolist() == [1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 1]
    # late samples the user accepts are not unusable, so they start no guard
    assert usable(status, use_late=True, guard=2).tolist() == [1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 1, 1]
    rule = UsableRule(guard=1)
    assert [rule(s) for s in ("missed", "ok", "ok")] == [False, False, True]


def test_an_ok_sample_skipped_while_the_rule_is_settled_gets_the_verdict_the_rule_gives():
    from servoid.session.samples import OK, STATUSES, UsableRule

    # the sampling loop asks the rule only when it is not settled or the status is not ok
    status = np.random.default_rng(3).choice(STATUSES, 400, p=[0.85, 0.05, 0.05, 0.05]).tolist()
    for kwargs in ({"guard": 3}, {"guard": 0}, {"guard": 2, "use_late": True, "after": ("timeout",)}):
        asked, skipping = UsableRule(**kwargs), UsableRule(**kwargs)
        verdicts = []
        for s in status:
            verdicts.append(True if s == OK and skipping.settled else skipping(s))
        assert verdicts == [asked(s) for s in status], kwargs
        assert 0 < sum(verdicts) < len(status)


def test_the_guard_follows_timeouts_everywhere_and_late_slots_where_the_protocol_carries_no_slot():
    from servoid.drivers.can.odrive import OdriveDriver
    from servoid.drivers.dynamixel import DynamixelDriver
    from servoid.drivers.serial import SerialDriver
    from servoid.drivers.sim import SimDriver
    from servoid.session import DEFAULT_GUARD_SAMPLES, SessionConfig

    cfg = SessionConfig(period_s=0.002)
    by_class = {cls: cls.carries_slots for cls in (SimDriver, SerialDriver, OdriveDriver, DynamixelDriver)}
    assert by_class == {SimDriver: True, SerialDriver: True, OdriveDriver: False, DynamixelDriver: False}
    with SimDriver(servo="model") as sim:
        slots = cfg.resolved(sim)
    own_clock = cfg.resolved(OdriveDriver(interface="virtual", channel="unused", node=3))
    # whether a servo applied a command without an intact acknowledgement is unknown on every transport
    assert slots.guard_samples == own_clock.guard_samples == DEFAULT_GUARD_SAMPLES == 10
    assert slots.guard_after == ("timeout",) and own_clock.guard_after == ("late", "missed", "timeout")
    status = ["ok", "late", "ok", "missed", "ok", "timeout", "ok", "ok", "ok"]
    assert slots.usable_rule().mask(status).tolist() == [1, 0, 1, 0, 1, 0, 0, 0, 0]
    assert SessionConfig(period_s=0.002, guard_samples=3).resolved(sim).guard_samples == 3


def test_with_replies_dropped_every_step_the_servo_received_stays_within_max_step():
    # A lost reply leaves the servo on the new command: the next step must be measured from it as
    # well as from the one before (before the fix, steps of 2 max_step reached the servo).
    max_step = 0.01
    with servo(drop=0.2, timeout=0.2 * T, limits=Limits(max_step=max_step)) as s:
        received: list[float] = []
        plant = s.device.plant
        apply = plant.command

        def command(u, t_ns, **kw):
            received.append(u)
            return apply(u, t_ns, **kw)

        plant.command = command
        result = run_session(s, excitation(2000, seed=4), SessionConfig(period_s=T))
    assert result.counts["timeout"] > 300  # the faults happened
    steps = np.abs(np.diff(received))
    assert steps.max() <= max_step * (1 + 1e-12), f"a step of {steps.max():.4g} reached the servo"
    assert steps.max() > 0.99 * max_step  # and the limit was the binding one
    # the recording says what the servo held: a timed-out row holds the command that was sent
    timed_out = np.flatnonzero(result.status == "timeout")
    assert np.all(np.abs(np.diff(result.u)) <= max_step * (1 + 1e-12))
    assert set(result.u[timed_out]) <= set(received)


def test_live_identification_refines_the_online_run_and_runs_no_second_mrgia(monkeypatch):
    import importlib

    from servoid.ident import identify

    pipeline = importlib.import_module("servoid.ident.identify")  # the module (the package exports the function)
    from servoid.session.listeners import EstimatorFeed

    config = MRGIAConfig(na=2, nb=0, delay=1)
    feed = EstimatorFeed(MRGIA(config), record_every=10)
    with servo(snr=40, drop=0.01, timeout=0.2 * T) as s:
        result = run_session(s, excitation(3000), SessionConfig(period_s=T), listeners=[feed])
    online = feed.mrgia_result()
    assert online is not None and online.samples == 3000 and (~result.valid).sum() > 10
    # what the session ran sample by sample is the batch run over the samples it was told were usable
    y = np.where(result.valid, result.y, 0.0)
    batch = run_mrgia(result.u, y, config, valid=result.valid, record_every=10)
    np.testing.assert_array_equal(online.theta, batch.theta)
    np.testing.assert_array_equal(online.theta_history, batch.theta_history)

    def no_second_run(*args, **kwargs):
        raise AssertionError("identify ran the MRGIA again")

    monkeypatch.setattr(pipeline, "run_mrgia", no_second_run)
    ident = identify(result.u, result.y, config, valid=result.valid, online=online)
    assert ident.mrgia is online and ident.method == "mrgia+oe"
    with pytest.raises(ConfigError, match="online result is for na=2"):
        identify(result.u, result.y, MRGIAConfig(na=3), valid=result.valid, online=online)
