"""The checks of genplan's configuration dataclasses (``GanConfig``, ``FlowConfig``,
``Seq2SeqConfig``): one helper, so that every config refuses a bad value the same way, a
:class:`~genplan.errors.SettingsError` naming the class and the field, before any work.

A config's ``validate()`` states a rule per field and calls :func:`check_fields`; checks that
relate several fields (a stride dividing a length, one value per axis) stay in ``validate()``::

    check_fields(self, {"n_net": integer(1), "gen_hidden": integer(1, each=True),
                        "lr_gen": number(above=0), "w_target": number(at_least=0),
                        "loss": one_of(self.LOSSES), "threads": optional(integer(1))})
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any

from genplan.errors import SettingsError

__all__ = ["Rule", "check_fields", "integer", "number", "one_of", "optional"]


@dataclass(frozen=True)
class Rule:
    """What one field may hold: ``test`` says whether a value (or, with ``each``, every element
    of a sequence) passes; ``what`` describes it for the message."""

    test: Any
    what: str
    each: bool = False
    none_ok: bool = False

    def holds(self, value: Any) -> bool:
        if value is None:
            return self.none_ok
        if self.each:
            return isinstance(value, (tuple, list)) and all(self.test(v) for v in value)
        return bool(self.test(value))

    def message(self, field: str, value: Any) -> str:
        verb = "hold" if self.each else "be"
        return f"{field} must {verb} {'None or ' if self.none_ok else ''}{self.what}, got {value!r}"


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_real(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def integer(least: int = 0, *, each: bool = False) -> Rule:
    """An integer >= ``least`` (never a bool); ``each``: a sequence of them."""
    name = {1: "positive integer", 0: "non-negative integer"}.get(least, f"integer >= {least}")
    what = (name.replace("integer", "integers") if each else
            f"{'an' if name[0] in 'aeiou' else 'a'} {name}")
    return Rule(lambda v: _is_int(v) and v >= least, what, each)


def number(*, above: float | None = None, at_least: float | None = None, at_most: float | None = None,
           each: bool = False) -> Rule:
    """A finite number (int or float, never a bool), ``> above`` or ``>= at_least`` and
    ``<= at_most`` when given; ``each``: a sequence of them."""
    if at_least is not None and at_most is not None:
        bound = f" in [{at_least:g}, {at_most:g}]"
    else:
        bound = "".join(f" {op} {x:g}" for op, x in ((">", above), (">=", at_least), ("<=", at_most)) if x is not None)

    def test(v: Any) -> bool:
        return (_is_real(v) and (above is None or v > above) and (at_least is None or v >= at_least)
                and (at_most is None or v <= at_most))

    return Rule(test, f"finite numbers{bound}" if each else f"a finite number{bound}", each)


def one_of(values: Collection[Any]) -> Rule:
    """One of ``values``."""
    allowed = list(values)
    return Rule(lambda v: v in allowed, f"one of {allowed}")


def optional(rule: Rule) -> Rule:
    """``rule``, or None."""
    return Rule(rule.test, rule.what, rule.each, none_ok=True)


def check_fields(cfg: Any, rules: Mapping[str, Rule]) -> None:
    """SettingsError naming the first field of ``cfg`` (in the order of ``rules``) whose value
    breaks its rule, e.g. ``GanConfig.n_net must be a positive integer, got 0``."""
    kind = type(cfg).__name__
    for name, rule in rules.items():
        value = getattr(cfg, name)
        if not rule.holds(value):
            raise SettingsError(rule.message(f"{kind}.{name}", value))
