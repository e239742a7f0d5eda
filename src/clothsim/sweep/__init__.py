"""Parameter sweeps: every combination of some scene values, in parallel.

The plan is pure data, a run is a pure function of its spec (returning bytes
and numbers, so it can run in a local process or on a Dask worker alike),
and only the submitting process writes into the output folder.
"""

from .plan import RunSpec, parse_vary, plan_runs
from .runner import RunResult, run_one, run_sweep

__all__ = ["RunResult", "RunSpec", "parse_vary", "plan_runs", "run_one", "run_sweep"]
