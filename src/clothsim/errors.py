"""The two exception types a user of clothsim meets.

Front ends turn both into a one-line message and exit code 2, so every
error carries enough context to be read on its own.
"""

from __future__ import annotations


class ClothsimError(Exception):
    """Base class: anything the command line reports as a one-line error."""


class _Located:
    """A message about a place in a scene: ``source`` names the file, ``key`` the key
    path inside it (``cloth.pinned[2]``) or ``None`` when the whole file is meant;
    its text is ``source: key: message``."""

    def __init__(self, source: str | None, key: str | None, message: str) -> None:
        self.source = source
        self.key = key
        self.message = message
        parts = [p for p in (source, key) if p]
        super().__init__(": ".join(parts + [message]))


class SceneError(_Located, ClothsimError):
    """A scene file (or an override of one) is not a valid scene (see :class:`_Located`)."""


class SceneWarning(_Located, UserWarning):
    """Part of a scene file that is ignored, as the CS184 program ignores it: an
    unknown key inside ``cloth``, ``sphere`` or ``plane``, a pinned point outside
    the grid. ``source``, ``key`` as in :class:`SceneError`; under ``strict`` the
    same item is a :class:`SceneError` instead."""


class SimulationError(ClothsimError):
    """The state blew up (non-finite or flew away); says at which frame and why."""


class RenderError(ClothsimError):
    """A shader did not compile or an image asset could not be read."""


class UsageError(ClothsimError):
    """A command-line value that cannot be used as given."""
