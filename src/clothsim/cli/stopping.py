"""How a run stops on Ctrl-C (SIGINT) or SIGTERM: one line and the shell's exit code.

While a command runs, both signals have a handler of ours (:func:`handling_stops`)
that raises :class:`Interrupted` or :class:`Terminated` in the main thread, so
that every output being written is removed on the way out and ``main`` prints
``clothsim: interrupted``. Once it has raised, a second Ctrl-C (users press it
again) is let go, so that it does not cut that removal short. Two things make Python's own Ctrl-C unfit for that:

* An exception raised in Python code that C code called through a ``ctypes``
  callback is printed and dropped, and the C code goes on with whatever the
  callback left. llvmlite loads numba's cached machine code through such
  callbacks, and a Ctrl-C that landed in one crashed the process (SIGSEGV).
  The handler leaves the signal pending while llvmlite's code is on the stack
  and looks again :data:`RETRY_S` later.
* The same holds for every place where Python prints an exception as
  "Exception ignored in ..." and goes on: a weakref callback (importlib runs
  one as it drops a module's lock), a ``__del__``, a garbage-collector
  callback. The run went on as if no Ctrl-C had come. While a block runs,
  ``sys.unraisablehook`` takes such a dropped interrupt back, silently, and
  sends the signal again :data:`RETRY_S` later, outside that code.
* A plain ``KeyboardInterrupt`` raised inside code run by ``eval`` of a string
  (numpy and numba do so while they load) marks the interpreter as stopped by
  Ctrl-C, and it then ends by killing itself with SIGINT whatever ``main``
  returned. :class:`Interrupted` is a subclass, which that check passes by.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) during a command."""


class Terminated(BaseException):
    """SIGTERM (a killed job, a closed terminal) during a command."""


EXIT_CODES = {KeyboardInterrupt: 130, Terminated: 143}
"""the shell's codes for a run stopped by SIGINT (Ctrl-C) and by SIGTERM"""

RAISES = {signal.SIGINT: Interrupted, signal.SIGTERM: Terminated}

RETRY_S = 0.05
"""seconds after which a signal left pending inside llvmlite is looked at again"""


def _unsafe_packages() -> tuple[str, ...]:
    """folders of the packages whose Python code C may be running as a callback"""
    module = sys.modules.get("llvmlite")
    if module is None or not getattr(module, "__file__", None):
        return ()
    return (os.path.dirname(module.__file__) + os.sep,)


def _inside(frame, folders: tuple[str, ...]) -> bool:
    while frame is not None:
        if frame.f_code.co_filename.startswith(folders):
            return True
        frame = frame.f_back
    return False


class _Handler:
    """The signal handler of one :func:`handling_stops` block, with the retry it may have pending."""

    def __init__(self):
        self.pending: int | None = None
        self.timers: list[threading.Timer] = []
        self.lock = threading.Lock()
        self.closed = False
        self.stopping = False

    def __call__(self, signum, frame) -> None:
        if self.stopping:  # a second Ctrl-C while the first one's exception cleans up: not in its way
            return
        if self.closed:  # the block is ending: raised after it (see handling_stops), not inside its exit
            self.pending = signum
            return
        folders = _unsafe_packages()
        if folders and _inside(frame, folders):
            self._again(signum)
            return
        self.pending = None
        self.stopping = True
        raise RAISES[signum]()

    def _again(self, signum: int) -> None:
        """the signal left pending and sent again :data:`RETRY_S` from now"""
        self.pending = signum
        timer = threading.Timer(RETRY_S, self._send, (signum,))
        timer.daemon = True
        self.timers.append(timer)
        timer.start()

    def _send(self, signum: int) -> None:
        """the retry: the signal sent again, unless the block has ended"""
        with self.lock:
            if not self.closed:
                os.kill(os.getpid(), signum)

    def dropped(self, unraisable, passed_on) -> None:
        """``sys.unraisablehook``: an interrupt of ours that Python dropped is sent
        again; anything else goes to ``passed_on``, the hook there was before"""
        for signum, kind in RAISES.items():
            if isinstance(unraisable.exc_value, kind):
                self.stopping = False  # it stopped nothing: the signal is sent again
                self._again(signum)
                return
        passed_on(unraisable)

    def close(self) -> None:
        """no retry sent from now on (one in flight is waited for); a signal from now
        on is left pending"""
        self.closed = True
        with self.lock:  # a retry that saw the block open has sent its signal
            pass
        for timer in self.timers:
            timer.cancel()


@contextlib.contextmanager
def handling_stops():
    """SIGINT and SIGTERM raise :class:`Interrupted` and :class:`Terminated` in
    the block (in the main thread only; elsewhere signals cannot be handled).
    A signal still left pending when the block ends raises there; one that
    Python dropped as unraisable is sent again."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    handler = _Handler()
    previous = {signum: signal.getsignal(signum) for signum in RAISES}
    previous_hook = sys.unraisablehook
    for signum in RAISES:
        signal.signal(signum, handler)
    sys.unraisablehook = lambda unraisable: handler.dropped(unraisable, previous_hook)
    try:
        yield
    finally:
        handler.close()
        sys.unraisablehook = previous_hook
        for signum, old in previous.items():
            signal.signal(signum, old)
    if handler.pending is not None:
        raise RAISES[handler.pending]()


def stopped_by(exc: BaseException | None) -> type | None:
    """KeyboardInterrupt or Terminated where ``exc`` is one or was caused by one, else None.

    An interrupt that lands while numba loads or calls compiled code can come
    back as a SystemError whose cause is the interrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        for kind in EXIT_CODES:
            if isinstance(exc, kind):
                return kind
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None
