"""A plain text table for the benchmarks' output (a helper they import, not a benchmark)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any


def table(title: str, cols: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    """Print ``rows`` under ``title``, right-aligned, with a rule under the header."""
    widths = [max([len(c), *(len(r[i]) for r in rows)]) for i, c in enumerate(cols)]  # no rows: the header's
    print(f"\n{title}")
    print("  ".join(c.rjust(w) for c, w in zip(cols, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(v.rjust(w) for v, w in zip(r, widths)))


def append_json(path: str | None, row: dict[str, Any]) -> None:
    """Append ``row`` to the file ``path`` as one JSON line (a benchmark's ``--dump``; nothing when ``path`` is None)."""
    if path:
        with open(path, "a") as f:
            f.write(json.dumps(row) + "\n")
