"""``--format c``: a C99 header with the parameters and the smoothed backlash inverse (or the reversal lead).

For a model whose play sits inside the position loop (``play_in_loop``, a
servo-loop model) the header is the reversal lead instead
(``templates/reversal_lead.h``: ``servoid_lead_params NAME`` = lead_up,
lead_down, threshold, max_samples, and ``servoid_reversal_lead(&NAME, &state,
r, y) -> u``, mirroring :func:`servoid.ident.control.reversal_lead.lead_step`).

Rendered from the package template ``templates/backlash_compensator.h``: a
``static const servoid_backlash_params NAME`` (m2, c1, c2, band), the linear
block as ``NAME_a`` / ``NAME_b`` / ``NAME_DELAY``, units and standard errors
in comments, and ``static inline`` functions that mirror
:class:`servoid.ident.control.compensate.BacklashInverse` operation for operation.
It compiles cleanly with ``gcc -std=c99 -Wall -Wextra -Werror``, whatever
the model file's strings hold: they go into comments on one line, with no
``*/``, no trigraph (``??/`` would splice lines) and every bidirectional or
control character shown as ``<U+202E>`` (:mod:`servoid.export._text`).
The name (``--name``) must be a C identifier that is no C keyword (C99 to
C23) and none of the header's own names, at most :data:`MAX_NAME` long.
Several headers (one per axis, different ``--name``) can be included
together: the types and functions are guarded once, the parameters per name.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from importlib import resources
from string import Template
from typing import TYPE_CHECKING, Any

from servoid import __version__
from servoid.errors import ConfigError
from servoid.export._text import one_line

if TYPE_CHECKING:  # pragma: no cover
    from servoid.modelfile import ModelFile

__all__ = ["SUMMARY", "OPTIONS", "DEFAULT_NAME", "MAX_NAME", "C_KEYWORDS", "render", "check_name", "header_names"]

SUMMARY = "a C99 header for firmware: static const parameters and an inline backlash inverse"
OPTIONS = ("name", "source_name")
DEFAULT_NAME = "servoid_axis"

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

#: Longest name: the longest name derived from it (``NAME_BACKLASH_PARAMS_H``) stays within the
#: 63 significant characters C99 promises for identifiers and macros.
MAX_NAME = 40

#: Keywords of C99, C11 and C23 (a header compiled as any of them).
C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline int long "
    "register restrict return short signed sizeof static struct switch typedef union unsigned void volatile while "
    "_Bool _Complex _Imaginary _Alignas _Alignof _Atomic _Generic _Noreturn _Static_assert _Thread_local "
    "alignas alignof bool constexpr false nullptr static_assert thread_local true typeof typeof_unqual _BitInt "
    "_Decimal32 _Decimal64 _Decimal128".split()
)


#: The templates: the backlash inverse (output backlash) and the reversal lead (play in the loop).
TEMPLATES = ("backlash_compensator.h", "reversal_lead.h")


def _template_text(template: str = TEMPLATES[0]) -> str:
    return resources.files("servoid.export.templates").joinpath(template).read_text(encoding="utf-8")


def _template(template: str = TEMPLATES[0]) -> Template:
    return Template(_template_text(template))


def header_names() -> frozenset[str]:
    """The identifiers the headers' code uses itself (types, functions, parameters, macros), comments left out."""
    code = re.sub(r"/\*.*?\*/", " ", "\n".join(_template_text(t) for t in TEMPLATES), flags=re.DOTALL)
    code = re.sub(r"\$\{\w+\}\w*", " ", code)  # NAME_a, MACRO_NA: made from the name
    return frozenset(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", code)) - {"ifndef", "define", "endif"}


def check_name(name: str) -> str:
    """``name`` if it can name the parameters in the header, else a :class:`ConfigError` saying why.

    Parameters
    ----------
    name : str
        The C identifier asked for (``--name``).
    """
    if not isinstance(name, str) or not _IDENTIFIER.match(name):
        raise ConfigError(f"name (={name!r}) must be a C identifier: a letter or _, then letters, digits or _")
    if len(name) > MAX_NAME:
        raise ConfigError(f"name (={name!r}) must be at most {MAX_NAME} characters long")
    if name in C_KEYWORDS:
        raise ConfigError(f"name (={name!r}) is a C keyword; choose another, e.g. {name}_axis")
    if name in header_names():
        raise ConfigError(f"name (={name!r}) is a name the header itself uses; choose another, e.g. {name}_axis")
    if name.startswith("__") or (name[0] == "_" and len(name) > 1 and name[1].isupper()):
        raise ConfigError(f"name (={name!r}) is reserved to the C implementation (_X..., __...); choose another")
    return name


def _number(value: float) -> str:
    """A C double literal that reads back as exactly ``value`` (Python's shortest round-trip repr)."""
    text = repr(float(value))
    return text if any(c in text for c in ".eE") else text + ".0"


def _comment(text: Any) -> str:
    """``text`` made safe inside a C block comment: one line, controls shown, no ``*/``, no trigraph."""
    flat = one_line(text)
    return flat.replace("*/", "* /").replace("/*", "/ *").replace("??", "? ?")


def _stderrs(stderr: dict[str, float] | None, names: Iterable[str]) -> str:
    if not stderr:
        return "not known"
    parts = [f"{n} {stderr[n]:.2g}" for n in names if n in stderr and stderr[n] is not None]
    return ", ".join(parts) if parts else "not known"


def render(content: ModelFile, *, name: str = DEFAULT_NAME, source_name: str = "model.json") -> str:
    """The header text.

    Parameters
    ----------
    content : ModelFile
        The model (its smoothing band included).
    name : str
        C identifier of the parameter constant (``NAME``, ``NAME_a``, ...).
    source_name : str
        The model file's name, for the header's first lines.

    Raises
    ------
    ConfigError
        If ``name`` cannot name the parameters (:func:`check_name`).
    """
    check_name(name)
    from servoid.ident.models.structure_names import PLAY_IN_LOOP
    from servoid.loop_compensation import has_loop

    if content.structure == PLAY_IN_LOOP and has_loop(content):
        return _render_lead(content, name, source_name)
    model = content.model
    macro = name.upper()
    names = model.names
    linear_names = [n for n in names if n not in ("m2", "c1", "c2")]
    fields = _common(content, name, source_name, "backlash compensation parameters")
    fields.update({
        "input_unit": _comment(content.input_unit),
        "guard": f"{macro}_BACKLASH_PARAMS_H",
        "m2": _number(model.m2),
        "c1": _number(model.c1),
        "c2": _number(model.c2),
        "band": _number(content.compensation_band),
        "backlash_stderr": _comment(_stderrs(content.stderr, ("m2", "c1", "c2"))),
        "noise_std": _comment(f"{content.noise_std:.3g} {content.output_unit}" if content.noise_std is not None
                              else "not known"),  # fmt: skip
        "linear_stderr": _comment(_stderrs(content.stderr, linear_names)),
        "na": str(model.na),
        "nb": str(model.nb),
        "delay": str(model.delay),
        "a": ", ".join(_number(v) for v in model.a),
        "b": ", ".join(_number(v) for v in model.b),
    })  # fmt: skip
    return _template().substitute(fields)


def _common(content: ModelFile, name: str, source_name: str, what: str) -> dict[str, str]:
    """The fields both templates share: provenance, units, the name and the guard."""
    period = content.sample_period_s
    macro = name.upper()
    return {
        "title": _comment(f"{name}: {what} for one servo axis"),
        "servoid_version": _comment(__version__),
        "model_file": _comment(source_name),
        "identified_at": _comment(content.identified_at or "unknown"),
        "identified_source": _comment(content.source or "unknown"),
        "samples": _comment(content.samples if content.samples is not None else "unknown"),
        "method": _comment(content.method or "unknown"),
        "fit_nrmse": _comment(f"{content.fit_nrmse:.4g}" if content.fit_nrmse is not None else "unknown"),
        "servo": _comment(", ".join(f"{k} {v}" for k, v in content.servo.items()) if content.servo else "not reported"),
        "output_unit": _comment(content.output_unit),
        "sample_period": _comment(f"{period:g} s" if period else "not known"),
        "name": name,
        "macro": macro,
        "sample_period_line": (
            f"#define {macro}_SAMPLE_PERIOD_S {_number(period)} /* seconds */\n" if period
            else "/* sample period not known: the identification record had no time column */\n"
        ),
    }  # fmt: skip


def _render_lead(content: ModelFile, name: str, source_name: str) -> str:
    """The reversal lead's header, for a play inside the loop (a servo-loop model)."""
    from servoid.loop_compensation import loop_model, reversal_lead

    loop = loop_model(content)
    lead = reversal_lead(content)
    fields = _common(content, name, source_name, "reversal lead for a play inside the position loop")
    fields.update({
        "guard": f"{name.upper()}_REVERSAL_LEAD_H",
        "loop": _comment(", ".join(f"{k} {v:.4g}" for k, v in loop.params().items())),
        "lead_up": _number(lead.lead_up),
        "lead_down": _number(lead.lead_down),
        "threshold": _number(lead.threshold),
        "max_samples": _number(float(lead.max_samples)),
    })  # fmt: skip
    return _template("reversal_lead.h").substitute(fields)
