"""Whole-simulation behaviour users expect of the API: parameters, reset, export, threads.

The cloth's physical facts (falling, pins, springs, colliders, self-collision,
reproducibility, the blow-up guard) are in test_physics.py, which checks each
of them on every solver path."""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest

from clothsim import Simulation
from clothsim.interrupts import held_interrupts
from clothsim.model import Model
from clothsim.scene import parse_scene
from clothsim.solver import ClothSolver

from .conftest import SCENES, small_scene


def sim_of(threads=None, **sections) -> Simulation:
    return Simulation(parse_scene(small_scene(**sections)), threads)


def test_params_change_without_rebuild():
    """changing ks between frames changes the motion but keeps the same model object"""
    sim = Simulation.from_file(SCENES / "pinned2.json")
    model = sim.model
    sim.step()
    sim.params.ks = 50
    sim.step()
    assert sim.model is model


def test_reset_restores_start():
    """reset puts every point back where it started and zeroes the clock"""
    sim = Simulation.from_file(SCENES / "pinned2.json")
    sim.run(0.2)
    sim.reset()
    assert np.array_equal(sim.positions, sim.model.rest_positions)
    assert sim.frame == 0 and sim.time == 0.0


def test_obj_export(tmp_path):
    """the OBJ has v, vt, vn for every point in grid order and two faces per cell"""
    sim = sim_of()
    sim.run(0.1)
    path = tmp_path / "cloth.obj"
    sim.export_obj(path)
    lines = path.read_text().splitlines()
    v = np.array([[float(x) for x in l.split()[1:]] for l in lines if l.startswith("v ")])
    assert len(v) == 256 and sum(l.startswith("vt ") for l in lines) == 256
    assert sum(l.startswith("vn ") for l in lines) == 256
    faces = [l for l in lines if l.startswith("f ")]
    assert len(faces) == 2 * 15 * 15
    np.testing.assert_allclose(v, sim.positions, rtol=1e-8)
    assert faces[0].split()[1] == "1/1/1"


def test_threads_choose_the_solver_parts():
    """the simulation wires one solver for its model: a small cloth runs in one part by
    default, and ``threads`` cuts each substep into that many"""
    sim = sim_of()
    assert isinstance(sim.model, Model) and isinstance(sim.solver, ClothSolver)
    assert sim.solver.model is sim.model
    assert sim.solver.parts == 1
    assert sim_of(threads=3).solver.parts == 3


def test_threads_must_be_positive():
    with pytest.raises(ValueError, match="threads"):
        Simulation.from_file(SCENES / "pinned2.json", threads=0)


@pytest.mark.parametrize("seconds", [float("nan"), float("inf"), -float("inf"), -0.5, 1e12, 1e308, "1", None, True])
def test_run_refuses_seconds_that_are_not_a_bounded_count_of_frames(seconds):
    """NaN, inf, a negative time, one of more than RUN_FRAMES_MAX frames (which
    would step for days) or a non-number: ValueError naming seconds, before
    any step; clothsim.record refuses the same"""
    import clothsim

    sim = sim_of()
    with pytest.raises(ValueError, match="seconds"):
        sim.run(seconds)
    with pytest.raises(ValueError, match="seconds"):
        clothsim.record(sim, seconds)
    assert sim.frame == 0 and sim.time == 0.0


def test_run_frames_counts_up_to_the_bound_and_no_further():
    from clothsim.scene_limits import RUN_FRAMES_MAX
    from clothsim.scene_limits import run_frames

    assert run_frames(0.1, 90.0) == 9 and run_frames(0, 90.0) == 0 and run_frames(np.float32(1.0), 60.0) == 60
    assert run_frames(RUN_FRAMES_MAX / 100.0, 100.0) == RUN_FRAMES_MAX
    with pytest.raises(ValueError, match=f"at most {RUN_FRAMES_MAX:,}"):
        run_frames((RUN_FRAMES_MAX + 1) / 100.0, 100.0)


@pytest.mark.parametrize("frames", [-1, 1.5, float("nan"), True, 10_000_001, 10**30])
def test_step_frames_refuses_a_count_that_is_not_a_whole_bounded_one(frames):
    """as step's substeps: ValueError naming frames, and nothing moves"""
    sim = sim_of()
    start = sim.positions.copy()
    with pytest.raises(ValueError, match="frames"):
        sim.step_frames(frames)
    assert sim.frame == 0 and sim.time == 0.0
    np.testing.assert_array_equal(sim.positions, start)
    sim.step_frames(0)
    assert sim.frame == 0
    sim.step_frames(np.int64(2))
    assert sim.frame == 2 and sim.time == pytest.approx(2 * sim.params.simulation_steps * sim.params.dt)


@pytest.mark.parametrize("substeps", [-1, 1.5, float("nan"), True, 100_001, 10**30])
def test_step_refuses_substeps_that_are_not_a_whole_bounded_count(substeps):
    """a negative count ran the clock backwards, a float reached the kernel;
    each is ValueError naming substeps, and nothing moves"""
    sim = sim_of()
    start = sim.positions.copy()
    with pytest.raises(ValueError, match="substeps"):
        sim.step(substeps=substeps)
    assert sim.frame == 0 and sim.time == 0.0
    np.testing.assert_array_equal(sim.positions, start)
    sim.step(substeps=np.int64(2))  # a NumPy whole number is a whole number
    assert sim.time == pytest.approx(2 * sim.params.dt)


def _bits(a):
    return np.ascontiguousarray(a).view(np.int64)


def test_a_ctrl_c_during_a_run_leaves_the_clock_and_the_list_with_the_cloth():
    """Ctrl-C lands while a compiled call runs many frames: KeyboardInterrupt comes
    once the call's frames are counted, so the frame, clock and neighbour list
    match the cloth, and the run goes on from there as an unbroken run of as
    many frames does, to the bit"""
    sim = Simulation.from_file(SCENES / "selfCollision.json")
    sim.step(0)  # the kernels compiled before the timer starts
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.4, os.kill, (os.getpid(), signal.SIGINT))
    try:
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            sim.run(60.0)  # far longer than the timer
    finally:
        timer.cancel()
        timer.join()
        signal.signal(signal.SIGINT, previous)
    assert 0 < sim.frame < 60 * sim.params.frames_per_sec
    sim.step_frames(20)
    unbroken = Simulation.from_file(SCENES / "selfCollision.json")
    unbroken.step_frames(sim.frame)
    assert np.array_equal(_bits(sim.positions), _bits(unbroken.positions))
    assert (sim.time, sim.neighbour_list_rebuilds) == (unbroken.time, unbroken.neighbour_list_rebuilds)


def test_held_interrupts_raise_after_the_block_through_the_handler_there_was():
    """a signal that comes inside the block runs no handler there; it is raised once
    as the block ends, through the handler that was set before it, which is set
    again"""
    seen = []

    def handler(signum, frame):
        seen.append(signum)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with held_interrupts():
                signal.raise_signal(signal.SIGINT)
                signal.raise_signal(signal.SIGINT)
                inside = list(seen)
        assert inside == [] and seen == [signal.SIGINT]
        assert signal.getsignal(signal.SIGINT) is handler
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_first_step_compiles_before_ctrl_c_is_held(monkeypatch):
    """the hold never covers a compile (a Ctrl-C then stops it at once): the step's
    kernels are loaded, and nothing moved, before the hold begins"""
    import clothsim.simulation

    sim = sim_of()
    start = sim.positions.copy()
    warm_at_hold = []
    real = clothsim.simulation.held_interrupts

    def watched():
        warm_at_hold.append(sim.solver.variant(sim.control, sim.params) in sim.solver._warm)
        np.testing.assert_array_equal(sim.positions, start)
        return real()

    monkeypatch.setattr(clothsim.simulation, "held_interrupts", watched)
    assert sim.solver.variant(sim.control, sim.params) not in sim.solver._warm
    sim.step()
    assert warm_at_hold == [True]


def test_a_moving_world_takes_a_bounded_count_of_frames_a_call():
    """each frame of a moving world has a control made in Python before the call: a
    small cloth's calls stop at MOVING_FRAMES_MAX frames, a still world's do not"""
    from clothsim.simulation import MOVING_FRAMES_MAX

    still = sim_of()
    spinning = sim_of(sphere={"origin": [0.5, -0.5, 0.5], "radius": 0.2, "friction": 0.5,
                              "animation": {"keys": [{"t": 0}, {"t": 4, "rotate": [0, 360, 0]}], "loop": True}})
    assert still.holds_still() and still.frames_per_call > MOVING_FRAMES_MAX
    assert not spinning.holds_still() and spinning.frames_per_call == MOVING_FRAMES_MAX
