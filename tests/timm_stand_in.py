"""A test-only stand-in for the four helpers of timm that ``mobile_sam``'s TinyViT imports, where timm is absent.

timm requires torchvision, which the dev venv does not have (its CPU torch has no matching torchvision on the
registries). MobileSAM's TinyViT takes from timm ``DropPath`` (identity in evaluation, and at drop probability 0),
``to_2tuple``, ``trunc_normal_`` (weight initialisation) and ``register_model`` (a registry decorator); the stand-in
gives these, so that the released ``vit_t`` architecture can be built and compared with the package's own builder.
Where timm is installed, it is used instead.
"""

from __future__ import annotations

import importlib.util
import sys
import types
from collections.abc import Callable
from typing import Any

import pytest
import torch


class DropPath(torch.nn.Module):
    """timm's stochastic depth at inference: the identity."""

    def __init__(self, drop_prob: float | None = None) -> None:
        super().__init__()
        self.drop_prob = drop_prob

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x


def to_2tuple(value: Any) -> tuple[Any, Any]:
    return tuple(value) if isinstance(value, (tuple, list)) else (value, value)  # type: ignore[return-value]


def register_model(function: Callable[..., Any]) -> Callable[..., Any]:
    return function


def install(monkeypatch: pytest.MonkeyPatch) -> None:
    """Puts the stand-in in ``sys.modules`` for the test when timm is not installed."""
    if importlib.util.find_spec("timm") is not None:
        return
    layers = types.ModuleType("timm.models.layers")
    layers.DropPath = DropPath  # type: ignore[attr-defined]
    layers.to_2tuple = to_2tuple  # type: ignore[attr-defined]
    layers.trunc_normal_ = torch.nn.init.trunc_normal_  # type: ignore[attr-defined]
    registry = types.ModuleType("timm.models.registry")
    registry.register_model = register_model  # type: ignore[attr-defined]
    models = types.ModuleType("timm.models")
    models.layers, models.registry = layers, registry  # type: ignore[attr-defined]
    timm = types.ModuleType("timm")
    timm.models = models  # type: ignore[attr-defined]
    for name, module in (("timm", timm), ("timm.models", models), ("timm.models.layers", layers)):
        monkeypatch.setitem(sys.modules, name, module)
    monkeypatch.setitem(sys.modules, "timm.models.registry", registry)
