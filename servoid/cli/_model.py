"""The options of the model and the estimator that identify and diagnose share, with the defaults the Python API has."""

from __future__ import annotations

import argparse

from servoid.ident import defaults
from servoid.ident.paper import PAPER_RHO_EXPONENT

__all__ = ["add_structure_options", "add_rho_option"]


def add_structure_options(group: argparse._ArgumentGroup, *, selectable: bool = False) -> None:
    """``--na``, ``--nb``, ``--delay``, defaulting as ``MRGIAConfig()`` does (:mod:`servoid.ident.defaults`).

    With ``selectable`` they default to None: chosen from the data (``identify(select=...)``).
    """
    if selectable:
        chosen = "default: chosen from the data by BIC, see servoid.ident.offline.structure"
        group.add_argument("--na", type=int, help=f"denominator order n_a >= 1 ({chosen})")
        group.add_argument("--nb", type=int, help=f"numerator order n_b >= 0 ({chosen})")
        group.add_argument("--delay", type=int, help=f"input delay d >= 1 in samples ({chosen})")
        return
    group.add_argument(
        "--na", type=int, default=defaults.NA, help=f"denominator order n_a >= 1 (default {defaults.NA})"
    )
    group.add_argument("--nb", type=int, default=defaults.NB, help=f"numerator order n_b >= 0 (default {defaults.NB})")
    group.add_argument("--delay", type=int, default=defaults.DELAY,
                       help=f"input delay d >= 1 in samples (default {defaults.DELAY})")  # fmt: skip


def add_rho_option(group: argparse._ArgumentGroup) -> None:
    """``--rho-exponent``, defaulting as ``MRGIAConfig()`` does."""
    group.add_argument("--rho-exponent", type=float, default=defaults.RHO_EXPONENT, metavar="R",
                       help=f"r in rho(k) = (k+1)^-r, in (0, 1]; the paper uses {PAPER_RHO_EXPONENT}, larger "
                            f"values average noise better (default {defaults.RHO_EXPONENT})")  # fmt: skip
