"""Numba kernels, compiled ahead of time where a matching build exists, else just in time (worker memory).

Every numba function of drivenav is declared with :func:`jit`. A kernel that Python calls names its signatures
(numba's signature strings); a helper that only kernels call names none. Numba's JIT keeps its LLVM compiler in every
process that runs a kernel, cached or not: about 105 MB of each worker (53 MB to import numba, 51 MB more to load
the first cached kernel). ``python -m drivenav.jit`` (run by ``make install``) compiles every kernel for its
signatures into one extension module beside this file (``numba.pycc``), which needs neither numba nor LLVM to run.

Kernel modules register themselves: a module of the package that imports :func:`jit` from here declares kernels
(:func:`kernel_modules` finds them by that import line), so no list of them is kept by hand; the Makefile finds the
same files with ``grep``.

At import, the kernels of a process come from that module when its build key matches -- the kernel sources, the
numba, numpy and Python versions and the machine, so a stale build or another venv's is never used -- and from
numba's JIT otherwise (``DRIVENAV_KERNELS=jit`` forces the JIT). Both compile the same functions with the same
options, so they compute the same numbers. Compiled code trusts its arguments, so every call is checked against the
signatures first: a mismatch is a ``TypeError`` here, as numba's dispatcher would raise, never a misread array.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import platform
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache
from importlib import metadata
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar, cast

import numpy as np

from drivenav.jsonstream import JsonObject

F = TypeVar("F", bound=Callable[..., Any])

COMPILED = "_compiled_kernels"  # the extension module's name, in this package
MODE_VARIABLE = "DRIVENAV_KERNELS"
DECLARATION = "from drivenav.jit import jit"  # the import line that makes a module a kernel module
_PACKAGE = Path(__file__).parent
_INDEX = _PACKAGE / f"{COMPILED}.json"


@dataclass(frozen=True)
class ArgSpec:
    """What one argument of a compiled variant must be: an array (``dtype``, ``ndim``, C-contiguous or any layout)
    or a scalar (``kind`` ``int``, ``float`` or ``bool``)."""

    kind: str
    dtype: str = ""
    ndim: int = 0
    contiguous: bool = False

    def checker(self) -> Callable[[Any], Any]:
        """A function that returns the argument as the compiled code reads it (scalars as Python numbers), or
        raises ``TypeError`` if it does not fit."""
        if self.kind == "array":
            dtype, ndim, contiguous = np.dtype(self.dtype), self.ndim, self.contiguous

            def array(value: Any) -> Any:
                if not (
                    isinstance(value, np.ndarray)
                    and value.dtype == dtype
                    and value.ndim == ndim
                    and value.flags.aligned
                    and (value.flags.c_contiguous or not contiguous)
                ):
                    raise TypeError
                return value

            return array
        return _SCALARS[self.kind]


def _int(value: Any) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError
    return int(value)


def _float(value: Any) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError
    return float(value)


def _bool(value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError
    return bool(value)


_SCALARS: dict[str, Callable[[Any], Any]] = {"int": _int, "float": _float, "bool": _bool}


class Variant:
    """One compiled signature of a kernel: the extension's function and its arguments' checks."""

    def __init__(self, function: Callable[..., Any], args: Sequence[ArgSpec]) -> None:
        self.function = function
        self.checks = tuple(spec.checker() for spec in args)

    def checked(self, args: Sequence[Any]) -> list[Any]:
        """The arguments as the compiled function reads them; ``TypeError`` if they do not fit its signature."""
        if len(args) != len(self.checks):
            raise TypeError
        return [check(a) for check, a in zip(self.checks, args, strict=True)]


class CompiledKernel:
    """A kernel of the ahead-of-time build: calls the first variant whose signature the arguments fit."""

    def __init__(self, name: str, py_func: Callable[..., Any], variants: Sequence[Variant]) -> None:
        self.name = name
        self.py_func = py_func
        self.variants = tuple(variants)

    def __call__(self, *args: Any) -> Any:
        for variant in self.variants:
            try:
                checked = variant.checked(args)
            except TypeError:
                continue
            return variant.function(*checked)
        given = ", ".join(_describe(a) for a in args)
        raise TypeError(f"kernel {self.name} has no compiled signature for ({given}); see drivenav.jit")


def _describe(value: object) -> str:
    if isinstance(value, np.ndarray):
        layout = "C" if value.flags.c_contiguous else "A"
        return f"{value.dtype}[{value.ndim}d, {layout}]"
    return type(value).__name__


@dataclass(frozen=True)
class Declared:
    """A kernel as declared: its name, numba dispatcher (with the declared options) and signatures (what a build
    compiles)."""

    name: str
    dispatcher: Any
    signatures: tuple[str, ...]


DECLARED: dict[str, Declared] = {}  # filled as the kernel modules are imported in JIT mode (the build reads it)


def jit(*signatures: str, inline: bool = False, error_model: str | None = None) -> Callable[[F], F]:
    """Declare a numba function: a kernel that Python calls when ``signatures`` are given, else a helper of
    kernels. Options as ``numba.njit``'s (``cache=True`` always)."""
    options: dict[str, str] = {"inline": "always"} if inline else {}
    if error_model is not None:
        options["error_model"] = error_model

    def declare(function: F) -> F:
        name = f"{function.__module__}.{function.__qualname__}"
        build = compiled_build()
        if build is not None:
            if not signatures:
                return function  # inlined or called by kernels only: inside the build
            variants = [Variant(getattr(build[0], e["export"]), _specs(e["args"])) for e in build[1][name]]
            return cast(F, CompiledKernel(name, function, variants))
        njit: Callable[..., Callable[[F], Any]] = importlib.import_module("numba").njit

        dispatcher = njit(cache=True, **options)(function)
        if signatures:
            DECLARED[name] = Declared(name, dispatcher, signatures)
        return cast(F, dispatcher)

    return declare


def _specs(raw: Sequence[JsonObject]) -> tuple[ArgSpec, ...]:
    return tuple(ArgSpec(**item) for item in raw)


def build_key() -> str:
    """What a build must match: the kernel sources, numba, numpy and Python, the machine and platform."""
    digest = hashlib.sha256()
    for module in ("drivenav.jit", *kernel_modules()):
        digest.update(_source(module).read_bytes())
    for part in (metadata.version("numba"), np.__version__, sys.version, platform.platform(), _cpu()):
        digest.update(part.encode())
    return digest.hexdigest()


@cache
def kernel_modules() -> tuple[str, ...]:
    """The package's modules that declare kernels (they import :func:`jit` from here), sorted: their sources are
    part of the build key and the build imports them."""
    found = []
    for path in sorted(_PACKAGE.rglob("*.py")):
        if path != Path(__file__) and DECLARATION in path.read_text(encoding="utf-8"):
            found.append(".".join(("drivenav", *path.relative_to(_PACKAGE).with_suffix("").parts)))
    return tuple(found)


def _cpu() -> str:
    """The CPU's model and instruction-set flags (Linux), else the processor name: a build for one CPU may use
    instructions that another lacks."""
    info = Path("/proc/cpuinfo")
    if info.is_file():
        lines = info.read_text(encoding="utf-8", errors="replace").splitlines()
        return "\n".join(sorted({line for line in lines if line.startswith(("model name", "flags"))}))
    return platform.processor()


def _source(module: str) -> Path:
    return _PACKAGE.joinpath(*module.split(".")[1:]).with_suffix(".py")


@cache
def compiled_build() -> tuple[ModuleType, dict[str, list[JsonObject]]] | None:
    """The extension module and its index of exports, if built for this key and not overridden; else ``None``."""
    if os.environ.get(MODE_VARIABLE, "").lower() == "jit" or not _INDEX.is_file():
        return None
    index = json.loads(_INDEX.read_text(encoding="utf-8"))
    if index.get("key") != build_key():
        return None
    try:
        module = importlib.import_module(f"{__package__}.{COMPILED}")
    except ImportError:
        return None
    exports: dict[str, list[JsonObject]] = index["kernels"]
    return module, exports


def _arg_spec(numba_type: Any) -> JsonObject:
    """An argument's :class:`ArgSpec` fields from its numba type (build time)."""
    from numba.core import types

    if isinstance(numba_type, types.Array):
        return {"kind": "array", "dtype": str(np.dtype(str(numba_type.dtype))), "ndim": numba_type.ndim,
                "contiguous": numba_type.layout == "C"}  # fmt: skip
    if isinstance(numba_type, types.Boolean):
        return {"kind": "bool"}
    if isinstance(numba_type, types.Integer):
        return {"kind": "int"}
    if isinstance(numba_type, types.Float):
        return {"kind": "float"}
    raise TypeError(f"a kernel argument of type {numba_type} cannot be checked")


def build() -> Path:
    """Compile every declared kernel for its signatures into :data:`COMPILED` beside this module and write its index
    (where :func:`compiled_build` reads them); returns the index's path. Runs the kernel modules under numba's JIT
    (``DRIVENAV_KERNELS=jit``)."""
    os.environ[MODE_VARIABLE] = "jit"
    compiled_build.cache_clear()
    normalize_signature: Any = importlib.import_module("numba.core.sigutils").normalize_signature
    for module in kernel_modules():
        importlib.import_module(module)
    cc: Any = importlib.import_module("numba.pycc").CC(COMPILED)
    cc.output_dir = str(_PACKAGE)
    cc.target_cpu = "host"  # as numba's JIT compiles: this CPU's instructions (part of the build key)
    index: dict[str, list[JsonObject]] = {}
    for n, declared in enumerate(sorted(DECLARED.values(), key=lambda d: d.name)):
        for k, signature in enumerate(declared.signatures):
            export = f"k{n}_{k}_{declared.dispatcher.py_func.__name__.strip('_')}"
            args, _ = normalize_signature(signature)
            cc.export(export, signature)(_trampoline(declared.dispatcher, len(args)))
            index.setdefault(declared.name, []).append({"export": export, "args": [_arg_spec(a) for a in args]})
    cc.compile()
    _INDEX.write_text(json.dumps({"key": build_key(), "kernels": index}, indent=1) + "\n", encoding="utf-8")
    return _INDEX


def _trampoline(dispatcher: Any, arity: int) -> Callable[..., Any]:
    """A plain function of ``arity`` arguments that calls ``dispatcher``: exported in its place, so that the kernel
    is compiled as a callee with its own numba options (``pycc`` exports take none)."""
    names = ", ".join(f"a{i}" for i in range(arity))
    namespace: dict[str, object] = {"kernel": dispatcher}
    exec(f"def call({names}):\n    return kernel({names})\n", namespace)
    return cast(Callable[..., Any], namespace["call"])


def main() -> int:
    import drivenav.jit as registry  # this file runs as __main__: the kernel modules register with drivenav.jit

    path = registry.build()
    print(f"compiled {len(registry.DECLARED)} kernels ahead of time into {COMPILED} ({path.name})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
