"""A model wrapping another (a recorder of its answers, a check of its outputs): its name and its calls are the
inner model's, so that the episode's records count the inner model's calls once."""

from __future__ import annotations

from typing import Generic, Protocol, TypeVar

from drivenav.semantics.protocols import ModelCall


class CallingModel(Protocol):
    """What every model has: a name and the calls it made (a reasoner, a scorer)."""

    name: str
    calls: list[ModelCall]


M = TypeVar("M", bound=CallingModel)


class Wrapped(Generic[M]):
    """The model ``inner``, wrapped: its ``name`` and its ``calls`` (read and reset through the wrapper)."""

    def __init__(self, inner: M) -> None:
        self.inner: M = inner
        self.name = inner.name

    @property
    def calls(self) -> list[ModelCall]:
        return self.inner.calls

    @calls.setter
    def calls(self, value: list[ModelCall]) -> None:
        self.inner.calls = value
