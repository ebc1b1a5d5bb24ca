"""What every online estimator offers: one sample at a time, a lost sample skipped, the estimate by name.

The sampling session feeds any :class:`Estimator` through one listener
(:class:`servoid.session.listeners.EstimatorFeed`), so the MRGIA, the wear
estimator of ``servoid monitor`` and estimators still to come (one that
decimates, a probe) plug in alike.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol, runtime_checkable

__all__ = ["Estimator"]


@runtime_checkable
class Estimator(Protocol):
    """An online estimator (duck-typed: :class:`~servoid.ident.online.mrgia.MRGIA` and others satisfy it)."""

    def update(self, u: float, y: float) -> object:
        """Process a measured sample ``(u(k), y(k))``; raise :class:`~servoid.errors.EstimatorDiverged` on divergence."""
        ...

    def skip(self, u: float) -> None:
        """Advance over a sample whose measurement was lost or is not to be used, with the command ``u`` the servo had."""
        ...

    def warm_up(self) -> None:
        """Compile whatever is compiled at first use now, on scratch data: a compile inside a sampling loop stalls it."""
        ...

    def current(self) -> Mapping[str, float]:
        """The current estimate by parameter name (``a1.., b0.., m2, c1, c2``), for progress lines."""
        ...
