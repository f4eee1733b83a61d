"""Import stand-ins for habitat-sim's compiled modules (``magnum``, ``corrade``, ``habitat_sim``), for tests only.

``import habitat`` (habitat-lab) imports these three at module level, although its ObjectNav path with a custom
simulator uses none of their names at run time. Where a real module is installed, :func:`install` leaves it
alone; otherwise it registers a placeholder package whose every attribute and submodule is a placeholder class
(usable as a base class, in annotations, called, indexed, combined). A placeholder computes nothing: a test that
reached one at run time would fail on its result, never pass by accident.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
import types
from collections.abc import Sequence
from typing import Any

STANDIN_ROOTS = ("magnum", "corrade", "habitat_sim")
STANDIN_ORIGIN = "drivenav test stand-in"


class _PlaceholderMeta(type):
    """Every attribute of a placeholder class is another placeholder class, named by its dotted path."""

    def __getattr__(cls, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return placeholder(f"{cls.__qualname__}.{name}")

    def __getitem__(cls, item: Any) -> Any:
        return cls

    def __or__(cls, other: Any) -> Any:
        return cls

    def __ror__(cls, other: Any) -> Any:
        return cls


class _Placeholder(metaclass=_PlaceholderMeta):
    """An inert value: module-level code may build, call, index and combine it; nothing is computed."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return placeholder(f"{type(self).__qualname__}.{name}")()

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self

    def __getitem__(self, item: Any) -> Any:
        return self

    def __mul__(self, other: Any) -> Any:
        return self

    __rmul__ = __add__ = __radd__ = __sub__ = __rsub__ = __neg__ = __truediv__ = __mul__


def placeholder(qualname: str) -> type:
    cls = _PlaceholderMeta(qualname.rsplit(".", 1)[-1], (_Placeholder,), {})
    cls.__qualname__ = qualname
    return cls


class _StandinModule(types.ModuleType):
    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        value = placeholder(f"{self.__name__}.{name}")
        setattr(self, name, value)
        return value


class _StandinFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def __init__(self, roots: Sequence[str]) -> None:
        self.roots = tuple(roots)

    def find_spec(self, fullname: str, path: Any, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        if fullname.split(".", 1)[0] not in self.roots:
            return None
        return importlib.machinery.ModuleSpec(fullname, self, origin=STANDIN_ORIGIN, is_package=True)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        module = _StandinModule(spec.name)
        module.__path__ = []
        return module

    def exec_module(self, module: types.ModuleType) -> None:
        return None


def install() -> tuple[str, ...]:
    """Register stand-ins for the modules in :data:`STANDIN_ROOTS` that are not installed; returns their names."""
    missing = tuple(name for name in STANDIN_ROOTS if importlib.util.find_spec(name) is None)
    if missing:
        sys.meta_path.append(_StandinFinder(missing))
    return missing
