"""Generate a signal from its spec: pure, seeded and resumable.

:func:`generate` is the one primitive: ``(spec, n, state) -> (values, state)``.
The state is small and immutable (the seed, the index of the next sample and
the last output, which the rate limit needs), so generating a signal in
chunks gives exactly the same samples as generating it at once, and a live
session can stream it. :func:`sample` returns ``n`` samples as an array,
:func:`stream` yields floats one at a time for a session that sends them as
it goes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.excitation import gentle, noise, periodic, prbs
from servoid.excitation.shaping import clip_and_limit
from servoid.excitation.specs import SignalSpec, parse_spec
from servoid.excitation.streams import check_seed

__all__ = ["SignalState", "generate", "sample", "stream"]

#: Target values of each kind: ``(spec, seed, start, count) -> ndarray``.
_TARGETS: dict[str, Callable[..., np.ndarray]] = {
    "uniform": noise.uniform,
    "steps": noise.steps,
    "levels": noise.levels,
    "prbs": prbs.prbs,
    "multisine": periodic.multisine,
    "chirp": periodic.chirp,
    "gentle": gentle.gentle,
}


@dataclass(frozen=True)
class SignalState:
    """Where a signal stands between two chunks.

    Attributes
    ----------
    seed : int
        The seed the signal was started with.
    sample : int
        Index of the next sample to generate (samples generated so far).
    last : float or None
        The last sample generated, unit of ``u``; ``None`` before the first,
        when the rate limit starts from the spec's ``offset``.
    """

    seed: int
    sample: int = 0
    last: float | None = None


def _spec(spec: SignalSpec | str) -> SignalSpec:
    if isinstance(spec, str):
        return parse_spec(spec)
    if not isinstance(spec, SignalSpec):
        raise ConfigError(f"spec must be a SignalSpec or a string like 'prbs:amplitude=1.5', got {spec!r}")
    return spec


def generate(
    spec: SignalSpec | str,
    n: int,
    state: SignalState | None = None,
    *,
    seed: int | None = None,
) -> tuple[np.ndarray, SignalState]:
    """The next ``n`` samples of the signal ``spec``.

    Parameters
    ----------
    spec : SignalSpec or str
        What to generate (a string is read by :func:`~servoid.excitation.specs.parse_spec`).
    n : int
        Number of samples, ``>= 0``.
    state : SignalState, optional
        Where the previous chunk ended; ``None`` starts a new signal.
    seed : int, optional
        Seed of a new signal (default 0). With ``state`` it may be omitted;
        if given it must equal ``state.seed``.

    Returns
    -------
    values : ndarray, shape (n,)
        Inside ``[offset - amplitude, offset + amplitude]``, consecutive
        samples (the first one against ``offset``) at most ``rate`` apart.
    state : SignalState
        Pass it to the next call to continue the signal.

    Raises
    ------
    ConfigError
        For a bad spec, ``n < 0``, a negative seed, or a seed that contradicts ``state``.

    Examples
    --------
    >>> u1, st = generate("prbs:amplitude=1.5,hold=3", 100, seed=4)
    >>> u2, st = generate("prbs:amplitude=1.5,hold=3", 50, st)
    >>> bool(np.array_equal(np.concatenate([u1, u2]), sample("prbs:amplitude=1.5,hold=3", 150, seed=4)))
    True
    """
    sp = _spec(spec)
    count = validation.integer("n", n, minimum=0)
    if state is None:
        state = SignalState(seed=check_seed(0 if seed is None else seed))
    elif not isinstance(state, SignalState):
        raise ConfigError(f"state must be a SignalState from a previous generate() call, got {state!r}")
    elif seed is not None and check_seed(seed) != state.seed:
        raise ConfigError(f"seed (={seed}) differs from the state's seed (={state.seed}); omit seed to continue")
    target = _TARGETS[sp.kind](sp, state.seed, state.sample, count)
    last = sp.offset if state.last is None else state.last
    values, last = clip_and_limit(target, low=sp.low, high=sp.high, rate=sp.rate, last=last)
    return values, replace(state, sample=state.sample + count, last=last if count else state.last)


def sample(spec: SignalSpec | str, n: int, *, seed: int = 0) -> np.ndarray:
    """``n`` samples of ``spec`` from the start, as one array (see :func:`generate`).

    Parameters
    ----------
    spec : SignalSpec or str
        What to generate.
    n : int
        Number of samples.
    seed : int
        Seed of the random stream (same seed, same samples).
    """
    return generate(spec, n, seed=seed)[0]


def stream(spec: SignalSpec | str, *, seed: int = 0, n: int | None = None, chunk: int = 4096) -> Iterator[float]:
    """Yield the samples of ``spec`` one by one, generated ``chunk`` at a time.

    Parameters
    ----------
    spec : SignalSpec or str
        What to generate.
    seed : int
        Seed of the signal.
    n : int, optional
        Stop after ``n`` samples; ``None`` runs for ever (the caller stops).
    chunk : int
        Samples generated per call of :func:`generate`.

    Notes
    -----
    The samples equal :func:`sample`'s for the same spec and seed.
    """
    sp = _spec(spec)
    size = validation.integer("chunk", chunk, minimum=1)
    left = None if n is None else validation.integer("n", n, minimum=0)
    state = SignalState(seed=check_seed(seed))
    while left is None or left > 0:
        take = size if left is None else min(size, left)
        values, state = generate(sp, take, state)
        yield from (float(v) for v in values)
        if left is not None:
            left -= take
