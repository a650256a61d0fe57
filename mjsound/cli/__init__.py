"""The ``mjsound`` command line: the only layer that parses arguments (argparse) and wires
optional parts (rerun recordings) onto the library. Each subcommand has ``--help``.

One module per group of subcommands; each has ``register(subparsers)`` and imports nothing
heavy until its subcommand runs:

=====================  ==========================================================
module                 subcommands
=====================  ==========================================================
:mod:`.analyze`        ``analyze``
:mod:`.sonify`         ``sonify``, ``demo``, ``sonify-batch``
:mod:`.events`         ``render-events``
:mod:`.fit`            ``fit``
:mod:`.report`         ``report accuracy``, ``report stability``
:mod:`.warmup`         ``warmup``
:mod:`.view`           ``view``
=====================  ==========================================================

Errors a user can fix (bad input, a file that cannot be written, a full disk) end with one
line ``mjsound COMMAND: error: ...`` naming the input and exit status 2; Ctrl-C ends with
status 130 and SIGTERM with 143, after every output in progress has been discarded (outputs
are written to temporary files and renamed into place only when complete; a SIGKILL leaves
its temporary file, which the next run writing to that directory removes).
"""

from __future__ import annotations

import argparse
import errno
import signal
import sys
import threading

from . import analyze, events, fit, report, sonify, view, warmup
from ..synth.interrupt import interrupt_in_chain

__all__ = ["main", "build_parser", "error_message"]

_GROUPS = (analyze, sonify, events, fit, report, warmup, view)


def build_parser() -> argparse.ArgumentParser:
    """The full ``mjsound`` argument parser (every subcommand registered)."""
    parser = argparse.ArgumentParser(prog="mjsound", description="Physically based sound for MuJoCo simulations.")
    parser.add_argument("--version", action="version", version="mjsound 0.1.0")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for group in _GROUPS:
        group.register(sub)
    return parser


def error_message(exc: BaseException) -> str | None:
    """The one-line message for an error a user can act on, or None for a bug (traceback)."""
    if isinstance(exc, KeyError):
        return str(exc.args[0]) if exc.args else "missing key"
    if isinstance(exc, (ValueError, ImportError, ConnectionError)):
        return str(exc)
    if isinstance(exc, MemoryError):
        return ("out of memory: the job needs more memory than this machine has; shorten --duration, lower "
                "--sample-rate or --quality, or pass --budget-modes")
    if isinstance(exc, RecursionError):
        return "input nested too deeply (a JSON file or text with thousands of nested levels?)"
    if isinstance(exc, OSError):
        what = f" {exc.filename}" if getattr(exc, "filename", None) else ""
        if exc.errno == errno.ENOSPC:
            return f"no space left on the device{what}: free some space or write elsewhere (-o)"
        if exc.errno == errno.EISDIR:
            return f"{exc.filename or 'the output'} is a directory: give a file name (-o DIR/name.wav)"
        return f"{exc.strerror or exc}{':' + what if what else ''}"
    return None


def main(argv=None) -> int:
    """Run ``mjsound`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return _interrupted(args, 130)
    except SystemExit as exc:
        if exc.code == 128 + signal.SIGTERM:
            return _interrupted(args, exc.code)
        raise
    except Exception as exc:
        cause = interrupt_in_chain(exc)
        if cause is not None:
            # an interrupt that arrived inside a numba call (or other native code) surfaces as another
            # exception (SystemError ...) caused by it: it is still an interrupt
            return _interrupted(args, 130 if isinstance(cause, KeyboardInterrupt) else cause.code)
        msg = error_message(exc)
        if msg is None:
            raise
        print(f"mjsound {args.command}: error: {msg}", file=sys.stderr)
        return 2
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _interrupted(args, code: int) -> int:
    print(f"mjsound {args.command}: interrupted; partial outputs discarded", file=sys.stderr)
    return code


def _terminate(signum, frame):
    """SIGTERM unwinds like Ctrl-C does (temporary files are removed on the way out)."""
    raise SystemExit(128 + signum)
