"""The sampling session: an excitation through a driver at a fixed period; listeners consume the samples.

``samples``    what one slot is (Sample, Status) and the one rule for which samples an estimator may use
``sampler``    the loop: one command per slot, each sample stamped, classified and handed to the listeners
``listeners``  who consumes the samples: the recording, an online estimator (any ``Estimator``), callbacks
"""

from servoid.session.listeners import CallbackListener, EstimatorFeed, RecordingListener, SampleListener
from servoid.session.sampler import SessionConfig, SessionProgress, SessionResult, run_session
from servoid.session.samples import COLUMNS, DEFAULT_GUARD_SAMPLES, Sample, Status, UsableRule, guard_after, usable

__all__ = [
    "Status",
    "Sample",
    "SessionConfig",
    "SessionProgress",
    "SessionResult",
    "run_session",
    "usable",
    "UsableRule",
    "guard_after",
    "DEFAULT_GUARD_SAMPLES",
    "COLUMNS",
    "SampleListener",
    "RecordingListener",
    "EstimatorFeed",
    "CallbackListener",
]
