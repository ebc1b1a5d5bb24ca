"""servoid: identify servo drives with gear backlash while they run on the bench.

The import package has four parts:

``servoid.ident``
    The pseudo-Wiener backlash model, its simulator, the MRGIA online
    estimator, output-error refinement and the metrics.
``servoid.excitation``
    Bounded, persistently exciting input signals.
``servoid.drivers``
    One driver interface for the simulated servo and the serial, CAN and
    Dynamixel servos, with emulators.
the app layer (``servoid.cli``, ``servoid.recording``, ``servoid.plots``, ...)
    The command line, recordings, export formats and plots.

This module imports nothing on purpose: ``import servoid.ident`` must not pull
in the app layer or matplotlib.
"""

__version__ = "0.1.0"
