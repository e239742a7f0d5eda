"""Running the planned runs: in local worker processes or on a Dask cluster."""

from __future__ import annotations

import io
import multiprocessing
import os
import signal
import threading
import time
import traceback
import warnings
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Any

from .plan import RunSpec


@dataclass
class RunResult:
    spec: RunSpec
    record: dict[str, Any] = field(default_factory=dict)
    """measured values (clothsim.metrics) plus frames and wall time"""
    png: bytes | None = None
    obj: str | None = None
    error: str | None = None


def run_one(spec: RunSpec, stop: str | None = None) -> RunResult:
    """Simulate and render one run headless with its own GL context.

    Never raises for a bad run: the error is returned, so the sweep goes on.
    ``stop``: the name of a Dask ``Event`` (a run on a cluster) looked at
    every :data:`WATCH_S` while it simulates; once it is set, the run ends
    there (its result, an error, goes to nobody): a cluster's worker cannot
    be killed from outside as a local one is, and would otherwise go on with
    a run of a sweep that was stopped.
    """
    from ..errors import ClothsimError, SceneWarning
    from ..export import model_obj_text
    from ..metrics import measure
    from ..scene import apply_overrides, parse_scene
    from ..simulation import Simulation

    start = time.perf_counter()
    result = RunResult(spec)
    try:
        with warnings.catch_warnings():  # what is ignored the sweep said once, before the runs
            warnings.simplefilter("ignore", SceneWarning)
            scene = parse_scene(apply_overrides(spec.scene, spec.overrides, spec.source), spec.source)
        sim = Simulation(scene, threads=1)  # the sweep runs in parallel already
        frames = sim.run(spec.seconds, _stop_check(stop) if stop else None)
        result.record = {**measure(sim), "frames": frames}
        result.obj = model_obj_text(sim.model, sim.positions, sim.normals)
        result.png = _render_png(sim, spec)
    except ClothsimError as exc:
        result.error = str(exc)
    except Exception as exc:  # a worker must report, not die: keep the last line of the trace
        result.error = f"{type(exc).__name__}: {exc} ({traceback.format_exc().strip().splitlines()[-1]})"
    result.record["wall_s"] = round(time.perf_counter() - start, 3)
    return result


def _render_png(sim, spec: RunSpec) -> bytes:
    from PIL import Image

    from ..render.renderer import DrawSettings, Renderer
    from ..render.scene_view import SimulationView, default_camera

    renderer = Renderer(size=spec.size)
    try:
        view = SimulationView(renderer, sim)
        view.sync()
        image = renderer.render(default_camera(sim, fixed=True), DrawSettings(shader=spec.shader))
    finally:
        renderer.release()
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    return buf.getvalue()


def _local(specs: list[RunSpec], workers: int) -> Iterator[RunResult]:
    if workers <= 1:
        for spec in specs:
            yield run_one(spec)
        return
    # spawn: a fresh interpreter per worker, no GL or thread state inherited by fork
    ctx = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=watch_parent,
                               initargs=(os.getpid(),))
    try:
        futures = [pool.submit(run_one, spec) for spec in specs]
        for fut in as_completed(futures):
            yield fut.result()
    except BaseException:  # Ctrl-C, SIGTERM, an error: the workers stop with the sweep
        stop_workers(pool)
        raise
    pool.shutdown(wait=True)


def stop_workers(pool: ProcessPoolExecutor) -> None:
    """End every worker of ``pool`` now: queued runs are dropped, running ones killed."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        if proc.is_alive():
            proc.terminate()
    for proc in processes:
        proc.join(timeout=5)
        if proc.is_alive():
            proc.kill()
            proc.join(timeout=5)


WATCH_S = 0.5
"""how often a worker checks that the sweep that started it still runs [s]"""


def watch_parent(parent: int) -> None:
    """A worker's initializer: a thread that ends the worker once the sweep that
    started it is gone (killed with SIGKILL, where it could not stop its workers).
    And Ctrl-C left to the sweep: a terminal sends it to the whole process group,
    and a worker that took it printed a traceback (an idle one from its queue's
    wait); the sweep stops every worker itself."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(WATCH_S)
        os._exit(1)

    threading.Thread(target=watch, name="clothsim-watch-parent", daemon=True).start()


class SweepStopped(Exception):
    """raised inside a run on a cluster once the sweep that sent it has stopped"""


def _stop_check(name: str) -> Callable[[Any], None]:
    """an ``on_frame`` that raises SweepStopped once the Dask Event ``name`` is set
    (asked at most every WATCH_S: one round trip to the scheduler)"""
    from distributed import Event

    event = Event(name)
    due = [time.monotonic() + WATCH_S]

    def check(sim) -> None:
        now = time.monotonic()
        if now >= due[0]:
            due[0] = now + WATCH_S
            if event.is_set():
                raise SweepStopped("the sweep that sent this run was stopped")

    return check


def _dask(specs: list[RunSpec], scheduler: str) -> Iterator[RunResult]:
    """The runs on the Dask cluster at ``scheduler``. Stopped (Ctrl-C, SIGTERM, an
    error): the queued runs are cancelled and the running ones told to stop
    (an Event each of them watches), so nothing of the sweep goes on on the
    cluster; the cluster and its workers, the user's, are left running."""
    from uuid import uuid4

    from distributed import Client, Event, as_completed as dask_completed

    from ..errors import ClothsimError

    try:
        client = Client(scheduler, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise ClothsimError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({exc})") from None
    futures = []
    stop = None
    try:
        stop = Event(f"clothsim-sweep-stop-{uuid4().hex}", client=client)
        futures = client.map(run_one, specs, pure=False, stop=stop.name)
        for fut in dask_completed(futures):
            yield fut.result()
        stop.clear()  # every run is done: the scheduler forgets the event (a stopped sweep leaves it set)
    except BaseException:
        _stop_on_cluster(client, stop, futures)
        raise
    finally:
        client.close()


def _stop_on_cluster(client, stop, futures) -> None:
    """tell the running runs to stop and cancel the rest; quietly, as the sweep
    is on its way out (a scheduler already gone is no error here)"""
    for action in (lambda: stop is not None and stop.set(), lambda: client.cancel(futures, force=True)):
        try:
            action()
        except BaseException:  # noqa: BLE001 - a second Ctrl-C, a lost scheduler: the sweep stops anyway
            pass


def run_sweep(specs: Iterable[RunSpec], workers: int = 1, scheduler: str | None = None,
              on_result: Callable[[RunResult], None] | None = None) -> list[RunResult]:
    """Run every spec; call ``on_result`` as each finishes; return results in plan order."""
    specs = list(specs)
    source = _dask(specs, scheduler) if scheduler else _local(specs, workers)
    results = []
    try:
        for result in source:
            if on_result is not None:
                on_result(result)
            results.append(result)
    finally:
        source.close()  # stopped in on_result: the workers stop now, not when the generator is collected
    return sorted(results, key=lambda r: r.spec.index)
