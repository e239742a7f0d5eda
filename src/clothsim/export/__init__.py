"""Exporters: what a run becomes outside clothsim. One module per format, each
taking a :class:`~clothsim.trajectory.Trajectory` or a single frame."""

from .obj import obj_text, write_obj

__all__ = ["obj_text", "write_obj"]
