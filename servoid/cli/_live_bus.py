"""``servoid identify --driver "feetech://PORT?id=1,2,3"``: identify every servo of one bus in one session.

The joints are excited ``--joints sequential`` (default: one after the other,
each for ``--samples``, the others holding their centre) or ``--joints
together`` (each its own signal, seeded ``--seed + index``, all at once), in
one session whose recording (``OUT/recording.csv``) has a column group per
joint. Each joint is then identified on its own samples (the slots that
excite it, less those the session could not use); its outputs go to
``OUT/joint_<id>/`` (``model.json``, plots), and one summary table has a row
per joint. The online MRGIA does not run during a bus session: each joint's
identification runs it afterwards (the progress line shows the bus's
timing instead).

The wall budget (``--budget``, :data:`~servoid.cli._live.BUS_BUDGET_WHY`) counts the
whole session from the bus's opening; the run cannot be cut (the servos are moving),
the identifications after it can: each joint's fits run under a
:class:`~servoid.ident.offline._threads.Stop` at its share of the time left
(:func:`joint_stop`), and a joint cut there answers with the best made by then,
withheld (:func:`~servoid.ident.identify.identify`), the cut named in its warning
line, its row of the summary table and its JSON's ``budget``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from servoid.bus_facts import GENTLE_AMPLITUDE_RAD
from servoid.cli import _live, _term
from servoid.errors import ConfigError, ServoidError

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

    from servoid.drivers.bus import BusDriver
    from servoid.ident.offline._threads import Stop
    from servoid.ident.online.mrgia import MRGIAConfig
    from servoid.session import SessionProgress

__all__ = ["add_options", "names_several", "run", "joint_stop"]


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--joints MODE`` (a group of ``servoid identify``).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.
    """
    from servoid.bus_facts import DEFAULT_MODE, MODES

    parser.add_argument("--joints", choices=MODES, default=DEFAULT_MODE,
                        help="several servos on one bus (--driver '...?id=1,2,3'): excite them one after the other, "
                             "the others holding (sequential, the default: on an arm a moving neighbour changes a "
                             "joint's load and so its play), or all at once with independent signals (together)")  # fmt: skip


def names_several(url: str | None) -> bool:
    """Whether a driver URL names several servos (``id=1,2,3``).

    Parameters
    ----------
    url : str or None
        The ``--driver`` URL.
    """
    if not url or "?" not in url:
        return False
    from urllib.parse import parse_qsl

    return any(k == "id" and "," in v for k, v in parse_qsl(url.split("?", 1)[1], keep_blank_values=True))


def run(args: argparse.Namespace, make_config: Callable[[float], MRGIAConfig]) -> int:
    """Run the bus session, identify each joint, write its outputs, print the table (or ``--json``).

    Parameters
    ----------
    args : argparse.Namespace
        The command line.
    make_config : callable
        ``make_config(epsilon)``: the estimator's settings.
    """
    import numpy as np

    from servoid.drivers import driver_from_url
    from servoid.drivers.bus import BusDriver
    from servoid.ident.identify import identify
    from servoid.ident.offline._threads import Stopped, stopping
    from servoid.ident.online.refinement import CUT
    from servoid.identify_outputs import OUTPUT_FILES, result_json, write_outputs
    from servoid.session import SessionConfig, run_session
    from servoid.session.joints import bus_excitation, joint_result

    began = time.perf_counter()  # the wall budget counts from here: the bus's opening included
    if args.data is not None:
        raise ConfigError("give --driver or --data, not both")
    _live.check_budget_and_lost(args)
    if not (math.isfinite(args.rate) and 0 < args.rate <= 20_000):
        raise ConfigError(f"--rate (={args.rate:g}) must lie in (0, 20000] Hz")
    if args.samples is not None and args.samples < 1:
        raise ConfigError(f"--samples (={args.samples}) must be >= 1")
    amplitude = args.amplitude if args.amplitude is not None else GENTLE_AMPLITUDE_RAD
    if not (math.isfinite(amplitude) and amplitude > 0):
        raise ConfigError(f"--amplitude (={amplitude:g}) must be > 0")
    bus = driver_from_url(args.driver)
    if not isinstance(bus, BusDriver):
        raise ConfigError(f"--driver {args.driver} names one servo")
    path = args.out / OUTPUT_FILES["recording"]
    quiet = args.json
    with bus:
        ids = bus.ids
        wall_s = _live.budget_s(args, len(ids))
        identities = [j.identity for j in bus.joints]
        samples = args.samples or _live.DEFAULT_SAMPLES

        # gentle sines by default (bus_facts says why), --amplitude their size
        spec = args.excitation or gentle_default(args.amplitude, args.rate, bus.command_unit.unit)

        def signal(index: int, n: int) -> np.ndarray:
            one = argparse.Namespace(**{**vars(args), "seed": args.seed + index, "samples": n, "excitation": spec,
                                        "amplitude": args.amplitude if args.excitation else None})  # fmt: skip
            limits = bus.joints[index].limits
            return _live.excitation(one, amplitude, limits, bus.command_unit.unit)[0] - limits.centre

        u, blocks = bus_excitation(signal, len(ids), samples, mode=args.joints)
        u += np.array([j.limits.centre for j in bus.joints])
        config = SessionConfig(period_s=1.0 / args.rate, use_late=args.use_late, guard_samples=args.guard)
        meta = {"amplitude": repr(amplitude), "seed": str(args.seed), "excitation": spec,
                "joints_excitation": args.joints}  # fmt: skip
        if not quiet:
            _term.stderr.print(f"servoid identify: {bus.describe()}: {len(ids)} joints, {args.joints}, at "
                               f"{args.rate:g} Hz, {u.shape[0]} slots ({u.shape[0] / args.rate:.1f} s), "
                               f"+/-{amplitude:g} {bus.command_unit.unit}; recording to {path}; "
                               f"wall budget {wall_s:g} s")  # fmt: skip
        if u.shape[0] / args.rate >= wall_s - len(ids) * _live.OUTPUTS_S:
            _term.warn(f"the run ({u.shape[0] / args.rate:.1f} s of servo time) leaves the joints no time within "
                       f"--budget {wall_s:g} s: every joint's identification will be cut (a larger --budget, fewer "
                       "--samples or --joints together let them end)")  # fmt: skip
        with _term.live_progress("live", u.shape[0]) as bar:

            def update(p: SessionProgress) -> None:
                bar(p.done, f"late {100 * p.late_share:.1f} %")

            result = run_session(bus, u, config, recording=path, metadata=meta, on_progress=None if quiet else update)
    if not quiet:
        cols, rows = _live.session_rows(result)
        _term.table(f"session: {bus.describe()}", cols, rows, console=_term.stderr)
    if result.stopped == "interrupted":
        _term.warn(f"interrupted after {len(result)} slots; they are in {path}")
        raise KeyboardInterrupt
    joints: list[dict[str, Any]] = []
    for index, servo_id in enumerate(ids):
        # this joint's share of the wall time left (what the joints before it left included)
        stop, share_s = joint_stop(began + wall_s, len(ids) - index)
        started = time.perf_counter()
        one = joint_result(result, index)
        block = blocks[index]
        one = dataclasses.replace(
            one, samples=one.samples[block], usable_flags=result.valid[block], slot_counts=None, _arrays={}
        )  # this joint's slots: its own counts
        source = f"{bus.describe()} joint {servo_id}"
        try:
            # the one-servo rules, per joint: too many unusable samples is a refusal with the reason, not a model
            lost = _live.check_lost(one, args.max_lost, allow=args.allow_lost, path=path)
            record = _live._record(one, source, identities[index], None, path, None)  # noqa: SLF001
            # with the record's time, so that the servo-loop model (the play inside the loop) is fitted too; its
            # fits (the black box's refinement, the servo-loop search) stop at the joint's share of the budget
            with stopping(stop):
                found = identify(record.u, record.y, make_config(args.epsilon if args.epsilon is not None else 0.0),
                                 refine_model=not args.no_refine, valid=record.valid,
                                 sample_period_s=record.sample_period_s, readings=record.readings)  # fmt: skip
        except (ServoidError, Stopped) as exc:  # this joint's samples do not identify it: say so, go on with the next
            budget = _joint_budget(stop, share_s, started)
            text = f"{exc}" + (f" ({CUT}: {budget['cut'][0]})" if budget["cut"] else "")
            _term.warn(f"joint {servo_id}: {text}")
            joints.append({"id": servo_id, "error": text, "budget": budget})
            continue
        budget = _joint_budget(stop, share_s, started)
        for w in found.warnings:
            _term.warn(f"joint {servo_id}: {w}")
        if budget["cut"]:
            _term.warn(f"joint {servo_id}: the wall budget ({wall_s:g} s; this joint's share {share_s:.1f} s) cut "
                       f"{budget['cut'][0]}, the verdict withheld (a larger --budget S lets them end)")  # fmt: skip
        record = dataclasses.replace(record, live={"lost": lost, "budget": budget})
        paths = write_outputs(args.out / f"joint_{servo_id}", record, found, plots=not args.no_plots)
        joints.append({"id": servo_id, **result_json(record, found, paths), "_found": found})
    failed = any("error" in j for j in joints)
    withheld = any("error" not in j and not j["_found"].identifiable for j in joints)
    status = 1 if failed or (args.strict and withheld) else 0
    cut = [j["id"] for j in joints if j["budget"]["cut"]]
    budget = {"wall_s": wall_s, "bounds": _live.BUS_BUDGET_WHY, "joints_cut": cut,
              "seconds": time.perf_counter() - began}  # fmt: skip
    if args.json:
        _term.print_json({"acquisition": result.to_dict(), "joints_excitation": args.joints, "budget": budget,
                          "joints": [{k: v for k, v in j.items() if k != "_found"} for j in joints]})  # fmt: skip
        return status
    _term.table(f"servoid identify: {len(ids)} joints on {bus.describe()}", *summary_rows(joints, bus))
    if args.strict and withheld:
        _term.warn("--strict: the play of at least one joint is not identifiable; exit 1")
    return status


def joint_stop(end_s: float, joints_left: int) -> tuple[Stop, float]:
    """The stop of one joint's identification: its share of the wall time left, less its outputs' seconds.

    Parameters
    ----------
    end_s : float
        The :func:`time.perf_counter` instant the session's wall budget ends (its start plus ``--budget``).
    joints_left : int
        The joints still to identify, this one included: each gets an equal share of what is left, so
        that what a quick joint leaves goes to the ones after it.

    Returns
    -------
    Stop, float
        The stop (at now + share - :data:`~servoid.cli._live.OUTPUTS_S`; past already when nothing is
        left: the fits stop at their first evaluation) and the share in wall seconds.
    """
    from servoid.ident.offline._threads import Stop

    if joints_left < 1:
        raise ConfigError(f"joints_left (={joints_left}) must be >= 1")
    now = time.perf_counter()
    share_s = (end_s - now) / joints_left
    return Stop(now + share_s - _live.OUTPUTS_S, "the wall budget"), share_s


def _joint_budget(stop: Stop, share_s: float, started_s: float) -> dict[str, Any]:
    """A joint's ``budget`` in the JSON: its share, its wall seconds, and the stage cut (empty when none)."""
    return {"share_s": share_s, "seconds": time.perf_counter() - started_s,
            "cut": [_live.IDENTIFY_CUT] if stop.fired else []}  # fmt: skip


def gentle_default(amplitude: float | None, rate_hz: float, unit: str) -> str:
    """The bus's default excitation as a spec: gentle sines of ``amplitude`` (default 0.1 rad), peak 8 rad/s^2.

    Parameters
    ----------
    amplitude : float or None
        ``--amplitude`` (the command unit), or None for :data:`~servoid.bus_facts.GENTLE_AMPLITUDE_RAD`.
    rate_hz : float
        The sample rate: the peak acceleration per sample squared is ``GENTLE_PEAK_ACCEL_RAD_S2 / rate^2``.
    unit : str
        The bus's command unit; the defaults are in rad, so another unit needs ``--excitation``.
    """
    from servoid.bus_facts import GENTLE_PEAK_ACCEL_RAD_S2

    if unit != "rad":
        raise ConfigError(f"the bus commands in {unit!r}, the default gentle sines are in rad: give --excitation")
    size = GENTLE_AMPLITUDE_RAD if amplitude is None else amplitude
    return f"gentle:amplitude={size!r},accel={GENTLE_PEAK_ACCEL_RAD_S2 / rate_hz**2!r},spread=8"


def summary_rows(joints: list[dict[str, Any]], bus: BusDriver) -> tuple[list[str], list[list[str]]]:
    """One row per joint: samples used, where the play sits, the play and its 95 % interval, the fit, the verdict,
    and whether the wall budget cut its identification (``cut``, else ``within``; its share in s).

    The play is the answer's (:attr:`~servoid.ident.identify.Identification.play`, of the
    structure identification chose), never shown without its verdict: a joint
    whose play the record cannot determine says "no" and why.

    Parameters
    ----------
    joints : list of dict
        Each joint's result (``_found``: its Identification) or error.
    bus : BusDriver
        The bus (for the unit).
    """
    from servoid.ident.models.structure_names import SERVO_LOOP

    unit = bus.position_unit.unit
    cols = ["joint", "samples", "play sits", f"play c1+c2 ({unit})", "play (deg)", f"95 % ({unit})",
            "fit / floor", "identifiable", "budget", "model"]  # fmt: skip
    rows = []
    for j in joints:
        share = j["budget"]["share_s"]
        spent = "cut" if j["budget"]["cut"] else "within"
        budget = f"{spent} ({share:.1f} s)" if math.isfinite(share) else spent
        if "error" in j:
            rows.append([str(j["id"]), "-", "-", "-", "-", "-", "-", "no: " + j["error"][:60], budget, "-"])
            continue
        found = j["_found"]
        degrees = f"{math.degrees(found.play):.3g}" if unit == "rad" else "-"
        low, high = found.play_interval
        interval = f"[{low:.4g}, {high:.4g}]" if math.isfinite(low) and math.isfinite(high) else "none"
        fit = found.loop.fit_nrmse if found.form == SERVO_LOOP and found.loop is not None else found.fit_nrmse
        ratio = fit / found.floor_nrmse if found.floor_nrmse > 0 else math.nan
        verdict = "yes" if found.identifiable else "no: " + found.reason[:60]
        rows.append([str(j["id"]), str(found.samples), found.structure, f"{found.play:.4g}", degrees, interval,
                     f"{ratio:.2f}", verdict, budget, j["outputs"]["model"]])  # fmt: skip
    return cols, rows
