"""Who consumes a session's samples: the recording, an online estimator, any callback.

The session produces samples; each listener gets every one, in order, with
the verdict of the one usable-sample rule (:class:`~servoid.session.samples.UsableRule`):
``on_sample(sample, usable)``. A listener runs inside the sampling loop, so it
must be quick; one that decimates (an estimator fed every n-th sample) does so
inside its own ``on_sample``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Protocol, runtime_checkable

import numpy as np

from servoid.errors import EstimatorDiverged
from servoid.ident.online.decimate import DecimatingEstimator
from servoid.ident.online.estimator import Estimator
from servoid.ident.online.mrgia import MRGIA, MRGIAResult
from servoid.recording import RecordingWriter
from servoid.session.samples import Sample

__all__ = ["SampleListener", "RecordingListener", "EstimatorFeed", "CallbackListener"]

log = logging.getLogger("servoid.session")


@runtime_checkable
class SampleListener(Protocol):
    """Something the session hands each sample to."""

    def on_sample(self, sample: Sample, usable: bool) -> None:
        """Take one sample; ``usable`` says whether an estimator may use it."""
        ...


class RecordingListener:
    """Appends each sample to a recording as it arrives (a flushed row: a crash keeps it).

    Parameters
    ----------
    writer : RecordingWriter
        The open recording (columns :data:`~servoid.session.samples.COLUMNS`).
    """

    def __init__(self, writer: RecordingWriter) -> None:
        self.writer = writer
        self._append_line = writer.append_line

    def on_sample(self, sample: Sample, usable: bool) -> None:  # noqa: ARG002 - every sample is recorded
        if type(sample) is Sample:
            self._append_line(sample.line())  # one format per row: this runs at every sample
        else:
            self.writer.append(*sample.row())

    def close(self) -> None:
        """Close the recording."""
        self.writer.close()


class EstimatorFeed:
    """Feeds an online estimator: usable samples update it, the others are skipped with the servo's command.

    A divergence stops the feeding (sampling goes on: the recording is what
    matters, and the offline stage re-estimates); :attr:`error` says why.

    Parameters
    ----------
    estimator : Estimator
        Any online estimator (:class:`~servoid.ident.online.estimator.Estimator`).
    record_every : int, optional
        For an :class:`~servoid.ident.online.mrgia.MRGIA`: keep its theta and
        line coverage every ``record_every`` samples, so that the live run's
        result (:meth:`mrgia_result`) has the history a batch run has.
    """

    def __init__(self, estimator: Estimator, *, record_every: int | None = None) -> None:
        self.estimator: Estimator | None = estimator
        self.error: str | None = None
        self.record_every = record_every if isinstance(estimator, MRGIA) else None
        self._theta: list[np.ndarray] = []
        self._coverage: list[tuple[float, float]] = []
        self._seen = 0

    def on_sample(self, sample: Sample, usable: bool) -> None:
        est = self.estimator
        if est is None:
            return
        if usable:
            try:
                est.update(sample.u, sample.y)
            except EstimatorDiverged as exc:
                self.error = str(exc)
                self.estimator = None
                log.warning("online estimation stopped: %s", exc)
                return
        else:
            est.skip(sample.u)
        if self.record_every is not None:  # counted only for the history: this runs at every sample
            self._seen += 1
            if self._seen % self.record_every == 0:
                assert isinstance(est, MRGIA)
                self._theta.append(est.theta)
                self._coverage.append(est.coverage)

    def current(self) -> Mapping[str, float] | None:
        """The estimate now by name (None once it diverged)."""
        return None if self.estimator is None else self.estimator.current()

    def mrgia_result(self) -> MRGIAResult | None:
        """The live MRGIA's result with the kept history (None for another estimator, or after a divergence).

        A :class:`~servoid.ident.online.decimate.DecimatingEstimator` keeps its
        inner MRGIA's history itself, over the slow stream.
        """
        est = self.estimator
        if isinstance(est, DecimatingEstimator):
            return est.mrgia_result()
        if not isinstance(est, MRGIA) or self.record_every is None:
            return None
        n = est.config.n_params
        theta = np.array(self._theta).reshape(-1, n)
        coverage = np.array(self._coverage, dtype=np.float64).reshape(-1, 2)
        return est.result(theta, coverage, self.record_every)


class CallbackListener:
    """A plain function of the sample as a listener (``on_sample=`` of :func:`~servoid.session.run_session`).

    Parameters
    ----------
    callback : callable
        ``callback(sample)``.
    """

    def __init__(self, callback: Callable[[Sample], None]) -> None:
        self.callback = callback

    def on_sample(self, sample: Sample, usable: bool) -> None:  # noqa: ARG002
        self.callback(sample)
