"""Driver tests: shared helpers live in the ``*_helpers`` modules and here."""

from __future__ import annotations

import signal


def ctrl_c_reaches_it() -> None:
    """``preexec_fn`` of an emulator a test stops with Ctrl-C: SIGINT as in a terminal's foreground.

    A shell starts a background job with SIGINT ignored and a child inherits that, so a test
    run started in the background (``make test &``) would send its Ctrl-C to an emulator that
    cannot hear it, and wait for it until the timeout.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)
