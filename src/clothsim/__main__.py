"""``python -m clothsim``: the command line (:func:`clothsim.cli.main`).

Until ``main`` installs its own handlers, a Ctrl-C or SIGTERM while the command
line's modules import ends the run with the same one line and exit code
(nothing has been written yet), not with Python's traceback."""

import os
import signal
import sys


def _stopped_early(signum, frame):
    os.write(2, b"clothsim: interrupted\n")
    os._exit(128 + signum)


for _signum in (signal.SIGINT, signal.SIGTERM):
    signal.signal(_signum, _stopped_early)

from .cli import main  # noqa: E402  (after the handlers: this import takes a moment)

signal.signal(signal.SIGINT, signal.default_int_handler)  # main's own handlers take over
signal.signal(signal.SIGTERM, signal.SIG_DFL)
sys.exit(main())
