"""A plain text table for the benchmarks' output (a helper they import, not a benchmark)."""

from __future__ import annotations

from collections.abc import Sequence


def table(title: str, cols: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    """Print ``rows`` under ``title``, right-aligned, with a rule under the header."""
    widths = [max([len(c), *(len(r[i]) for r in rows)]) for i, c in enumerate(cols)]  # no rows: the header's
    print(f"\n{title}")
    print("  ".join(c.rjust(w) for c, w in zip(cols, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(v.rjust(w) for v, w in zip(r, widths)))
