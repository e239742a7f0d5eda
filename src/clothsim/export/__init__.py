"""Exporters: what a run becomes outside clothsim. One module per format, each
taking a :class:`~clothsim.trajectory.Trajectory` or a single frame."""

from .obj import model_obj_text, obj_text, write_model_obj, write_obj

__all__ = ["model_obj_text", "obj_text", "write_model_obj", "write_obj"]
