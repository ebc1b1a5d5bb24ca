"""Online identification at real servo rates: probe, design, decimated MRGIA, verdict, on every twin x transport.

Run: ``.venv/bin/python benchmarks/online.py [--full] [--presets xm430 ...] [--transports sim ...] [--samples 12000]
[--seeds 0 1 2] [--keep DIR]``.

The default run is short: every preset on ``sim://`` (4 runs); ``--full`` runs
the grid, every preset x every transport of ``benchmarks/twins.py``.

Each run is ``servoid identify --driver URL --json --samples N`` with nothing
else (the probe, the design from it, the decimated online estimator, the
offline fit on the same slow record, the verdict), at identify's default rate
(200 Hz) against the transports of ``benchmarks/twins.py``. ``--samples``
defaults to identify's own (``DEFAULT_LIVE_S`` of servo time). Printed as they
are, one row per run:

* ``probe s``: wall time of the probe (from the run's own table), ``k``: the
  decimation it chose, ``lost``: the share of unusable samples;
* ``estimator``: which online estimate identify reported (``loop:<place of
  the play>``: the moving-window servo-loop refit; ``mrgia``: the decimated
  MRGIA, when the black box sits at its floor with a white residual);
* ``online`` and ``refined``: that estimate's play and the refined fit's
  (refined from it), at the output; ``err``: the online one against the
  twin's true play;
* ``to 5 %``: servo seconds until the online play stays within 5 % of its
  final value (the window refits' history, which starts after the design's slow
  phase; for the MRGIA replayed from the recording through the same decimated
  stream); ``to answer``: until it stays within 5 % of the reported answer's
  play (issue 15's target; ``never`` when the last refit is not), ``fit on/ref``: free-run
  NRMSE of the online model over that of the refined one on the same record;
* ``refit s/stall ms/dropped/late/age s``: the window refit's median wall time (on its
  worker thread), the longest time one sample's hand-over took on the
  sampling thread, the windows left out because a refit still ran, those not
  started because the last refits' wall time said they could not end before
  the run (real clock), and the servo seconds between the last refit's window
  and the run's end (the estimate's age: a refit running at the end is not
  waited for on a real clock); ``refits (searched)``: the window refits that ended, and how many
  of them searched from scratch (the first window, a changed place, the slow phase's first look, a
  second look);
* ``answer``: the play identify reported (``answer`` in its JSON): ``search`` the offline
  servo-loop search on the whole live record, ``online`` the online window estimate when it
  validated better than that search as one more candidate, ``offline`` identification's own
  fit (the black box); its error against the truth and whether it was called identifiable;
* ``verdict``: the online verdict (``servoid.ident.online.verdict``) and its first reason;
* ``wall s``: the whole command, probe included; ``stages s``: where it went (``wall_s`` in identify's JSON):
  the probe, the run (the session), the last window's refit after it, the wait for the answer's early
  search (``ident/online/early_search.py``), the servo-loop answer (``refine_online``), identification
  (``identify``), each in wall seconds; ``horn stage``: what became of the answer's horn stage
  (``refine_online``'s step 5: answered, not kept, skipped by the wall budget, ...; ``-`` where it does not apply);
  ``cut``: the stages the wall budget stopped (``budget.cut`` in the JSON: ``early`` the head's early search,
  ``slow`` the slow phase's, and the answer's ``search`` / ``candidate`` / ``extend`` / ``slow part`` / ``horn``;
  ``-`` none; a virtual clock is not timed).

``--design NAME=VALUE`` runs every row under another live design (issue 15, hornturns21): ``GENTLE_SHARE``,
``SLOW_SHARE``, ``SLOW_PART`` of ``ident/online/probe_design.py`` or ``DEFAULT_LIVE_S``, ``SLOW_REVERSALS`` of
``servoid/cli/_live.py``, set for the whole process; ``--mid SHARE:PART`` ends the fast part with ``PART`` of the run's
samples of gentle sines at ``SHARE`` of the probe's bandwidth (a middle speed between the slow and the fast phase;
the fast part keeps the rest, cut at its whole segments); ``--mid SHARE:PART:slow`` puts them after the slow phase
instead, counted in it (the fast part's search and windows do not see them; the fast part loses its last samples).

The monitor's tracking of a growing play on the wearing twin is
``benchmarks/monitor_loop.py``. The machine may be shared: wall times depend on its load.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _table import table
from twins import LIVE, outcome  # benchmarks/, on the path when a benchmark runs as a script

from servoid.cli import main as servoid_main
from servoid.cli._live import recording_valid
from servoid.drivers.twin.presets import preset, preset_names
from servoid.ident.online.decimate import decimate_record
from servoid.ident.online.mrgia import MRGIAConfig, run_mrgia
from servoid.recording import read_recording

#: Share of its final value the online play must stay within.
WITHIN = 0.05


def run(url: str, samples: int | None, out: Path, seed: int = 0) -> tuple[dict | None, str, float]:
    argv = ["identify", "--json", "--driver", url, "--out", str(out), "--no-plots", "--seed", str(seed),
            *([] if samples is None else ["--samples", str(samples)])]  # fmt: skip
    stdout, stderr = io.StringIO(), io.StringIO()
    started = time.perf_counter()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = servoid_main(argv)
    wall = time.perf_counter() - started
    if code != 0:
        return None, stderr.getvalue().strip().splitlines()[-1], wall
    return json.loads(stdout.getvalue()), "", wall


def seconds_to_within(out: Path, result: dict) -> float:
    """Servo seconds until the online play stays within WITHIN of its final value (replayed from the recording)."""
    rec = read_recording(out / "recording.csv")
    k = int(result["decimation"]["factor"])
    us, ys, vs, _ = decimate_record(rec.u, np.where(np.isfinite(rec.y), rec.y, 0.0), k, recording_valid(rec))
    mr = result["mrgia"]
    config = MRGIAConfig(na=len(result["model"]["a"]), nb=len(result["model"]["b"]) - 1, delay=result["model"]["delay"],
                         rho_exponent=mr["rho_exponent"], epsilon=mr["epsilon"])  # fmt: skip
    online = run_mrgia(us, ys, config, valid=vs)
    lay = config.theta_layout
    gaps = online.theta_history[:, lay.c1] + online.theta_history[:, lay.c2]
    final = gaps[-1]
    outside = np.flatnonzero(np.abs(gaps - final) > WITHIN * abs(final))
    slow = 0 if outside.size == 0 else int(outside[-1]) + 1
    return slow * k / float(result["acquisition"]["rate_hz"])


def window_seconds_to_within(history: list[dict], target: float | None = None) -> float:
    """Servo seconds until the window refits' play stays within WITHIN of ``target`` (default its final value; from
    the run's history); NaN when the last refit is not within it."""
    if not history:  # no window refit ended before the run did
        return float("nan")
    plays = np.array([r["play"] for r in history])
    t = np.array([r["t_s"] for r in history])
    goal = plays[-1] if target is None else target
    outside = np.flatnonzero(np.abs(plays - goal) > WITHIN * abs(goal))
    if outside.size and outside[-1] == plays.size - 1:
        return float("nan")
    return float(t[0] if outside.size == 0 else t[int(outside[-1]) + 1])


def row(name: str, transport: str, samples: int | None, out: Path, seed: int = 0) -> list[str]:
    params = preset(name)
    play = params.play_rad
    scale = params.gear_ratio if transport.startswith("odrive") and params.loop_encoder == "motor" else 1.0
    with LIVE[transport](name) as url:
        result, error, wall = run(url, samples, out, seed)
    if result is None:
        return [name, transport, f"{play:.5f}", *["-"] * 13, f"{wall:.0f}", "-", "-", "-", outcome(error)]
    verdict = result["online"]
    online_gap = (verdict["online_gap"] or float("nan")) / scale  # null: no window refit ended
    refined_gap = (verdict["refined_gap"] or float("nan")) / scale
    fit_ratio = (verdict["online_nrmse"] or float("nan")) / (verdict["refined_nrmse"] or float("nan"))
    why = "settled" if verdict["settled"] else "not: " + (verdict["reasons"][0][:40] if verdict["reasons"] else "?")
    window = result["online_loop"]["estimate"]
    costs = [r["seconds"] for r in window["history"]]
    if verdict["estimator"] == "window":
        # the window refit starts after the design's slow phase: its times count from there
        slow_s = result.get("slow_samples", 0) / float(result["acquisition"]["rate_hz"])
        to5 = window_seconds_to_within(window["history"]) + slow_s
        to_answer = window_seconds_to_within(window["history"], result["answer"]["play"]) + slow_s
        what = f"loop:{verdict['structure']}"
    else:
        to5, to_answer, what = seconds_to_within(out, result), float("nan"), "mrgia"
    probe = result["probe"]
    answer = result["answer"]
    names = {
        "loop_search": "search",
        "loop_online": "online",
        "loop_online_cut": "online (cut)",
        "offline_fit": "offline",
    }
    said = names.get(answer["source"], answer["source"])
    answer_play = answer["play"] / scale
    age = window.get("age_s")  # null: no refit, or no end given
    return [
        name, transport, f"{play:.5f}", f"{probe['samples'] / probe['rate_hz']:.1f}",
        str(result["decimation"]["factor"]), f"{result['lost']['share_unusable']:.2f}", what, f"{online_gap:.5f}",
        f"{refined_gap:.5f}", f"{(online_gap - play) / play:+.0%}", f"{to5:.1f}",
        "never" if np.isnan(to_answer) else f"{to_answer:.1f}", f"{fit_ratio:.2f}",
        f"{said} {answer_play:.5f} ({(answer_play - play) / play:+.0%}, {_identified(result)})",
        f"{np.median(costs) if costs else float('nan'):.2f}/{1e3 * window['stall_s']:.0f}/{window['dropped']}"
        f"/{window.get('late', 0)}/{float('nan') if age is None else age:.1f}",
        f"{len(costs)} ({sum(bool(r.get('searched')) for r in window['history'])})",
        f"{wall:.0f}", _stages(result), _horn(result), _cut(result), why,
    ]  # fmt: skip


def _stages(result: dict) -> str:
    """The run's wall seconds per stage: probe/run/last window/answer/identify."""
    s = result.get("wall_s", {})
    stages = ("probe", "run", "last_window", "early_search", "loop_answer", "identify")
    return "/".join(f"{s.get(k, float('nan')):.1f}" for k in stages)


def _horn(result: dict) -> str:
    """What became of the answer's horn stage (``refine_online``'s step 5): its first words, ``-`` where it did not apply."""
    said = (result["online_loop"].get("refined") or {}).get("horn")
    return "-" if said is None else re.split(r"[:(]", said, maxsplit=1)[0].strip()[:24]


#: The first words of a stage the wall budget cut (``budget.cut``) and its short name in the table.
_CUT_NAMES = (("the early search", "early"), ("the slow phase", "slow"), ("in the answer: the search", "search"),
              ("in the answer: the online candidate", "candidate"), ("in the answer: the answer's refit", "extend"),
              ("in the answer: the slow part", "slow part"), ("in the answer: the horn", "horn"), ("the answer:", "no answer"))  # fmt: skip


def _cut(result: dict) -> str:
    """The stages the wall budget cut, by short name (``-``: none, or not timed)."""
    cut = (result.get("budget") or {}).get("cut") or []
    return "+".join(next((short for head, short in _CUT_NAMES if c.startswith(head)), c[:12]) for c in cut) or "-"


def _identified(result: dict) -> str:
    """``ident.``, or ``not:`` and the head of the first reason (its words before a colon or a parenthesis)."""
    if result["identifiable"]:
        return "ident."
    first = (result["reasons"] or ["?"])[0]
    return "not: " + re.split(r"[:(]", first, maxsplit=1)[0].strip()[:40]


#: The live design's constants ``--design`` may set, by module.
_DESIGN_KNOBS = {"GENTLE_SHARE": "servoid.ident.online.probe_design", "SLOW_SHARE": "servoid.ident.online.probe_design",
                 "SLOW_PART": "servoid.ident.online.probe_design", "DEFAULT_LIVE_S": "servoid.cli._live",
                 "SLOW_REVERSALS": "servoid.cli._live"}  # fmt: skip


def redesign(settings: list[str], mid: str | None) -> str:
    """Set the live design's constants (``NAME=VALUE``) and a middle phase (``SHARE:PART``) for this process; what
    was set, for the table's title."""
    import importlib

    said = []
    for item in settings:
        name, _, value = item.partition("=")
        if name not in _DESIGN_KNOBS or not value:
            raise SystemExit(f"--design {item!r}: expected NAME=VALUE with NAME one of {', '.join(_DESIGN_KNOBS)}")
        module = importlib.import_module(_DESIGN_KNOBS[name])
        old = getattr(module, name)
        setattr(module, name, type(old)(float(value)))
        said.append(f"{name}={getattr(module, name):g}")
    if mid is not None:
        share, part, *where = mid.split(":")
        _with_mid(float(share), float(part), where == ["slow"])
        said.append(f"mid {float(share):g}x for {float(part):g} of the run{' after the slow phase' if where else ''}")
    return ", ".join(said)


def _with_mid(share: float, part: float, after_slow: bool = False) -> None:
    """Wrap the live run's input (``_live.excitation``): the fast part ends with ``part`` of the run at ``share``."""
    from servoid.cli import _live
    from servoid.excitation import parse_spec, sample
    from servoid.excitation.gentle import whole_segments
    from servoid.ident.online import probe_design

    plain = _live.excitation

    def excitation(args, amplitude, limits, unit, *, designed=None, slow=None):  # type: ignore[no-untyped-def]
        u, first = plain(args, amplitude, limits, unit, designed=designed, slow=slow)
        if designed is None or args.excitation is not None:
            return u, first
        spec = parse_spec(designed)
        accel = float(spec.accel) * (share / probe_design.GENTLE_SHARE) ** 2  # type: ignore[attr-defined]
        mid_spec = parse_spec(f"gentle:amplitude={spec.amplitude!r},accel={accel!r}")
        rest = u.size - first
        fast = whole_segments(spec, args.seed, rest - int(part * u.size))  # type: ignore[arg-type]
        if after_slow:  # after the slow phase, as its second half: only the whole record's fits (step 4's, 5's) see it
            mid = whole_segments(mid_spec, args.seed + 7, int(part * u.size))
            head = limits.centre + sample(mid_spec, mid, seed=args.seed + 7)
            return np.concatenate([u[:first], head, u[first : u.size - mid]]), first + mid
        tail = limits.centre + sample(mid_spec, rest - fast, seed=args.seed + 7)
        return np.concatenate([u[: first + fast], tail]), first

    _live.excitation = excitation


def _seeded(cells: list[str], seed: int) -> list[str]:
    """A row with the seed after the transport."""
    return [*cells[:2], str(seed), *cells[2:]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=list(preset_names()))
    parser.add_argument("--transports", nargs="+", default=None, choices=list(LIVE), help="default: sim (--full: all)")
    parser.add_argument("--full", action="store_true", help="every preset x every transport")
    parser.add_argument(
        "--samples",
        type=int,
        default=None,
        help="samples per run (default: identify's own, DEFAULT_LIVE_S of servo time)",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="identify's --seed, one run each (default 0)")
    parser.add_argument(
        "--keep", type=Path, default=None, help="keep each run's outputs (recording.csv, model.json) here"
    )
    parser.add_argument("--design", nargs="+", default=[], metavar="NAME=VALUE",
                        help=f"the live design's constants for this run: {', '.join(_DESIGN_KNOBS)}")  # fmt: skip
    parser.add_argument("--mid", default=None, metavar="SHARE:PART",
                        help="end the fast part with PART of the run at SHARE of the probe's bandwidth (SHARE:PART:slow: after the slow phase)")  # fmt: skip
    args = parser.parse_args()
    designed = redesign(args.design, args.mid)
    if args.transports is None:
        args.transports = list(LIVE) if args.full else [next(iter(LIVE))]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load (1 min): {load:.2f} on {os.cpu_count()} cores", file=sys.stderr)
    with tempfile.TemporaryDirectory() as tmp:
        where = args.keep if args.keep is not None else Path(tmp)
        rows = [
            _seeded(row(name, transport, args.samples, where / f"{name}-{i}-{seed}", seed), seed)
            for name in args.presets
            for i, transport in enumerate(args.transports)
            for seed in args.seeds
        ]
    table(
        f"servoid identify --driver URL{'' if args.samples is None else f' --samples {args.samples}'} (probe, design, "
        "decimated MRGIA, verdict)" + (f"; design: {designed}" if designed else ""),
        ["preset", "transport", "seed", "true play", "probe s", "k", "lost", "estimator", "online", "refined", "err",
         "to 5 % s", "to answer s", "fit on/ref", "answer (err, verdict)", "refit s/stall ms/dropped/late/age s",
         "refits (searched)", "wall s",
         "stages s (probe/run/last/early/answer/identify)", "horn stage", "cut", "verdict"],
        rows,
    )  # fmt: skip
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load (1 min) at the end: {load:.2f}", file=sys.stderr)


if __name__ == "__main__":
    main()
