"""Reading user documents (episode files, objects.json, the vocabulary, map YAML) and typed readers of their fields.

One approach for every JSON / YAML document drivenav reads: :func:`read_json` / :func:`read_yaml` turn a file into
plain values (an unreadable or malformed file is one :class:`~drivenav.errors.InputError` on the field
``<document>``), and a :class:`Fields` bound to the document's source reads each value as the type the schema
wants and, when it is not, raises one :class:`~drivenav.errors.InputError` naming the file, the dotted field path
(``episodes[3].goals[0].position``) and what was expected. Rules beyond a field's type (cross-references, ranges
between fields) stay with the reader of each schema, and raise through :meth:`Fields.error`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from drivenav.errors import InputError
from drivenav.jsonstream import DOCUMENT, JsonObject, read_document

read_json = read_document
"""The JSON content of a file, plain or gzip-compressed: see :mod:`drivenav.jsonstream` for what is refused."""


class _Yaml12Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 floats: ``1e-6`` is a number (as for yaml-cpp, ROS's parser), not text."""


_Yaml12Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def read_yaml(path: Path) -> Any:
    """The YAML content of a file (safe loading, YAML 1.2 floats); a mapping that holds a key twice is refused
    (:func:`check_unique_keys`)."""
    try:
        text = path.read_text(encoding="utf-8")
        check_unique_keys(text, path)
        return yaml.load(text, Loader=_Yaml12Loader)  # a SafeLoader
    except yaml.YAMLError as exc:
        raise InputError(path, DOCUMENT, "well-formed YAML", yaml_problem(exc)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, DOCUMENT, "a readable UTF-8 text file", str(exc)) from None


def yaml_problem(error: yaml.YAMLError) -> str:
    """What a YAML parser found and where (line and column, from 1)."""
    mark = getattr(error, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{getattr(error, 'problem', None) or type(error).__name__}{where}"


def check_unique_keys(text: str, source: str | Path) -> None:
    """Refuse a YAML text with a mapping that holds a key twice (PyYAML keeps the last value, other readers the
    first or refuse): one :class:`~drivenav.errors.InputError` on the dotted key, at the line of its second copy.
    Malformed YAML raises the parser's :class:`yaml.YAMLError`."""
    node = yaml.compose(text, Loader=_Yaml12Loader)
    found = _repeated_key(node, "", set()) if node is not None else None
    if found is not None:
        key, mark = found
        raise InputError(source, key, "each key once in its mapping", f"the key again at line {mark.line + 1}")


def _repeated_key(node: yaml.Node, prefix: str, walked: set[int]) -> tuple[str, yaml.Mark] | None:
    """The first key (dotted) that a mapping under ``node`` holds twice, and where; each node walked once (aliases
    share theirs)."""
    if id(node) in walked:
        return None
    walked.add(id(node))
    children: list[tuple[str, yaml.Node]] = []
    if isinstance(node, yaml.MappingNode):
        seen: set[tuple[str, str]] = set()
        for key, value in node.value:
            name = f"{prefix}.{key.value}" if prefix else str(key.value)
            if isinstance(key, yaml.ScalarNode) and (key.tag, key.value) in seen:
                return name, key.start_mark
            seen.add((key.tag, str(key.value)))
            children.append((name, value))
    elif isinstance(node, yaml.SequenceNode):
        children = [(f"{prefix}[{k}]", item) for k, item in enumerate(node.value)]
    for name, child in children:
        found = _repeated_key(child, name, walked)
        if found is not None:
            return found
    return None


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _finite_floats(values: list[Any]) -> bool:
    """Whether every value is a float and none is infinite or NaN (their sum is finite; one that overflows sends
    the values down the number-by-number path)."""
    return set(map(type, values)) == {float} and math.isfinite(sum(values))


def _bounds_text(minimum: float | None, maximum: float | None, positive: bool) -> str:
    if positive:
        return "a number > 0"
    if minimum is not None and maximum is not None:
        return f"a number in [{minimum:g}, {maximum:g}]"
    return f"a number >= {minimum:g}" if minimum is not None else f"a number <= {maximum:g}"


@dataclass(frozen=True)
class Fields:
    """Readers of one document's fields (``source``: its file, or what the user gave)."""

    source: str | Path

    def error(self, field: str, expected: str, got: object = None) -> InputError:
        """The error for ``field`` (the whole document if empty)."""
        return InputError(self.source, field or DOCUMENT, expected, got)

    def mapping(
        self, value: Any, field: str, keys: Collection[str] | None = None, required: Sequence[str] = ()
    ) -> JsonObject:
        """A JSON object; with ``keys``, only those keys; every ``required`` key present."""
        if not isinstance(value, dict):
            raise self.error(field, "a JSON object", value)
        prefix = f"{field}." if field else ""
        unknown = sorted(set(value) - set(keys)) if keys is not None else []
        if unknown:
            raise self.error(prefix + unknown[0], f"only the keys {', '.join(sorted(keys or ()))}", "unknown key")
        missing = [key for key in required if key not in value]
        if missing:
            raise self.error(prefix + missing[0], f"the keys {', '.join(required)}", "missing")
        return value

    def sequence(self, value: Any, field: str, min_items: int = 0, expected: str | None = None) -> list[Any]:
        """A JSON array of at least ``min_items`` items."""
        if not isinstance(value, list) or len(value) < min_items:
            default = {0: "a JSON array", 1: "a non-empty JSON array"}.get(
                min_items, f"a JSON array of at least {min_items} items"
            )
            raise self.error(field, expected or default, value)
        return value

    def text(self, value: Any, field: str) -> str:
        """A non-empty string."""
        if not isinstance(value, str) or not value.strip():
            raise self.error(field, "a non-empty string", value)
        return value

    def texts(self, value: Any, field: str) -> list[str]:
        """A JSON array of non-empty strings."""
        return [self.text(item, f"{field}[{k}]") for k, item in enumerate(self.sequence(value, field))]

    def choice(self, value: Any, field: str, options: Sequence[object], expected: str | None = None) -> Any:
        """One of ``options`` (compared with ``==``, so ``1`` also matches ``True``)."""
        if value not in options:
            raise self.error(field, expected or f"one of {', '.join(map(str, options))}", value)
        return value

    def number(
        self,
        value: Any,
        field: str,
        minimum: float | None = None,
        maximum: float | None = None,
        positive: bool = False,
    ) -> float:
        """A finite number, ``> 0`` if ``positive``, within ``[minimum, maximum]`` where given."""
        if not _is_number(value):
            raise self.error(field, "a finite number", value)
        below = (positive and value <= 0) or (minimum is not None and value < minimum)
        if below or (maximum is not None and value > maximum):
            raise self.error(field, _bounds_text(minimum, maximum, positive), value)
        return float(value)

    def numbers(
        self, value: Any, field: str, count: int, expected: str | None = None, positive: bool = False
    ) -> tuple[float, ...]:
        """A JSON array of ``count`` finite numbers (each ``> 0`` if ``positive``)."""
        if not positive and type(value) is list and len(value) == count and _finite_floats(value):
            return tuple(value)  # the common case, read without a call per number (100,000-episode files)
        kind = "positive numbers" if positive else "finite numbers"
        wanted = expected or f"a list of {count} {kind}"
        if not isinstance(value, list) or len(value) != count:
            raise self.error(field, wanted, value)
        numbers = tuple(self.number(item, f"{field}[{k}]") for k, item in enumerate(value))
        if positive and min(numbers, default=1.0) <= 0.0:
            raise self.error(field, wanted, value)
        return numbers

    def integer(self, value: Any, field: str, minimum: int | None = None) -> int:
        """An integer (``>= minimum`` if given)."""
        if not isinstance(value, int) or isinstance(value, bool) or (minimum is not None and value < minimum):
            raise self.error(field, "an integer" if minimum is None else f"an integer >= {minimum}", value)
        return value
