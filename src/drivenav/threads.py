"""One BLAS thread per process.

drivenav's numeric work is single-threaded by design (one core per worker); BLAS thread pools spinning on the
small matrix products of the embedded language model cost far more than they give. The variables must be set
before numpy loads: the command line and the tests do it first thing, and Ray workers get them in their
environment.
"""

from __future__ import annotations

import os

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def single_thread_env() -> dict[str, str]:
    """The variables, each set to one thread."""
    return dict.fromkeys(BLAS_THREAD_VARIABLES, "1")


def limit_blas_threads() -> None:
    """One thread unless the user chose otherwise (call before numpy is imported)."""
    for name, value in single_thread_env().items():
        os.environ.setdefault(name, value)
