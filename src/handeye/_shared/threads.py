"""One BLAS thread for the estimations: their matrices are narrow (6 to a few hundred columns), where a
second BLAS thread waits more than it works, and far more when the other core is busy.

Measured: a laser session of 100 profiles (``handeye calibrate``, 2 cores, the other busy) took 6.3 s
with OpenBLAS's two threads and 2.7 s with one (a 6,000 x 42 least squares: 0.30 s against 0.01 s);
200 views of 12 MP, idle: 2.65 -> 2.42 s. The numbers then do not depend on how many cores the machine
has either.
"""

from __future__ import annotations

import functools
from typing import Callable, TypeVar

from threadpoolctl import ThreadpoolController

F = TypeVar("F", bound=Callable)

_controller: list[ThreadpoolController] = []  # made once (it scans the loaded libraries), on first use


def one_blas_thread():
    """A context in which BLAS runs on one thread (restored on exit)."""
    if not _controller:
        _controller.append(ThreadpoolController())
    return _controller[0].limit(limits=1, user_api="blas")


def on_one_blas_thread(func: F) -> F:
    """``func`` run inside :func:`one_blas_thread`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
