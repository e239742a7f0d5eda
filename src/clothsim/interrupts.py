"""Ctrl-C held back while a step's results are put in place.

A compiled step moves the cloth in place, many frames in one call, with the
GIL released. A Ctrl-C that comes during the call makes Python raise
KeyboardInterrupt the moment the call returns, before the step's results are
stored: the cloth would have moved some frames while the simulation's clock,
frame count and neighbour list stayed where they were, and the next step
would read that list against the moved cloth. :class:`held_interrupts` holds
the signal back over the call and the bookkeeping after it, and raises it
right after, through whatever handler was there (Python's KeyboardInterrupt,
or the command line's own, :mod:`clothsim.cli.stopping`).

Only SIGINT is held: SIGTERM left to the system ends the process at once,
and the command line's handler of it gives up the run's outputs anyway.
Swapping the handler costs a few microseconds a step (two system calls).

The hold must not cover a compile: a first step compiles its kernels for
seconds to minutes, and a Ctrl-C then must stop it at once. The solver loads
its kernels before the hold (:meth:`~clothsim.solver.ClothSolver.load`).
"""

from __future__ import annotations

import signal
import threading


class held_interrupts:
    """``with held_interrupts():`` a SIGINT that comes during the block runs no
    handler there; it is raised once as the block ends, through the handler
    set before it (in the main thread only: elsewhere Python runs no signal
    handler, and nothing is held)."""

    __slots__ = ("active", "caught", "previous")

    def __enter__(self):
        self.caught = False
        self.active = threading.current_thread() is threading.main_thread()
        if self.active:
            self.previous = signal.signal(signal.SIGINT, self._note)
        return self

    def _note(self, signum, frame) -> None:
        self.caught = True

    def __exit__(self, *exc) -> None:
        if not self.active:
            return
        # None: a handler not set from Python, which cannot be set again
        signal.signal(signal.SIGINT, self.previous if self.previous is not None else signal.SIG_DFL)
        if self.caught:
            signal.raise_signal(signal.SIGINT)  # its handler runs before this returns
