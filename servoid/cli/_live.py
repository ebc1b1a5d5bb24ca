"""``servoid identify --driver URL``: identify a live servo through any driver.

The excitation (``--excitation SPEC``, else uniform white noise of
``--amplitude``; around the driver's ``centre``, ``--samples`` long, seeded
by ``--seed``) runs through the
sampling session at ``--rate``; the recording is written to
``OUT/recording.csv`` as samples arrive; the online MRGIA runs meanwhile and
the progress line shows it. The record then goes through the same
identification and outputs as an offline run, with the late, missed and
timed-out samples left out (:func:`servoid.session.usable`).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid import readings_side
from servoid.cli import _term
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.drivers.realtime import SAMPLER_PRIORITY
from servoid.drivers.servo_facts import DEFAULT_RATE_HZ
from servoid.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

    from servoid.drivers.base import Limits
    from servoid.excitation import GentleSpec
    from servoid.ident.identify import Identification
    from servoid.ident.models.pseudo_wiener import BacklashModel
    from servoid.ident.offline._threads import Stop
    from servoid.ident.offline.loop_fit import LoopChoice
    from servoid.ident.online.early_search import EarlySearch
    from servoid.ident.online.mrgia import MRGIAConfig, MRGIAResult
    from servoid.ident.online.window import SlowSearch, WindowResult
    from servoid.identify_outputs import Record
    from servoid.recording import Recording
    from servoid.session import SessionProgress, SessionResult

# The libraries a run needs are imported inside the functions that run it, so that the
# commands' --help (which add_options serves) starts without them.

__all__ = ["add_options", "live_record", "recording_valid", "session_rows", "excitation", "DEFAULT_RATE_HZ"]

#: Samples of a simulated or live run when --samples is not given.
DEFAULT_SAMPLES = 5000

#: Servo seconds of a live run designed from the probe when neither --samples nor --seconds is
#: given (more when its slow phase needs them for :data:`SLOW_REVERSALS` reversals: up to 44 s on
#: the twins). Issue 15's budget is 60 s of wall time for the probe and the identification: the probe
#: takes 6.2 s, the run this long, the fits after it a few seconds (the answer's search of the fast
#: part's head runs during the run: ident/online/early_search.py). 60 s of servo time before
#: (identify took 69-117 s on a real clock); docs/online.md, "Within 60 s of wall time".
DEFAULT_LIVE_S = 40.0
#: Issue 15's wall-time target for the probe and the identification, s.
WALL_TARGET_S = 60.0
#: Wall seconds kept after the servo-loop answer for identification and the outputs (0.0-0.2 s on ``sim://``).
AFTER_ANSWER_S = 2.0
#: Of :data:`AFTER_ANSWER_S`, the wall seconds kept for the outputs (files, plots): identification's own fits (the
#: black box's refinement) stop at the budget less this (:func:`identify_stop`).
OUTPUTS_S = 1.0
#: What the wall budget (``--budget``) bounds, said in --help and in the JSON's ``budget``.
BUDGET_WHY = ("on a real clock every fit after the run (the early searches, the last window, the answer's search, "
              "refits and horn stage) stops at the budget less {after:g} s kept for identification and the outputs, "
              f"identification's own fits at the budget less {OUTPUTS_S:g} s kept for the outputs; "
              "the best answer made by then answers, the cut stages are named and the verdict withheld")  # fmt: skip
#: What the wall budget bounds in a bus session (``--driver '...?id=1,2,3'``, :mod:`servoid.cli._live_bus`), said in
#: --help and in its JSON's ``budget``.
BUS_BUDGET_WHY = ("for several servos of one bus (id=1,2,3) the budget counts the whole session from the bus's "
                  f"opening (default {WALL_TARGET_S:g} s a joint): the wall time left after the run is shared among "
                  "the joints in turn (what one joint leaves goes to the next), each joint's identification "
                  f"stopping at its share less {OUTPUTS_S:g} s kept for its outputs")  # fmt: skip
#: The stage a stop after the answer cuts, named in the JSON's ``budget.cut`` (one live servo, or a bus's joint).
IDENTIFY_CUT = "identification's own fits (the best made by then answers)"
#: Reversals of the set point a design's slow phase holds at least (:func:`slow_phase`): each is a
#: motor crossing of the play, what the slow phase's search reads a play outside the loop from. 18:
#: the fewest a third of a 60 s run held on the twins (ODrive, XM430 designs, seeds 0-2), whose
#: answers it gave; 6-12 (a third of 40 s) missed the ODrive's play by -38 / -42 % on 2 of 3 seeds.
SLOW_REVERSALS = 18
#: Why the live run has its default length, said in --help and in the line a run starts with.
DEFAULT_LIVE_WHY = "probe, run and fits within 60 s of wall time"

#: Largest share of a live run's samples that may be unusable (lost, late, guarded) before
#: identify refuses to report a model (--max-lost; --allow-lost overrides): beyond it the
#: usable samples come in short runs between gaps, and the Dynamixel under load that lost
#: 50-80 % still got a model reported (issue 15).
DEFAULT_MAX_LOST = 0.2


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of a live run (a group of ``servoid identify``)."""
    live = parser.add_argument_group("live servo")
    live.add_argument("--driver", metavar="URL",
                      help="identify this servo live: sim://xm430?snr=40 (a twin; sim://model the model), serial:///dev/ttyUSB0, can://..., dxl://... "
                           "(see docs/drivers.md); --samples, --seed set the excitation")  # fmt: skip
    live.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ, metavar="HZ",
                      help=f"sample rate of the live run in Hz (default {DEFAULT_RATE_HZ:g})")  # fmt: skip
    live.add_argument("--seconds", type=float, metavar="S",
                      help=f"servo seconds of the live run, instead of --samples (default, a run designed from its "
                           f"probe: {DEFAULT_LIVE_S:g} s, {DEFAULT_LIVE_WHY}; longer runs show more reversals, "
                           "and the fits after them take longer)")  # fmt: skip
    live.add_argument("--amplitude", type=float, metavar="A",
                      help="half-width of the uniform excitation, in the driver's unit "
                           f"(default: the simulated servo's reference, else {MODEL_AMPLITUDE} for the bench servo)")  # fmt: skip
    live.add_argument("--guard", type=int, metavar="N",
                      help="samples left out after one whose command the servo may have applied otherwise than "
                           "recorded: a timed-out exchange (the command or its reply lost), and for a device on its "
                           "own clock (Dynamixel, ODrive) a late or missed slot too; the next samples carry that "
                           "error (default 10)")  # fmt: skip
    live.add_argument(
        "--use-late", action="store_true", help="let the estimator use samples exchanged late (default: leave them out)"
    )
    live.add_argument("--no-probe", action="store_true",
                      help="skip the probe (a short safe experiment that measures the loop's bandwidth, delay, noise, "
                           "saturation and rough play, and designs the run from them); then --decimate (default 1), "
                           "--amplitude or --excitation set the run")  # fmt: skip
    live.add_argument("--decimate", type=int, metavar="K",
                      help="run the online estimator on every K-th sample (default: the smallest K at which its "
                           "convergence condition holds on the probe's model)")  # fmt: skip
    live.add_argument("--hold", type=int, metavar="N",
                      help="held random levels of N samples instead of the designed gentle sines (whose fastest "
                           "segment is set from the probe's loop bandwidth: docs/online.md)")  # fmt: skip
    live.add_argument("--budget", type=float, default=None, metavar="S",
                      help=f"wall seconds for the probe, the run and the answer (default {WALL_TARGET_S:g}, issue 15's "
                           f"target): {BUDGET_WHY.format(after=AFTER_ANSWER_S)}; {BUS_BUDGET_WHY}; a simulated servo "
                           "on a virtual clock (sim://NAME?clock=virtual) is not timed")  # fmt: skip
    live.add_argument("--max-lost", type=float, default=DEFAULT_MAX_LOST, metavar="SHARE",
                      help="refuse to report a model when more than this share of the samples was lost, late or "
                           f"guarded (default {DEFAULT_MAX_LOST:g})")  # fmt: skip
    live.add_argument("--allow-lost", action="store_true",
                      help="report a model however many samples were lost (the share is still printed)")  # fmt: skip


def with_length(args: argparse.Namespace) -> argparse.Namespace:
    """The command line with ``--seconds`` turned into ``--samples`` at ``--rate`` (unchanged without it).

    Raises
    ------
    ConfigError
        ``--seconds`` with ``--samples``, without ``--driver``, or not a positive number.
    """
    seconds = getattr(args, "seconds", None)
    if seconds is None:
        return args
    if args.samples is not None:
        raise ConfigError("give --samples or --seconds, not both")
    if args.driver is None:
        raise ConfigError("--seconds sets the length of a live run (--driver); a simulated run takes --samples")
    if not (math.isfinite(seconds) and seconds > 0):
        raise ConfigError(f"--seconds (={seconds:g}) must be > 0")
    return argparse.Namespace(**{**vars(args), "seconds": None, "samples": max(1, int(round(seconds * args.rate)))})


def length_note(args: argparse.Namespace, samples: int, designed: str | None) -> str:
    """The run's servo seconds, and when they are the default of a designed run, which and why."""
    seconds = f"{samples / args.rate:.1f} s"
    if args.samples is None and designed is not None and args.excitation is None:
        return f"{seconds}: the default, {DEFAULT_LIVE_WHY}; --seconds to change"
    return seconds


def excitation(
    args: argparse.Namespace,
    amplitude: float,
    limits: Limits,
    unit: str = "",
    designed: str | None = None,
    slow: tuple[str, float] | None = None,
) -> tuple[np.ndarray, int]:
    """The input of a live run, and how many of its first samples are the design's slow phase.

    ``--excitation file:...`` replays a file's commands as they are, after
    checking them against the driver's ``limits``; a spec (``--excitation
    SPEC``) runs around ``limits.centre``; else the ``designed`` spec (the
    design from the probe, :meth:`LiveDesign.spec`) or uniform noise ``centre +/-
    amplitude``. ``--samples`` long (a file: all of it by default; a design:
    :data:`DEFAULT_LIVE_S` of servo time). ``slow`` (a design's
    :meth:`LiveDesign.slow_spec` and its share of the run) comes first, cut at
    the end of a whole segment (back at the centre: no step into the fast phase), long
    enough for :data:`SLOW_REVERSALS` reversals (:func:`slow_phase`); a default run then
    grows by what the slow phase took beyond its share, so that the fast part keeps its own.
    """
    from servoid.excitation import GentleSpec, UniformSpec, parse_spec, sample
    from servoid.readers.excitation_file import is_file_spec, read_excitation

    if args.excitation is not None and args.amplitude is not None:
        raise ConfigError("give --amplitude or --excitation (whose spec has its own amplitude), not both")
    if is_file_spec(args.excitation):
        replay = read_excitation(args.excitation)
        replay.check_within(limits.low, limits.high, limits.max_step, unit=unit)
        u: np.ndarray = replay.first(args.samples)
        return u, 0
    if args.excitation is not None:
        spec = parse_spec(args.excitation)
    else:
        spec = UniformSpec(amplitude=amplitude) if designed is None else parse_spec(designed)
    default = DEFAULT_SAMPLES if designed is None else int(round(DEFAULT_LIVE_S * args.rate))
    n = args.samples or default
    if args.excitation is not None or slow is None:
        return limits.centre + sample(spec, n, seed=args.seed), 0
    import numpy as np

    slow_spec = parse_spec(slow[0])
    assert isinstance(slow_spec, GentleSpec)
    first = slow_phase(slow_spec, args.seed, int(slow[1] * n), n // 2)
    if args.samples is None:  # the default run: a longer slow phase leaves the fast part its share of DEFAULT_LIVE_S
        n = max(n, first + n - int(slow[1] * n))
    head = sample(slow_spec, first, seed=args.seed) if first else np.empty(0)
    return limits.centre + np.concatenate([head, sample(spec, n - first, seed=args.seed)]), first


def slow_phase(spec: GentleSpec, seed: int, share: int, most: int) -> int:
    """Samples of a design's slow phase: whole segments, at least ``share`` and :data:`SLOW_REVERSALS` reversals.

    The slow phase answers for a play outside the loop (``refine_online``'s step 4), one motor
    crossing of the play per reversal of the set point (by more than a tenth of the amplitude), and
    its segments are long: cut at whole segments, a third of a 40 s run of the ODrive or XM430 design
    held 6-12 reversals in 6-8 s, where the answer missed the ODrive twin's play by -38 / -42 % (seeds
    0, 1; a third of 60 s: 18-24 reversals, +3 / +1 %). It ends at the first segment end after the
    :data:`SLOW_REVERSALS`-th reversal, when that is later than ``share`` and within ``most``.

    Parameters
    ----------
    spec : GentleSpec
        The slow phase's signal.
    seed : int
        Its seed.
    share : int
        Samples of the design's share of the run (:data:`~servoid.ident.online.probe_design.SLOW_PART`).
    most : int
        The most samples it may take (half the run).

    Returns
    -------
    int
        The samples, at segment ends (0 when no segment fits in ``share``).
    """
    from servoid.excitation import sample
    from servoid.excitation.gentle import segment_end, whole_segments
    from servoid.ident.offline.intervals import reversal_indices

    first = whole_segments(spec, seed, share)
    turns = reversal_indices(sample(spec, max(most, 1), seed=seed), 0.1 * spec.amplitude)
    if turns.size >= SLOW_REVERSALS:
        enough = segment_end(spec, seed, int(turns[SLOW_REVERSALS - 1]) + 1)
        if enough <= most:
            first = max(first, enough)
    return first


def recording_valid(rec: Recording) -> np.ndarray | None:
    """The samples of a recording to identify from (:func:`servoid.session.samples.recording_usable`)."""
    from servoid.session.samples import recording_usable

    return recording_usable(rec)


def live_record(args: argparse.Namespace, make_config: Callable[[float], MRGIAConfig]) -> tuple[Record, MRGIAConfig]:
    """Run the excitation through ``args.driver`` with the MRGIA online; return the record and the settings.

    ``make_config(epsilon)`` builds the estimator's settings from the command
    line, once: the record carries the online run's result
    (:attr:`Record.online`), which identification refines rather than runs again.
    """
    began = time.perf_counter()  # the wall budget counts from here: the driver's opening included
    if args.data is not None:
        raise ConfigError("give --driver or --data, not both")
    if args.snr is not None:
        raise ConfigError("--snr sets the noise of the built-in simulation; for the simulated servo put it in the URL: "
                          "--driver 'sim://xm430?snr=40'")  # fmt: skip
    if not (math.isfinite(args.rate) and 0 < args.rate <= 20_000):
        raise ConfigError(f"--rate (={args.rate:g}) must lie in (0, 20000] Hz")
    if args.samples is not None and args.samples < 1:
        raise ConfigError(f"--samples (={args.samples}) must be >= 1")
    from servoid.drivers import driver_from_url
    from servoid.drivers.clock import VirtualClock
    from servoid.drivers.simulated import SimulatedServo
    from servoid.ident.offline._threads import Stop
    from servoid.ident.online.decimate import DecimatingEstimator
    from servoid.ident.online.early_search import EarlySearch, head_samples
    from servoid.ident.online.mrgia import MRGIA, noise_epsilon
    from servoid.ident.online.refinement import CUT
    from servoid.ident.online.window import END_GRACE_S, WindowConfig, WindowRefit
    from servoid.identify_outputs import OUTPUT_FILES
    from servoid.session import SessionConfig, run_session
    from servoid.session.listeners import EstimatorFeed

    _check_live_options(args)
    driver = driver_from_url(args.driver)
    quiet = args.json
    live: dict[str, Any] = {}
    with driver:
        identity = driver.identity
        noise = identity.get("noise_std")
        if args.epsilon is not None:
            epsilon = args.epsilon
        else:
            epsilon = noise_epsilon(noise) if isinstance(noise, (int, float)) else 0.0
        simulated = driver if isinstance(driver, SimulatedServo) else None
        amplitude = args.amplitude if args.amplitude is not None else (
            simulated.reference_amplitude if simulated is not None else MODEL_AMPLITUDE)  # fmt: skip
        if not (math.isfinite(amplitude) and amplitude > 0):
            raise ConfigError(f"--amplitude (={amplitude:g}) must be > 0")
        config = SessionConfig(period_s=1.0 / args.rate, use_late=args.use_late, guard_samples=args.guard)
        factor, designed, slow = (args.decimate or 1), None, None
        clock = _Stages()
        # the wall budget on a real clock: one stop for every fit after the run (the early searches', the last
        # window's, the answer's), at the budget less what identification and the outputs take (module BUDGET_WHY)
        virtual = simulated is not None and isinstance(simulated.clock, VirtualClock)
        wall_s = budget_s(args)
        budget = None if virtual else Stop(began + wall_s - AFTER_ANSWER_S, "the wall budget")
        live["budget"] = {"wall_s": None if virtual else wall_s, "after_answer_s": AFTER_ANSWER_S,
                          "bounds": "not timed (a virtual clock)" if virtual else BUDGET_WHY.format(after=AFTER_ANSWER_S)}  # fmt: skip
        if not args.no_probe:
            design = probe_and_design(args, driver, amplitude, config, quiet=quiet)
            clock.mark("probe")
            live.update(probe=design[0].to_dict(), design=design[1].to_dict())
            factor, designed, amplitude = design[1].factor, design[1].spec(), design[1].amplitude
            slow_spec = design[1].slow_spec()
            slow = None if slow_spec is None else (slow_spec, design[1].slow_part)
        u, slow_samples = excitation(args, amplitude, driver.limits, driver.command_unit.unit, designed=designed,
                                     slow=slow)  # fmt: skip
        estimator_config = make_config(epsilon)
        online = EstimatorFeed(
            DecimatingEstimator(MRGIA(estimator_config), factor, record_every=history_every(u.size // factor))
        )
        # the servo-loop model's online estimate, on every sample, refitted on a worker thread
        # (on a real clock no refit is started that the last refits' wall time says cannot end before the run)
        # the answer's search of the fast part's head, started while the run goes on (fed before the window refit,
        # whose second look on the same samples takes its answer)
        # (on a real clock searched warm from the first window's load when the machine is too slow for its own: end)
        early = EarlySearch(config.period_s, head_samples(u.size, slow_samples), skip=slow_samples,
                            end=0 if virtual else u.size, stop=budget)  # fmt: skip
        # the slow phase's search on a thread of its own, started when first asked for (a window that puts the play
        # outside the loop, else the answer's step 4): the windows and the answer take it (one search of the slow phase)
        slow_search = EarlySearch(config.period_s, slow_samples, hold=True, stop=budget) if slow_samples else None
        # (on a real clock a first window's search still running at the run's end carries on for the head's search)
        window = WindowRefit(WindowConfig(config.period_s), wait=virtual, slow=slow_samples, load=None, end=u.size,
                             grace_s=END_GRACE_S, early=early, slow_early=slow_search, budget=budget)  # fmt: skip
        window.warm_up()
        if not virtual:
            early.warm_up()  # the searches' kernels loaded before the servo moves (a real sampler cannot wait)
        path = args.out / OUTPUT_FILES["recording"]
        meta = {"amplitude": repr(amplitude), "seed": str(args.seed), "excitation": args.excitation or _described(designed, slow, slow_samples),
                "servo": _flat(identity), "decimate": str(factor),
                readings_side.METADATA_KEY: readings_side.of(identity)}  # fmt: skip
        if not quiet:
            _term.stderr.print(f"servoid identify: {driver.describe()} at {args.rate:g} Hz, {u.size} samples "
                               f"({length_note(args, u.size, designed)}), +/-{amplitude:g} {driver.command_unit.unit}; "
                               f"the online estimator at 1 in {factor}; recording to {path}")  # fmt: skip
        with _term.live_progress("live", u.size) as bar:

            def update(p: SessionProgress) -> None:
                bar(p.done, _status_text(p, driver.position_unit.unit))

            clock.mark("setup")
            try:
                result = run_session(
                    driver, u, config, recording=path, metadata=meta,
                    listeners=[online, *([] if slow_search is None else [EstimatorFeed(slow_search)]), EstimatorFeed(early),
                               EstimatorFeed(window)],
                    on_progress=None if quiet else update,
                )  # fmt: skip
            except BaseException:
                window.close()  # the worker stopped and the switch interval restored on an error's way out too
                raise
    clock.mark("run")
    for search in (early, slow_search):  # no sampler to yield to any more: the searches at the machine's priority
        if search is not None:
            search.full_speed()
    if slow_search is not None and result.stopped != "interrupted" and _maybe_outside(window.model):
        # no sampler to share the machine with any more: the slow phase's search, if no window has started it, now
        # runs beside the waits below (the answer's step 4 takes it when the place is outside the loop; the CiA 402
        # twin at load 7 with no window refit: 20 s of loop_answer after a 30 s wait for the early search)
        slow_search.begin()
    if not quiet:
        cols, rows = session_rows(result)
        _term.table(f"session: {driver.describe()}", cols, rows, console=_term.stderr)
    # the window refit's last window (the worker stops here, whatever follows): the end refitted unless the last
    # window is as fresh as the refits are apart. On a virtual clock a running refit is waited for; on a real clock
    # a refit (the end's too) still running END_GRACE_S after the run is told to stop and the newest finished
    # window is the estimate, its age in the JSON and the verdict (on the CiA 402 twin waiting took up to 14 s)
    ended = result.stopped != "interrupted"
    grace_s = END_GRACE_S if budget is None else min(END_GRACE_S, max(budget.left_s(), 0.0))
    window_result = window.result(final=ended, fresh_s=window.config.every_s, wait=ended and virtual,
                                  wait_s=grace_s if ended else 0.0)  # fmt: skip
    clock.mark("last_window")
    early_search = early.result(wait=result.stopped != "interrupted")
    clock.mark("early_search")
    if result.stopped == "interrupted":
        _term.warn(f"interrupted after {len(result)} samples; they are in {path} "
                   f"(identify them with: servoid identify --data {path})")  # fmt: skip
        raise KeyboardInterrupt
    if result.estimator_error:
        _term.warn(f"online estimation stopped early: {result.estimator_error}")
    live["lost"] = check_lost(result, args.max_lost, allow=args.allow_lost, path=path)
    live["slow_samples"] = slow_samples
    live["early_search"] = _early_dict(early, early_search)
    if slow_search is not None:
        live["slow_search"] = _early_dict(slow_search, slow_search.result(wait=False))
    slow_found = None if slow_search is None else (lambda: slow_search.searched(wait=True))
    # (on a real clock the answer's horn stage only where it can end within the wall budget, identification after it)
    live["online_loop"], loop = loop_online(
        window_result, result, slow_samples, early_search, slow_found,
        deadline_s=math.inf if budget is None else budget.deadline_s,
    )  # fmt: skip
    clock.mark("loop_answer")
    live["budget"]["cut"] = cut = _cut(early, slow_search, live["online_loop"])
    if cut and not quiet:
        _term.warn(f"the wall budget ({wall_s:g} s) cut {'; '.join(cut)} (a larger --budget S lets them end)")
    if loop is None and live["online_loop"].get("cut"):
        # no servo-loop answer made: identification fits the black box alone (the decimated MRGIA's estimate refined;
        # its servo-loop search would be the one just cut), its verdict withheld with the reason (unanswered)
        live["budget"]["unanswered"] = (
            f"{CUT}: the servo-loop search, with no online servo-loop estimate to answer instead; the answer is "
            f"the black box's (identify the recording offline for the servo loop: servoid identify --data {path}, "
            "or give a larger --budget)"
        )
    live["wall_s"] = clock.seconds
    est = online.estimator
    if isinstance(est, DecimatingEstimator):
        live["decimation"] = est.stats.to_dict()
        if est.stats.unheld and not (designed or "").startswith("gentle"):  # designed sines change in a group
            _term.warn(f"the set point changed inside {est.stats.unheld} of {est.stats.groups} groups of {factor} "
                       "samples: the online estimator saw their mean (hold the excitation for whole groups)")  # fmt: skip
    truth = simulated.truth if simulated is not None else None
    record = _record(result, driver.describe(), identity, truth, path, online.mrgia_result(), factor)
    return dataclasses.replace(record, live=live, loop=_on_record(loop, result, record, factor)), estimator_config


def identify_stop(record: Record, began_s: float) -> Stop | None:
    """The stop of identification's fits after a live run on a real clock (None: none, a virtual clock or no run).

    At ``began_s`` (the command's :func:`time.perf_counter` start, at or before the run's) plus the wall budget less
    :data:`OUTPUTS_S`; a fit stopped there keeps the best answer made and says so (:func:`~servoid.ident.identify.identify`).
    """
    from servoid.ident.offline._threads import Stop

    wall_s = ((record.live or {}).get("budget") or {}).get("wall_s")
    return None if wall_s is None else Stop(began_s + wall_s - OUTPUTS_S, "the wall budget")


def _cut(early: EarlySearch, slow_search: EarlySearch | None, online_loop: dict[str, Any]) -> list[str]:
    """The stages the wall budget cut (the JSON's ``budget.cut``), each with what answered instead."""
    cut = []
    if early.cut:
        cut.append("the early search of the fast part's head (the answer searched the fast part itself)")
    if slow_search is not None and slow_search.cut:
        cut.append("the slow phase's search")
    refined = online_loop.get("refined") or {}
    cut += [f"in the answer: {c}" for c in refined.get("cut") or ()]
    if online_loop.get("cut"):
        cut.append(f"the answer: {online_loop['cut']}")
    return cut


def _maybe_outside(model: Any) -> bool:
    """Whether the window refit's model leaves a play outside the loop possible (none yet, or one outside)."""
    from servoid.ident.models.structure_names import PLAY_IN_LOOP

    return model is None or model.structure != PLAY_IN_LOOP


class _Stages:
    """Wall seconds of a live run's stages, in order (``live["wall_s"]``: where the time went)."""

    def __init__(self) -> None:
        self._last = self.started = time.perf_counter()
        self.seconds: dict[str, float] = {}

    def mark(self, stage: str) -> None:
        """Close ``stage``: the wall time since the last mark."""
        now = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - self._last
        self._last = now


def _early_dict(early: EarlySearch, found: SlowSearch | None) -> dict[str, Any]:
    """For JSON: where the answer's early search started, what it covered, and whether it was taken."""
    return {"at_samples": early.at, "started": early.started, "samples": None if found is None else found.samples,
            "play": None if found is None else found.choice.play,
            "structure": None if found is None else found.choice.structure,
            "seconds": None if found is None else found.choice.seconds, "error": early.error,
            "warm": early.warm, "taken": early.taken}  # fmt: skip


def _described(designed: str | None, slow: tuple[str, float] | None, slow_samples: int) -> str:
    """The recording's note of its excitation: the designed spec, after the slow phase's when there is one."""
    if designed is None:
        return "uniform"
    return designed if slow is None or not slow_samples else f"{slow[0]} for {slow_samples} samples, then {designed}"


def history_every(samples: int) -> int:
    """Every how many samples the MRGIA's history is kept: at most 20 000 rows for the convergence plot."""
    return max(1, samples // 20_000)


def _record(
    result: SessionResult,
    source: str,
    identity: dict[str, Any],
    truth: BacklashModel | None,
    path: Path,
    online: MRGIAResult | None,
    factor: int = 1,
) -> Record:
    """The record identification works on: the session's, or with ``factor > 1`` the slow record the online estimator saw.

    The offline fit then runs on the estimator's time base and starts from its
    estimate (no second MRGIA run); the recording keeps every sample. A
    pseudo-Wiener plant's truth is at the session's rate, so it is not
    compared with a decimated model.
    """
    import numpy as np

    from servoid.ident.online.decimate import decimate_record
    from servoid.identify_outputs import Record

    u, y, t, valid = result.u, result.y, result.t, result.valid
    if factor > 1:
        u, y, valid, _ = decimate_record(u, y, factor, valid)
        t = t[: u.size * factor : factor]
        truth = None
    if not valid.any():
        raise ConfigError(f"no sample of {source} was usable ({result.counts}); the recording is in {path}")
    # the free-run simulation starts at the first measured sample; the online run began before it, on
    # unusable samples it skipped, so its estimate is the MRGIA's on this record (its sample counts are the
    # session's) and identification refines it rather than running the MRGIA again (9 s at load 7-9
    # after a run whose first decimated sample was unusable, issue 15 wall15 session)
    first = int(np.argmax(valid))
    unit = result.unit
    return Record(
        u=u[first:], y=y[first:], t=t[first:], source=source, input_unit=unit,
        output_unit=unit, truth=truth, servo=identity, written_to=path, valid=valid[first:],
        acquisition=acquisition(result), online=online, readings=readings_side.of(identity),
    )  # fmt: skip


def with_verdict(record: Record, result: Identification, *, quiet: bool) -> Record:
    """A live record with the online estimate's verdict and which number is the answer, printed.

    The online estimate is the product of a live run: it is judged on its
    trajectory and against the refined fit of the same record, and both
    numbers are shown. Two estimators ran: the decimated MRGIA (the
    pseudo-Wiener model, :func:`~servoid.ident.online.verdict.judge_online`)
    and the moving-window servo-loop refit (:func:`loop_online`). The one
    reported as ``online`` is the servo loop's when identification chose that
    form, or, as the second-structure seam decides
    (:func:`~servoid.ident.offline.second_structure.second_structure`), when
    the black box is off its floor or its residual is coloured and the servo
    loop's answer on the whole record fits it within
    ``1 + MIN_STRUCTURE_MARGIN`` of the black box; else the MRGIA's (the
    paper's plant). Both are kept in the JSON.

    ``live["answer"]`` says where the reported play came from (:func:`answer`):
    the servo loop's search on the whole record or the online estimate that won
    it as a candidate, or identification's own fit (the black box), and how far
    the online play lies from it. Records that are not live pass unchanged.
    """
    if not record.live:
        return record
    import math

    from servoid.ident.models.structure_names import PSEUDO_WIENER, SERVO_LOOP
    from servoid.ident.offline.intervals import MAX_FIT_TO_FLOOR, MIN_STRUCTURE_MARGIN
    from servoid.ident.offline.second_structure import needed
    from servoid.ident.online.verdict import judge_online

    refined = result.model if result.refinement is not None else None
    verdict = judge_online(result.mrgia, result.mrgia_nrmse, refined, result.fit_nrmse if refined else None)
    mrgia = {**verdict.to_dict(), "estimator": "mrgia", "structure": PSEUDO_WIENER}
    loop = record.live.get("online_loop") or {}
    loop_verdict = loop.get("verdict")
    at_floor = math.isfinite(result.floor_nrmse) and result.fit_nrmse <= MAX_FIT_TO_FLOOR * result.floor_nrmse
    # the second-structure seam's rule: the loop only where the black box is not enough, and fits about as well
    loop_fit = _num((loop.get("refined") or {}).get("fit_nrmse"))
    use_loop = loop_verdict is not None and (
        result.form == SERVO_LOOP
        or (needed(at_floor, result.residual_white) and loop_fit <= (1.0 + MIN_STRUCTURE_MARGIN) * result.fit_nrmse)
    )
    chosen = mrgia
    if loop_verdict is not None:
        model = loop["estimate"]["model"]
        loop_dict = {**loop_verdict, "estimator": "window", "structure": model["structure"] if model else None}
        chosen = loop_dict if use_loop else mrgia
    said = answer(record, result, chosen)
    if not quiet:
        unit = record.output_unit
        mark = {True: "", False: " (not the reported one)"}
        (_term.stderr.print if verdict.settled else _term.warn)(
            "pseudo-Wiener, decimated MRGIA" + mark[not use_loop] + ": " + verdict.line(unit)
        )
        if loop_verdict is not None:
            line = (f"servo loop ({loop_dict['structure']}), online window refit{mark[use_loop]}: play "
                    f"{_num(loop_verdict.get('online_gap')):.4g} {unit} (fit {_num(loop_verdict.get('online_nrmse')):.3g}); "
                    f"the whole record's fit: {_num(loop_verdict.get('refined_gap')):.4g} {unit} "
                    f"(fit {_num(loop_verdict.get('refined_nrmse')):.3g}); ")  # fmt: skip
            line += "settled" if loop_verdict["settled"] else "NOT settled: " + "; ".join(loop_verdict["reasons"])
            line += f" ({loop_verdict['judged']})" if loop_verdict.get("judged") else ""
            (_term.stderr.print if loop_verdict["settled"] else _term.warn)(line)
    return dataclasses.replace(record, live={**record.live, "online": chosen, "online_mrgia": mrgia, "answer": said})


def answer(record: Record, result: Identification, online: dict[str, Any]) -> dict[str, Any]:
    """Which number a live identify reports as its answer, and how the online estimate compared (JSON-ready).

    ``source`` is ``loop_online`` when the servo-loop answer is the online estimate, which
    validated better than the offline search on the whole record and was refitted on it
    (:func:`loop_online`; identification took it, ``identify(loop=)``), ``loop_search`` when
    that search's own answer won, ``loop_online_cut`` when the wall budget cut that search and the
    online estimate answered as it is (not validated), ``offline_fit`` when identification's own fit
    answers (the black box, or no online servo-loop model); ``online_settled`` says whether the online
    estimate had converged and ``gap`` is the online play relative to the answer's (the
    convergence check). ``line`` is the sentence ``servoid identify`` prints under its headline.
    """
    import math

    unit = record.output_unit
    online_play = _num(online.get("online_gap"))
    play = float(result.play)
    gap = online_play / play - 1.0 if math.isfinite(online_play) and play > 0.0 else math.nan
    took_online = record.loop is not None and result.loop is record.loop
    refined = ((record.live or {}).get("online_loop") or {}).get("refined") or {}
    won = bool(refined.get("online_won"))
    # the search cut by the wall budget: the online estimate answered as it is, not as a validated candidate
    unsearched = any(c.startswith("the search") for c in refined.get("cut") or ())
    source = (
        ("loop_online_cut" if unsearched else "loop_online" if won else "loop_search") if took_online else "offline_fit"
    )
    est = "the servo loop's window refit" if online.get("estimator") == "window" else "the decimated MRGIA"
    why = "settled" if online.get("settled") else "NOT settled"
    if took_online and not math.isfinite(online_play):  # no window refit ended before the run did: the search alone
        line = (f"the answer: the offline search on the whole record: play {play:.4g} {unit}; no online estimate "
                f"({est}: no refit ended before the run did)")  # fmt: skip
    elif took_online and unsearched:
        line = (f"the answer: the online estimate ({est}, {why}) as it is, its search cut by the wall budget: play "
                f"{play:.4g} {unit} (not validated against any search)")  # fmt: skip
    elif took_online:
        how = ("the online estimate won the offline search's validation on the whole record" if won
               else "the offline search on the whole record (the online estimate a candidate)")  # fmt: skip
        line = (f"the answer: {how}: play {play:.4g} {unit}; the online estimate ({est}, {why}) "
                f"{online_play:.4g} {unit}, {100 * gap:+.1f} % from it")  # fmt: skip
    else:
        line = (f"the answer: identification's own fit ({result.form}): play {play:.4g} {unit}; the online estimate "
                f"({est}, {why}) {online_play:.4g} {unit}, {100 * gap:+.1f} % from it")  # fmt: skip
    return {"source": source, "play": play, "structure": result.structure, "form": result.form,
            "online_estimator": online.get("estimator"), "online_play": online_play, "online_settled":
            bool(online.get("settled")), "gap": gap, "line": line}  # fmt: skip


def loop_online(
    online: WindowResult,
    result: SessionResult,
    slow_samples: int = 0,
    early: SlowSearch | None = None,
    slow_search: Callable[[], SlowSearch | None] | None = None,
    *,
    deadline_s: float = math.inf,
) -> tuple[dict[str, Any], LoopChoice | None]:
    """The servo-loop answer of a live run, the online estimate among its candidates, and the estimate's verdict (JSON-ready).

    The answer is :func:`~servoid.ident.online.refinement.refine_online` over the
    usable samples: the offline search on the whole record (both places fresh,
    the load stage) with the last window's model as one more candidate judged
    on validation; :func:`~servoid.ident.online.verdict.judge_window` judges the
    online estimate on its windows and against that answer. :func:`with_verdict`
    then reports this estimate or the MRGIA's, by the structure identification chose.

    Returns the JSON-ready summary and the answer as identification's servo-loop
    answer (``identify(loop=)``, which applies the offline honesty rules to it; None
    when the refinement failed, and identification fits its own). With no online model
    (no window refit ended before the run did: the CiA 402 twin at load 7-12) the search
    answers alone and the verdict says why there is no estimate: identification then
    does not search the record again (24-30 s at load 8, and the MRGIA's offline fit
    answered there, -97 ... +32 %).

    Parameters
    ----------
    online : WindowResult
        The window refit's run (:meth:`~servoid.ident.online.window.WindowRefit.result`).
    result : SessionResult
        The session it ran in (every sample, with the usable ones).
    slow_samples : int
        How many of its first samples are the design's slow phase
        (:func:`~servoid.ident.online.refinement.refine_online`'s ``slow``).
    early : SlowSearch, optional
        The search of the fast part's head run during the session
        (:class:`~servoid.ident.online.early_search.EarlySearch`, ``start`` counted from the
        slow phase's end), which the refinement takes instead of searching those samples again.
    slow_search : callable, optional
        The slow phase's search held by the session (``EarlySearch(period, slow_samples, hold=True)``,
        started when first asked for), when the refinement needs it and the windows did not take it
        (``refine_online(slow_search=)``).
    deadline_s : float
        The :func:`time.perf_counter` instant by which the refinement's horn stage must end (its step 5).
    """
    import numpy as np

    from servoid.ident.offline._threads import Stopped
    from servoid.ident.online.refinement import CUT, refine_online
    from servoid.ident.online.verdict import judge_window

    out: dict[str, Any] = {"estimate": online.to_dict(), "refined": None, "verdict": None}
    keep = result.valid
    first = int(np.argmax(keep))
    u, y, keep = result.u[first:], result.y[first:], keep[first:]
    started = time.perf_counter()
    try:
        if early is not None:  # its start on this record: the session's samples from the first usable one
            early = dataclasses.replace(early, start=slow_samples + early.start - first)
        slow_done = _moved(slow_search, -first)
        choice, refined = refine_online(u, y, online, keep=keep, slow=max(slow_samples - first, 0), early=early,
                                        slow_search=slow_done, deadline_s=deadline_s)  # fmt: skip
    except (ConfigError, ValueError) as exc:
        out["verdict"] = {"settled": False, "reasons": [f"the refinement failed: {exc}"]}
        return out, None
    except Stopped as exc:  # no online model and the search cut: no answer made
        out["cut"] = f"the search ({exc}), with no online estimate to answer instead"
        out["verdict"] = {"settled": False, "reasons": [f"{CUT}: {out['cut']}"]}
        return out, None
    if online.model is None:  # no window refit ended (a loaded real clock): the search answered alone, nothing to judge
        verdict = dataclasses.replace(judge_window(online), refined_gap=choice.play, refined_nrmse=choice.fit_nrmse)
    else:  # like with like: the online model on the samples the answer's fit is on (after a slow phase: one part)
        verdict = judge_window(online, refined.score(online.model, u, y, keep), choice.play, choice.fit_nrmse)
    if refined.cut:  # an answer from an earlier stage: the online estimate is not judged settled against it
        verdict = dataclasses.replace(
            verdict, settled=False, reasons=(*verdict.reasons, *(f"{CUT}: {c}" for c in refined.cut))
        )
    out["refined"] = {"model": choice.model.to_dict(), "fit_nrmse": choice.fit_nrmse,
                      "seconds": time.perf_counter() - started, "choice": choice.to_dict(), **refined.to_dict()}  # fmt: skip
    out["verdict"] = verdict.to_dict()
    return out, choice


def _moved(search: Callable[[], SlowSearch | None] | None, by: int) -> Callable[[], SlowSearch | None] | None:
    """A search's start moved ``by`` samples (onto a record that starts elsewhere), when it is asked for."""
    if search is None:
        return None

    def moved() -> SlowSearch | None:
        found = search()
        return None if found is None else dataclasses.replace(found, start=found.start + by)

    return moved


def _on_record(loop: LoopChoice | None, result: SessionResult, record: Record, factor: int) -> LoopChoice | None:
    """The refinement's free run moved onto the record identification sees (decimated, from its first usable
    sample, about its operating point ``mean(u)``), as ``identify(loop=)`` takes it.

    With ``factor > 1`` the refinement ran on every sample, identification on every ``factor``-th:
    its verdict's floor is the slow record's, which the fast fit is not to be judged against
    (the STS3215 twin: fit 0.10, the slow floor 0.13, the fast one 0.019); the fast record's
    floor rule joins the loop's reasons.
    """
    if loop is None:
        return None
    import numpy as np

    from servoid.ident.offline.intervals import MAX_FIT_TO_FLOOR, floor_nrmse

    first = int(np.argmax(result.valid))
    reasons = loop.reasons
    floor = floor_nrmse(result.y[first:], result.valid[first:]) if factor > 1 else float("nan")
    if np.isfinite(floor) and floor > 0.0 and loop.fit_nrmse > MAX_FIT_TO_FLOOR * floor:
        reasons = (*reasons, f"on every sample of the session (the servo-loop model's record), its fit (NRMSE "
                             f"{loop.fit_nrmse:.3g}) is {loop.fit_nrmse / floor:.3g} times the floor {floor:.3g} "
                             f"(at most {MAX_FIT_TO_FLOOR:g}): the model misses something and the play may be absorbing it")  # fmt: skip
    full = np.full(len(result), np.nan)
    full[first:] = loop.simulated
    n = record.u.size
    # the record's sample j is the fast sample (offset + j) * factor, its first usable one at the end
    offset = result.u.size // factor - n if factor > 1 else len(result) - n
    at = (offset + np.arange(n)) * factor
    return dataclasses.replace(loop, simulated=full[at] - float(np.mean(record.u)), reasons=reasons)


#: Why a busy host spoils slots, said where late and missed slots cost a run (servoid.drivers.realtime).
NOT_REALTIME = ("the sampling loop ran without real-time priority, which this user may not take: on a busy host "
                "the scheduler makes slots late or missed; run as root, with CAP_SYS_NICE or an RLIMIT_RTPRIO "
                f"of at least {SAMPLER_PRIORITY}")  # fmt: skip


def check_lost(result: SessionResult, max_lost: float, *, allow: bool, path: Path) -> dict[str, Any]:
    """How many samples a live run could not use; refuse (one line) beyond ``max_lost`` unless ``allow``.

    Parameters
    ----------
    result : SessionResult
        The session.
    max_lost : float
        Largest share of unusable samples (lost, late, timed out, or in a guard window after one).
    allow : bool
        Report anyway (``--allow-lost``).
    path : Path
        The recording, named in the refusal.
    """
    n = len(result)
    usable = int(result.valid.sum())
    counts = result.counts
    not_measured = sum(counts[s] for s in ("missed", "timeout"))
    late = counts["late"]
    guarded = max(n - usable - not_measured - (0 if result.config.use_late else late), 0)
    share = (n - usable) / max(n, 1)
    summary = {"samples": n, "usable": usable, "not_measured": not_measured, "late": late, "guarded": guarded,
               "share_unusable": share, "max_share": max_lost}  # fmt: skip
    if share > max_lost:
        what = (f"{n - usable} of {n} samples ({100 * share:.0f} %) could not be used: {not_measured} lost, "
                f"{late} late, {guarded} in guard windows after them")  # fmt: skip
        if not result.realtime and counts["late"] + counts["missed"]:
            what += f" ({NOT_REALTIME})"
        if not allow:
            raise ConfigError(f"{what}; above --max-lost {max_lost:g}, no model is reported (the recording is in {path}; "
                              "--allow-lost reports one anyway)")  # fmt: skip
        _term.warn(f"{what}: above --max-lost {max_lost:g}, reported because of --allow-lost")
    return summary


def probe_and_design(
    args: argparse.Namespace, driver: Any, amplitude: float, config: Any, *, quiet: bool
) -> tuple[Any, Any]:
    """Run the probe inside ``centre +/- amplitude`` and design the run from it (``--decimate``, ``--hold``,
    ``--amplitude`` override); print both tables unless ``quiet``.
    """
    from servoid.ident.online.probe_design import design_live
    from servoid.identify_outputs import OUTPUT_FILES
    from servoid.session.probe import run_probe

    started = time.perf_counter()
    probe, _ = run_probe(driver, amplitude, config, recording=args.out / OUTPUT_FILES["probe_recording"])
    design = design_live(probe, args.rate, factor=args.decimate, hold=args.hold, amplitude=args.amplitude)
    if not quiet:
        unit = driver.position_unit.unit
        _term.table(f"probe: {driver.describe()} ({probe.samples} samples, {time.perf_counter() - started:.1f} s)",
                    ["", "value"], probe.rows(unit), console=_term.stderr)  # fmt: skip
        _term.table("design", ["", "value"], design.rows(unit), console=_term.stderr)
    return probe, design


def _check_live_options(args: argparse.Namespace) -> None:
    for name in ("decimate", "hold"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise ConfigError(f"--{name} (={value}) must be >= 1")
    check_budget_and_lost(args)
    if args.no_probe and args.hold is not None:
        raise ConfigError(
            "--hold shapes the excitation designed from the probe; with --no-probe use --excitation steps:hold=N"
        )


def budget_s(args: argparse.Namespace, joints: int = 1) -> float:
    """The wall budget in s: ``--budget``, else :data:`WALL_TARGET_S` a servo (a bus session's ``joints``)."""
    given = getattr(args, "budget", None)
    return WALL_TARGET_S * joints if given is None else float(given)


def check_budget_and_lost(args: argparse.Namespace) -> None:
    """``--budget`` and ``--max-lost``, which a bus session takes too (one-line errors, before the servo moves)."""
    budget = budget_s(args)
    if not budget > AFTER_ANSWER_S:  # (NaN too; inf: no budget)
        raise ConfigError(f"--budget (={budget:g}) must be a number of wall seconds > {AFTER_ANSWER_S:g}")
    if not (math.isfinite(args.max_lost) and 0.0 <= args.max_lost <= 1.0):
        raise ConfigError(f"--max-lost (={args.max_lost:g}) must lie in [0, 1]")


def acquisition(result: SessionResult) -> dict[str, Any]:
    """How a live record was sampled, for ``--json`` (:meth:`SessionResult.to_dict`)."""
    return result.to_dict()


def session_rows(result: SessionResult) -> tuple[list[str], list[list[str]]]:
    """The session summary table: one row per quantity."""
    acq = acquisition(result)
    counts = result.counts
    n = max(len(result), 1)
    rows = [["rate", f"{acq['rate_hz']:g} Hz asked, {acq['achieved_rate_hz']:.4g} Hz answered"]]
    for status in ("ok", "late", "missed", "timeout"):
        rows.append([status, f"{counts[status]} ({100.0 * counts[status] / n:.2f} %)"])
    if acq["exchange_median_s"] is not None:
        rows.append(["exchange", f"median {acq['exchange_median_s'] * 1e6:.0f} us, "
                                 f"99 % {acq['exchange_p99_s'] * 1e6:.0f} us"])  # fmt: skip
    rows.append(["frames rejected / stale", f"{acq['frames_rejected']} / {acq['replies_stale']}"])
    if acq["commands_unconfirmed"]:
        rows.append(["commands not confirmed", str(acq["commands_unconfirmed"])])
    rows.append(["commands clamped", str(acq["commands_clamped"])])
    return ["", "value"], rows


def _status_text(p: SessionProgress, unit: str) -> str:
    text = f"late {100 * p.late_share:.1f} %"
    if p.estimate:
        shown = ", ".join(f"{k} {v:.4g}" for k, v in p.estimate.items())
        text += f" | {shown} ({unit})"
    return text


def _num(value: Any) -> float:
    """A number of a verdict's dict for printing (NaN when it is missing)."""
    return float("nan") if value is None else float(value)


def _flat(identity: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in identity.items() if not isinstance(v, dict))
