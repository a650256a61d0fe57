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

__all__ = ["interruptible"]


def interruptible(fn):
    """``fn`` with a ``SystemError`` caused by ``KeyboardInterrupt`` re-raised as the
    ``KeyboardInterrupt`` itself."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except SystemError as e:
            if isinstance(e.__cause__, KeyboardInterrupt):
                raise KeyboardInterrupt from None
            raise

    return wrapper
