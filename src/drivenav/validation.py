"""Typed readers for the fields of user documents (episode files, objects.json, the vocabulary).

One approach for every JSON / YAML document drivenav reads: a :class:`Fields` bound to the document's source
reads each value as the type the schema wants and, when it is not, raises one
:class:`~drivenav.errors.InputError` naming the file, the dotted field path (``episodes[3].goals[0].position``)
and what was expected. Rules beyond a field's type (cross-references, ranges between fields) stay with the
reader of each schema.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivenav.errors import InputError


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class Fields:
    """Readers of one document's fields (``source``: its file, or what the user gave)."""

    source: str | Path

    def error(self, field: str, expected: str, got: object = None) -> InputError:
        return InputError(self.source, field or "<document>", expected, got)

    def mapping(
        self, value: Any, field: str, keys: Collection[str] | None = None, required: Sequence[str] = ()
    ) -> dict[str, Any]:
        """A JSON object; with ``keys``, only those keys; every ``required`` key present."""
        if not isinstance(value, dict):
            raise self.error(field, "a JSON object", value)
        prefix = f"{field}." if field else ""
        unknown = sorted(set(value) - set(keys)) if keys is not None else []
        if unknown:
            raise self.error(prefix + unknown[0], f"only the keys {', '.join(sorted(keys or ()))}", "unknown key")
        missing = [key for key in required if key not in value]
        if missing:
            raise self.error(prefix + missing[0], "a value", "missing")
        return value

    def sequence(self, value: Any, field: str, nonempty: bool = False) -> list[Any]:
        """A JSON array (non-empty if asked)."""
        if not isinstance(value, list) or (nonempty and not value):
            raise self.error(field, "a non-empty JSON array" if nonempty else "a JSON array", value)
        return value

    def text(self, value: Any, field: str) -> str:
        """A non-empty string."""
        if not isinstance(value, str) or not value.strip():
            raise self.error(field, "a non-empty string", value)
        return value

    def texts(self, value: Any, field: str) -> list[str]:
        """A JSON array of non-empty strings."""
        return [self.text(item, f"{field}[{k}]") for k, item in enumerate(self.sequence(value, field))]

    def number(self, value: Any, field: str, minimum: float | None = None) -> float:
        """A finite number (``>= minimum`` if given)."""
        if not _is_number(value):
            raise self.error(field, "a finite number", value)
        if minimum is not None and value < minimum:
            raise self.error(field, f"a number >= {minimum:g}", value)
        return float(value)

    def numbers(self, value: Any, field: str, count: int, expected: str | None = None) -> tuple[float, ...]:
        """A JSON array of ``count`` finite numbers."""
        if not isinstance(value, list) or len(value) != count:
            raise self.error(field, expected or f"a list of {count} finite numbers", value)
        return tuple(self.number(item, f"{field}[{k}]") for k, item in enumerate(value))

    def integer(self, value: Any, field: str, minimum: int | None = None) -> int:
        """An integer (``>= minimum`` if given)."""
        if not isinstance(value, int) or isinstance(value, bool) or (minimum is not None and value < minimum):
            raise self.error(field, "an integer" if minimum is None else f"an integer >= {minimum}", value)
        return value
