"""Ctrl-C held back while a step's results are put in place.

A compiled step moves the cloth in place, many frames in one call, with the
GIL released. A Ctrl-C that comes during the call makes Python raise
KeyboardInterrupt the moment the call returns, before the step's results are
stored: the cloth would have moved some frames while the simulation's clock,
frame count and neighbour list stayed where they were, and the next step
would read that list against the moved cloth. :func:`held_interrupts` holds
the signal back over the call and the bookkeeping after it, and raises it
right after, through whatever handler was there (Python's KeyboardInterrupt,
or the command line's own, :mod:`clothsim.cli.stopping`).

The hold must not cover a compile: a first step compiles its kernels for
seconds to minutes, and a Ctrl-C then must stop it at once. The solver loads
its kernels before the hold (:meth:`~clothsim.solver.ClothSolver.load`).
"""

from __future__ import annotations

import contextlib
import signal
import threading

HELD = (signal.SIGINT, signal.SIGTERM)
"""the signals held back; only those with a handler in Python are (a signal
left to the system's default ends the process at once, as it should)"""


@contextlib.contextmanager
def held_interrupts():
    """Signals of :data:`HELD` that come during the block are raised when it ends,
    each once, through the handler each had before it (in the main thread only:
    elsewhere Python runs no signal handler)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = {}
    for signum in HELD:
        handler = signal.getsignal(signum)
        if callable(handler):
            previous[signum] = handler
            signal.signal(signum, lambda number, frame: caught.append(number))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum in dict.fromkeys(caught):
            signal.raise_signal(signum)  # its handler runs before this returns
