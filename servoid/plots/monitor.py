"""Figures of a monitoring run: the dead zone, the down-line slope and the fit against time, with bounds and alarms.

:func:`plot_monitor` draws a :class:`~servoid.monitor_history.HistorySnapshot`.
:class:`LivePlot` redraws it in a separate process while the monitor runs,
so that drawing (a tenth of a second or more) never holds up the sampling
loop: the loop only hands over a snapshot, and drops it when the previous
one is still being drawn.
"""

from __future__ import annotations

import math
import os
import pickle
import select
import struct
import subprocess
import sys
from typing import TYPE_CHECKING

import numpy as np

from servoid.monitor_history import HISTORY_COLUMNS, HistorySnapshot
from servoid.plots._base import figure as _figure
from servoid.plots._base import save

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["plot_monitor", "LivePlot"]

_PANELS = (("dead_zone", "dead zone c1 + c2", "true_dead_zone"), ("m2", "down-line slope m2", "true_m2"),
           ("fit", "fit (free-run NRMSE)", None))  # fmt: skip


def plot_monitor(history: HistorySnapshot) -> Figure:
    """Three panels against time: ``c1 + c2`` and ``m2`` with a band of two standard deviations, and the fit.

    Bounds are dashed red lines, alarms shaded from the first check that
    decided them to their clearing; true values (a simulated servo) dashed black.
    """
    fig = _figure(figsize=(8.0, 7.0))
    axes = fig.subplots(3, 1, sharex=True)
    t = history.column("t")
    rows = history.rows
    unit = f" [{history.unit}]" if history.unit and history.unit != "unit" else ""
    for ax, (name, title, true_name) in zip(axes, _PANELS):
        if rows.shape[0]:
            value = history.column(name)
            ax.plot(t, value, color="tab:blue", lw=1.2, label="estimate")
            if f"{name}_std" in HISTORY_COLUMNS:
                std = history.column(f"{name}_std")
                ax.fill_between(
                    t, value - 2 * std, value + 2 * std, color="tab:blue", alpha=0.2, lw=0, label="+/- 2 std"
                )
            if true_name is not None and np.isfinite(history.column(true_name)).any():
                ax.plot(t, history.column(true_name), "k--", lw=1.0, label="true")
        for bound in history.bounds:
            if bound.quantity == name:
                limits = [v for v in (bound.low, bound.high) if math.isfinite(v)]
                for i, limit in enumerate(limits):
                    ax.axhline(limit, color="tab:red", ls="--", lw=1.0, label="bounds" if i == 0 else None)
        spans = [(r, c) for label, r, c in history.alarms if _quantity_of(history, label) == name]
        for i, (raised, cleared) in enumerate(spans if rows.shape[0] else []):
            end = t[-1] if cleared is None else cleared * history.period_s
            ax.axvspan(
                raised * history.period_s, end, color="tab:red", alpha=0.12, lw=0, label="alarm" if i == 0 else None
            )
        ax.set_ylabel(title + (unit if name == "dead_zone" else ""), fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper left", ncol=2)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"servoid monitor: {history.source}", fontsize=10)
    fig.tight_layout()
    return fig


def _quantity_of(history: HistorySnapshot, label: str) -> str:
    return next((b.quantity for b in history.bounds if b.label == label), label)


class LivePlot:
    """Redraw ``path`` from snapshots in a separate process (``python -m servoid.plots.monitor PATH``).

    Parameters
    ----------
    path : path
        The PNG to refresh.

    Notes
    -----
    A plain child process fed through a pipe, not :mod:`multiprocessing`:
    its spawn start re-imports the caller's main module (re-running a
    user's script), and forking a process with threads (rich's refresh
    thread) can deadlock the child. The child says ``ready`` on its stdout
    when it waits for a snapshot; :meth:`submit` only writes then, so it
    never waits for a drawing to finish.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "servoid.plots.monitor", os.fspath(path)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, start_new_session=True,  # Ctrl-C is for the monitor
        )  # fmt: skip
        self._ready = False

    def _is_ready(self) -> bool:
        assert self._proc.stdout is not None
        if not self._ready and self._proc.poll() is None:
            if select.select([self._proc.stdout], [], [], 0.0)[0]:
                self._ready = self._proc.stdout.read(1) == _READY
        return self._ready

    def submit(self, history: HistorySnapshot) -> bool:
        """Hand a snapshot over; False (dropped) while the previous one is still being drawn."""
        if not self._is_ready():
            return False
        self._ready = False
        return self._send(pickle.dumps(history, protocol=pickle.HIGHEST_PROTOCOL))

    def _send(self, payload: bytes) -> bool:
        assert self._proc.stdin is not None
        try:
            self._proc.stdin.write(struct.pack("<Q", len(payload)) + payload)
            self._proc.stdin.flush()
        except (BrokenPipeError, OSError):  # the plotter died; the monitor goes on without it
            return False
        return True

    def close(self, timeout_s: float = 20.0) -> None:
        """Let the drawing in progress finish and stop the process."""
        if self._proc.poll() is None:
            self._send(b"")
            if self._proc.stdin is not None:
                try:
                    self._proc.stdin.close()
                except OSError:
                    pass
            try:
                self._proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        if self._proc.stdout is not None:
            self._proc.stdout.close()


_READY = b"r"


def _draw_forever(path: str) -> None:
    """The plotting process: draw each snapshot from stdin until an empty one (or end of input)."""
    inbox, outbox = sys.stdin.buffer, sys.stdout.buffer
    while True:
        outbox.write(_READY)
        outbox.flush()
        head = inbox.read(8)
        if len(head) < 8:
            return
        size = struct.unpack("<Q", head)[0]
        if size == 0:
            return
        save(plot_monitor(pickle.loads(inbox.read(size))), path)


if __name__ == "__main__":
    _draw_forever(sys.argv[1])
