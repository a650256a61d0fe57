"""Plausible ranges of rates, steps and durations, and the memory budget, checked before
anything is allocated.

Every check raises ``ValueError`` naming the input (``name``), the value, the range and the
fix, so that a mistyped unit (a duration in milliseconds, a timestamp in nanoseconds, a rate
in kHz) is refused up front instead of allocating terabytes or writing silence.

================================  =============================================================
limit                             value
================================  =============================================================
sample rate                       ``SAMPLE_RATE_RANGE`` = 1 000 .. 768 000 Hz
physics timestep                  ``TIMESTEP_RANGE`` = 1 us .. 1 s
a take (sonify, events, rollout)  ``MAX_DURATION_S`` = 86 400 s (one day)
physics steps of one job          ``MAX_STEPS`` = 10^9 (about 3 h of CPU at 10 us per step)
one in-memory array               :func:`memory_budget_bytes`: ``$MJSOUND_MAX_MEMORY_GB`` GB
                                  (default 8 GB, which leaves room on a 16-24 GB machine; the
                                  same variable caps a modal analysis)
================================  =============================================================

Long takes written to a file are streamed block by block (``mjsound sonify``), so only the
in-memory paths (``render_events``, a gymnasium observation window, ``sonify(keep_audio=True)``)
are bounded by the memory budget.
"""

from __future__ import annotations

import math
import os

__all__ = [
    "SAMPLE_RATE_RANGE", "TIMESTEP_RANGE", "MAX_DURATION_S", "MAX_STEPS",
    "check_sample_rate", "check_timestep", "check_duration", "check_steps", "memory_budget_bytes",
    "check_array_bytes", "finite_number", "max_memory_gb", "MAX_MEMORY_ENV", "DEFAULT_MAX_MEMORY_GB",
]

#: Accepted audio sample rates [Hz] (inclusive).
SAMPLE_RATE_RANGE = (1000, 768000)
#: Accepted physics timesteps [s] (inclusive).
TIMESTEP_RANGE = (1e-6, 1.0)
#: Longest take [s].
MAX_DURATION_S = 86400.0
#: Most physics steps one job may ask for.
MAX_STEPS = 10**9
#: Environment variable of the memory cap [GB = 1e9 bytes] (arrays and modal analyses).
MAX_MEMORY_ENV = "MJSOUND_MAX_MEMORY_GB"
#: Default memory cap [GB]: a 24 GB machine keeps 16 GB for everything else.
DEFAULT_MAX_MEMORY_GB = 8.0
_GB = 1e9


def _show(value) -> str:
    """A value as a user typed it: numbers in ``%g`` form (``1e+09``, ``nan``), others by repr."""
    try:
        return f"{float(value):g}" if not isinstance(value, (str, bool)) else repr(value)
    except (TypeError, ValueError):
        return repr(value)


def finite_number(value, name: str) -> float:
    """``float(value)``, or ``ValueError`` naming ``name`` if it is not a finite number."""
    if isinstance(value, bool):
        raise ValueError(f"{name}={_show(value)} must be a number")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={_show(value)} must be a number") from None
    if not math.isfinite(x):
        raise ValueError(f"{name}={_show(value)} must be a finite number")
    return x


def check_sample_rate(value, name: str = "sample_rate") -> int:
    """An integer sample rate in :data:`SAMPLE_RATE_RANGE` [Hz]."""
    x = finite_number(value, name)
    lo, hi = SAMPLE_RATE_RANGE
    if x != int(x) or not lo <= x <= hi:
        raise ValueError(f"{name}={_show(value)} Hz is not a plausible audio rate: give an integer in {lo}..{hi} Hz "
                         "(e.g. 16000, 44100 or 48000)")
    return int(x)


def check_timestep(value, name: str = "timestep") -> float:
    """A physics timestep in :data:`TIMESTEP_RANGE` [s]."""
    x = finite_number(value, name)
    lo, hi = TIMESTEP_RANGE
    if not lo <= x <= hi:
        raise ValueError(f"{name}={_show(value)} s is outside the plausible {lo:g}..{hi:g} s (MuJoCo scenes use "
                         "about 1e-4..1e-2 s); give seconds")
    return x


def check_duration(value, name: str = "duration", allow_zero: bool = False) -> float:
    """A duration in seconds, > 0 (or >= 0) and at most :data:`MAX_DURATION_S`."""
    x = finite_number(value, name)
    if x < 0 or (x == 0 and not allow_zero):
        raise ValueError(f"{name}={_show(value)} s must be {'>= 0' if allow_zero else '> 0'} seconds")
    if x > MAX_DURATION_S:
        raise ValueError(f"{name}={_show(value)} s is longer than the {MAX_DURATION_S:.0f} s (one day) limit: "
                         "is it in milliseconds or nanoseconds? give seconds")
    return x


def check_steps(n_steps, what: str, fix: str = "shorten the take or use a larger timestep") -> int:
    """At most :data:`MAX_STEPS` physics steps for ``what``."""
    if not n_steps <= MAX_STEPS:
        raise ValueError(f"{what} needs {float(n_steps):.3g} physics steps, more than the {MAX_STEPS:.0e} limit: {fix}")
    return int(n_steps)


def max_memory_gb(value: float | None = None) -> float:
    """The memory cap [GB]: ``value``, else ``$MJSOUND_MAX_MEMORY_GB``, else
    :data:`DEFAULT_MAX_MEMORY_GB`."""
    source = "max_memory_gb"
    if value is None:
        env = os.environ.get(MAX_MEMORY_ENV)
        if env is None or not env.strip():
            return DEFAULT_MAX_MEMORY_GB
        value, source = env, f"${MAX_MEMORY_ENV}"
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{source}={value!r} is not a number of gigabytes") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{source}={value!r} must be a positive number of gigabytes")
    return v


def memory_budget_bytes() -> int:
    """The most bytes one in-memory array may take: :func:`max_memory_gb` in bytes."""
    return int(max_memory_gb() * _GB)


def check_array_bytes(nbytes, what: str, fix: str) -> None:
    """Refuse an allocation of ``nbytes`` bytes over :func:`memory_budget_bytes`, naming ``what``."""
    cap = memory_budget_bytes()
    if not nbytes <= cap:
        raise ValueError(f"{what} would take {float(nbytes) / _GB:.3g} GB of memory, over the "
                         f"{cap / _GB:.3g} GB cap (${MAX_MEMORY_ENV}): {fix}")
