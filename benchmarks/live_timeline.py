"""Where a live identify's wall time goes: a time line of its stages on the real clock, one run.

Run: ``.venv/bin/python benchmarks/live_timeline.py --preset cia402 --transport "cia402 (udp)" [--seed 0]``.

``servoid identify --driver URL --json`` with nothing else (as ``benchmarks/online.py`` runs it), its stages
wrapped to log when they start and end, in wall seconds from the command's start, on which thread, with the
thread's CPU seconds over the stage (a fit's pool helpers not counted) and the machine's load: the probe, the
session (the run), the slow phase's end (the slow phase's held search has its samples), the answer's head search,
each window refit (searched or warm), the slow phase's search, the answer (``refine_online``'s searches, refits
and horn stage) and identification. The stages are wrapped, not changed: the answer is the command's own.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import json
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from twins import LIVE  # benchmarks/, on the path when a benchmark runs as a script

from servoid.cli import _live
from servoid.cli import main as servoid_main
from servoid.ident.online import early_search, refinement, window

_T0 = [0.0]
_LINES: list[tuple[float, str, str]] = []
_LOCK = threading.Lock()


def _log(what: str) -> None:
    now = time.perf_counter() - _T0[0]
    with _LOCK:
        nice = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
        _LINES.append(
            (
                now,
                threading.current_thread().name,
                f"{what} (load {os.getloadavg()[0]:.1f}, process cpu {time.process_time():.1f} s, nice {nice})",
            )
        )


def _wrap(owner: Any, name: str, label: Callable[..., str]) -> None:
    """``owner.name`` logged at its start and end (``label(*args, **kwargs)`` says which), the thread's CPU s."""
    inner = getattr(owner, name)

    @functools.wraps(inner)
    def traced(*args: Any, **kwargs: Any) -> Any:
        what = label(*args, **kwargs)
        cpu = time.thread_time()
        _log(f"start {what}")
        try:
            out = inner(*args, **kwargs)
        except BaseException as exc:
            _log(f"end   {what}: {type(exc).__name__} {str(exc)[:60]} [cpu {time.thread_time() - cpu:.1f} s]")
            raise
        _log(f"end   {what} [cpu {time.thread_time() - cpu:.1f} s]")
        return out

    setattr(owner, name, traced)


def _n(a: Any) -> str:
    return f"{getattr(a, 'size', '?')} samples"


def install() -> None:
    """Wrap the stages (module text)."""
    _wrap(_live, "probe_and_design", lambda *a, **k: "probe")
    import servoid.session as session

    _wrap(session, "run_session", lambda *a, **k: f"session ({len(a[1])} samples)")
    es = early_search.EarlySearch
    _wrap(es, "_start", lambda self: f"{'slow phase' if not self._skip else 'head'}: samples all come ({self.at})")
    _wrap(es, "begin", lambda self: f"begin {'slow' if not self._skip else 'head'} search")
    _wrap(es, "_search", lambda self, u, *a: f"{'SLOW' if not self._skip else 'HEAD'} search on {_n(u)}")
    _wrap(es, "result", lambda self, **k: f"wait {'slow' if not self._skip else 'head'} search {k}")
    _wrap(
        window,
        "_refit",
        lambda u, y, keep, start, config, t_s, *a: (
            f"window {t_s:.1f} s ({'search' if start is None else 'warm'}, {_n(u)})"
        ),
    )
    _wrap(window, "_refit_later", lambda u, y, *a: f"window {a[4]:.1f} s (later, {_n(u)}, look={a[7]})")
    _wrap(window.WindowRefit, "result", lambda self, **k: "last window")
    _wrap(_live, "loop_online", lambda *a, **k: "the answer (loop_online)")
    _wrap(refinement, "fit_loop", lambda u, *a, **k: f"answer fit_loop on {_n(u)} load={k.get('load')}")
    _wrap(refinement, "refit_loop", lambda u, *a, **k: f"answer refit_loop on {_n(u)}")
    _wrap(refinement, "_horn_on_whole", lambda *a, **k: "answer horn stage")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="cia402")
    parser.add_argument("--transport", default="cia402 (udp)", choices=list(LIVE))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None, help="also write identify's JSON here")
    parser.add_argument("--niceness", type=int, default=None, help="the worker threads' WORKER_NICENESS (a trial)")
    args = parser.parse_args()
    if args.niceness is not None:
        window.WORKER_NICENESS = args.niceness
    install()
    print(f"start {time.strftime('%H:%M:%S', time.gmtime())} load {os.getloadavg()}", file=sys.stderr)
    with tempfile.TemporaryDirectory() as tmp, LIVE[args.transport](args.preset) as url:
        argv = ["identify", "--json", "--driver", url, "--out", tmp, "--no-plots", "--seed", str(args.seed)]
        out, err = io.StringIO(), io.StringIO()
        _T0[0] = time.perf_counter()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = servoid_main(argv)
        wall = time.perf_counter() - _T0[0]
    for t, thread, what in sorted(_LINES):
        print(f"{t:7.2f}  {thread[:22]:22}  {what}")
    print(f"wall {wall:.1f} s, exit {code}, load {os.getloadavg()}")
    if code != 0:
        print(err.getvalue().strip().splitlines()[-1])
        return
    result = json.loads(out.getvalue())
    if args.json is not None:
        args.json.write_text(json.dumps(result))
    a = result["answer"]
    print(f"answer {a['source']} {a['play']:.5g} ({result['identifiable']=}); cut {result['budget'].get('cut')}")
    print(f"stages {result['wall_s']}")
    print(f"slow_samples {result['slow_samples']}, lost {result['lost']['share_unusable']:.2f}")


if __name__ == "__main__":
    main()
