"""The sampling session: an excitation through a driver at a fixed period; listeners consume the samples.

``sampler``    the loop: one command per slot, each sample stamped and classified, handed to the listeners
"""

from servoid.session.sampler import (
    COLUMNS,
    DEFAULT_GUARD_SAMPLES,
    Sample,
    SessionConfig,
    SessionProgress,
    SessionResult,
    Status,
    UsableRule,
    run_session,
    usable,
)

__all__ = [
    "Status",
    "Sample",
    "SessionConfig",
    "SessionProgress",
    "SessionResult",
    "run_session",
    "usable",
    "UsableRule",
    "DEFAULT_GUARD_SAMPLES",
    "COLUMNS",
]
