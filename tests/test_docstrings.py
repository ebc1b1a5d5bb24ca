"""Every argument of the public API is documented (as python-control's test does).

Public means: listed in ``__all__`` of ``servoid.ident``, ``servoid.excitation``
and ``servoid.drivers``. A class's parameters may be documented by any class it
inherits from.
"""

from __future__ import annotations

import importlib
import inspect
import re

import pytest

PACKAGES = ("servoid.ident", "servoid.excitation", "servoid.drivers")


def _public() -> list[tuple[str, object]]:
    out = []
    for package in PACKAGES:
        mod = importlib.import_module(package)
        for name in mod.__all__:
            obj = getattr(mod, name)
            if inspect.isfunction(obj) or inspect.isclass(obj):
                out.append((f"{package}.{name}", obj))
    return out


def _documented(obj: object) -> str:
    if inspect.isclass(obj):
        return "\n".join(inspect.getdoc(c) or "" for c in obj.__mro__ if c is not object)
    return inspect.getdoc(obj) or ""


def _parameters(obj: object) -> list[str]:
    target = obj.__init__ if inspect.isclass(obj) else obj  # type: ignore[misc]
    if inspect.isclass(obj) and "__init__" not in vars(obj) and not hasattr(obj, "__dataclass_fields__"):
        return []
    try:
        sig = inspect.signature(target)
    except (TypeError, ValueError):
        return []
    return [
        p.name
        for p in sig.parameters.values()
        if p.name not in ("self", "cls")
        and not p.name.startswith("_")
        and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
    ]


@pytest.mark.parametrize("qualname, obj", _public(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_argument_is_documented(qualname, obj):
    doc = _documented(obj)
    missing = [p for p in _parameters(obj) if not re.search(rf"(^|[\s,`(]){re.escape(p)}([\s,`:)]|$)", doc, re.M)]
    assert not missing, f"{qualname}: undocumented argument(s) {', '.join(missing)}"
