"""numpy's BLAS on one thread while an engine that also runs torch cleans a take.

On this 2-core machine OpenBLAS's worker threads spin for a while after every
threaded numpy call, and torch's OpenMP threads then find one core taken: the
network runs up to 1.6 times slower. The numpy work of these engines is small
matrices (3x3 rotations, a few hundred frames of channels), which gain nothing from
a second thread. Test split, ``block:120``, frames per second on one core for BLAS
(both for torch) against two for each: cae 11.6k against 7.5-9.4k, holden 9.8k
against 8.2-8.6k, ebf 13.2-14.1k against 11.8-13.3k. Engines on numpy alone keep
both threads: mssa's large products run 1.4 times slower on one.
"""

from __future__ import annotations

import functools
from typing import Callable, TypeVar

from threadpoolctl import ThreadpoolController

__all__ = ["one_blas_thread"]

Method = TypeVar("Method", bound=Callable)


@functools.cache
def _controller() -> ThreadpoolController:
    """The process's thread pools, found once (a few ms) when first needed."""
    return ThreadpoolController()


def one_blas_thread(method: Method) -> Method:
    """Decorator: run ``method`` with numpy's BLAS limited to one thread, restored after.

    The limit costs about 13 us a call; the process's thread pools are found once, when
    first needed (a few ms).

    Parameters
    ----------
    method : callable
        A function or method, e.g. an engine's ``clean``.

    Returns
    -------
    callable
        A wrapper with the same signature, name and docstring
        (``functools.wraps``) that returns what ``method`` returns.
    """

    @functools.wraps(method)
    def limited(*args, **kwargs):
        with _controller().limit(limits=1, user_api="blas"):
            return method(*args, **kwargs)

    return limited  # type: ignore[return-value]
