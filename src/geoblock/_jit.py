"""Compiled kernels that cost nothing until they are called.

``import numba`` takes 0.13 s, and the first call of any kernel in a process another 0.25 s
(numba builds its typing and lowering registries, and ``numba.np.arraymath`` imports
``scipy.linalg`` to find BLAS), even when the machine code comes from numba's on-disk cache.
:func:`lazy_njit` defers both to the first call of a kernel, so that a module of helpers can be
imported by commands that never call its kernels (``geoblock plugins``, ``geoblock info``,
reading a model).

A kernel made with :func:`lazy_njit` is called like the function it compiles, from Python only:
a kernel called from another compiled kernel must be a plain ``numba.njit`` dispatcher (numba
resolves callees when it compiles the caller). The undecorated function stays available as
:attr:`LazyKernel.py_func`, the pure-Python reference path tests compare the kernel with.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Generic, TypeVar

__all__ = ["LazyKernel", "lazy_njit"]

F = TypeVar("F", bound=Callable[..., Any])


class LazyKernel(Generic[F]):
    """A function compiled with ``numba.njit(**options)`` on its first call.

    Parameters
    ----------
    func : callable
        The kernel's Python source: numba-compilable code.
    options : dict
        ``numba.njit``'s keyword arguments (``cache=True``, ``nogil=True``...).
    """

    def __init__(self, func: F, options: dict[str, Any]) -> None:
        self.py_func: F = func
        self.options = dict(options)
        self._dispatcher: Any = None
        self._lock = threading.Lock()
        self.__name__ = func.__name__
        self.__qualname__ = func.__qualname__
        self.__doc__ = func.__doc__
        self.__module__ = func.__module__
        self.__wrapped__ = func

    @property
    def loaded(self) -> bool:
        """Whether numba has made the dispatcher (the kernel was called or :meth:`load`-ed)."""
        return self._dispatcher is not None

    def load(self) -> Any:
        """The ``numba`` dispatcher (imports numba and makes it the first time)."""
        dispatcher = self._dispatcher
        if dispatcher is None:
            with self._lock:  # two threads calling first make one dispatcher
                if self._dispatcher is None:
                    import numba

                    self._dispatcher = numba.njit(**self.options)(self.py_func)
                dispatcher = self._dispatcher
        return dispatcher

    def __call__(self, *args: Any) -> Any:
        dispatcher = self._dispatcher
        if dispatcher is None:
            dispatcher = self.load()
        return dispatcher(*args)

    def __repr__(self) -> str:
        state = "loaded" if self.loaded else "not loaded"
        return f"<LazyKernel {self.__module__}.{self.__qualname__} ({state})>"


def lazy_njit(**options: Any) -> Callable[[F], LazyKernel[F]]:
    """``numba.njit(**options)``, applied when the kernel is first called.

    Examples
    --------
    >>> @lazy_njit(nogil=True)
    ... def twice(x):
    ...     return 2.0 * x
    >>> twice.loaded
    False
    >>> twice(1.5), twice.loaded
    (3.0, True)
    >>> twice.py_func(1.5)
    3.0
    """

    def decorate(func: F) -> LazyKernel[F]:
        return LazyKernel(func, options)

    return decorate
