"""What every plotting module shares: a new figure that touches no backend, and saving it.

Figures are :class:`matplotlib.figure.Figure` objects made without pyplot, so
drawing one neither picks nor switches matplotlib's backend: a notebook keeps
its inline (or widget) backend, a server or the command line needs no screen,
and nothing is left open in pyplot's list of figures. In a notebook a returned
figure shows as the cell's value; :func:`save` (or ``fig.savefig``) writes it.
"""

from __future__ import annotations

import functools
import io
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["figure", "save"]


@functools.cache
def _figure_class() -> type[Figure]:
    from matplotlib.figure import Figure

    class ShownFigure(Figure):
        """A figure that shows itself as a notebook cell's value.

        IPython draws a matplotlib figure through a formatter that the inline
        backend registers when pyplot is imported; a figure made without
        pyplot would otherwise show as ``<Figure size ...>``. When that
        formatter is registered it still wins (IPython asks it first).
        """

        def _repr_png_(self) -> bytes:
            buffer = io.BytesIO()
            self.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
            return buffer.getvalue()

    return ShownFigure


def figure(**kwargs: Any) -> Figure:
    """A new figure, not managed by pyplot (matplotlib imported on first use); a notebook shows it as PNG.

    Parameters
    ----------
    **kwargs
        Passed to :class:`matplotlib.figure.Figure` (``figsize=(8, 6)``).
    """
    return _figure_class()(**kwargs)


def save(fig: Figure, path: str | os.PathLike[str]) -> Path:
    """Write ``fig`` as PNG (parent folders created) and return the path.

    Parameters
    ----------
    fig : Figure
        The figure.
    path : path-like
        Where to write it.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=110, bbox_inches="tight")
    return p
