"""Ctrl-C during a numba call reaches the caller as ``KeyboardInterrupt``.

A SIGINT that arrives while compiled code runs is only noted by Python's signal handler.
When a numba function returns a freshly allocated array, boxing it runs Python code, where
the pending interrupt is raised and then swallowed by the dispatcher, which reports
``SystemError: CPUDispatcher(...) returned a result with an exception set`` (its
``__cause__`` is the ``KeyboardInterrupt``). The long per-step kernels therefore return no
arrays (:mod:`mjsound.sim.step`); the render path, which takes its events as arrays, is
wrapped with :func:`interruptible`.
"""

from __future__ import annotations

import functools
import signal

__all__ = ["interruptible", "interrupt_in_chain", "caused_by_interrupt"]


def interruptible(fn):
    """``fn`` with a ``SystemError`` caused by ``KeyboardInterrupt`` re-raised as the
    ``KeyboardInterrupt`` itself."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except SystemError as e:
            if caused_by_interrupt(e):
                raise KeyboardInterrupt from None
            raise

    return wrapper


def interrupt_in_chain(exc: BaseException | None):
    """The ``KeyboardInterrupt`` (or SIGTERM's ``SystemExit(143)``) anywhere in ``exc``'s
    cause/context chain, or None.

    The interrupt may sit several ``SystemError`` deep: when boxing a returned array runs
    numba's ``_numba_unpickle`` more than once, each call wraps the previous failure."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt) or (isinstance(exc, SystemExit) and exc.code == 128 + signal.SIGTERM):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a ``KeyboardInterrupt`` lies anywhere in ``exc``'s cause/context chain."""
    return isinstance(interrupt_in_chain(exc), KeyboardInterrupt)
