"""What results show in a notebook: a small HTML table for ``_repr_html_``, its cells escaped."""

from __future__ import annotations

import html
from collections.abc import Sequence

__all__ = ["html_table"]


def html_table(columns: Sequence[str], rows: Sequence[Sequence[str]], *, caption: str = "") -> str:
    """An HTML ``<table>`` of ``rows`` under the header ``columns``, with an optional caption.

    Parameters
    ----------
    columns : sequence of str
        Header cells.
    rows : sequence of sequence of str
        Body cells, row by row.
    caption : str
        Shown above the table.
    """
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
