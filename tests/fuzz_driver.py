"""Runs a batch of fuzzed ``clothsim simulate`` cases in one process and reports each outcome.

Used by ``tests/test_fuzz.py``, which starts one of these per batch so that a
crash (a signal, an abort) kills only the batch and is still seen. Each case
goes through :func:`clothsim.cli.main`, the command's own entry point, with
its stdout and stderr captured.

Usage: ``python fuzz_driver.py CASES.json REPORT.jsonl``. CASES.json is a list
of ``{"scene": TEXT, "sets": [KEY=VALUE, ...]}``; the scene text is written to
``scene_N.json`` beside CASES.json (which holds the ``meshes/`` folder the
standard scenes name). Before a case runs its index is written to stderr
(``case N``), after it one JSON line to REPORT.jsonl: ``{"case", "rc",
"stdout", "stderr", "exception"}``. A case still running after
``CLOTHSIM_FUZZ_CASE_S`` seconds (default 300: a case may compile a variant of the kernels on a cold cache) ends the process with the
stacks of its threads on stderr.
"""

from __future__ import annotations

import contextlib
import faulthandler
import io
import json
import os
import sys
import traceback
from pathlib import Path

SECONDS = "0.02"


def run_case(index: int, case: dict, folder: Path) -> dict:
    from clothsim.cli import main

    scene = folder / f"scene_{index}.json"
    scene.write_text(case["scene"], encoding="utf-8")
    argv = ["simulate", str(scene), "--seconds", SECONDS, "--no-progress", *case.get("options", []),
            *[f"--set={item}" for item in case["sets"]]]
    out, err = io.StringIO(), io.StringIO()
    rc, exception = None, None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as exc:  # argparse's own errors
            rc = exc.code
        except BaseException:  # noqa: BLE001 - every escape is a finding
            exception = traceback.format_exc()
    return {"case": index, "rc": rc, "stdout": out.getvalue(), "stderr": err.getvalue(), "exception": exception}


def main(cases_path: str, report_path: str) -> int:
    folder = Path(cases_path).parent
    cases = json.loads(Path(cases_path).read_text(encoding="utf-8"))
    limit = float(os.environ.get("CLOTHSIM_FUZZ_CASE_S", "300"))
    with open(report_path, "w", encoding="utf-8") as report:
        for index, case in enumerate(cases):
            print(f"case {index}", file=sys.stderr, flush=True)
            faulthandler.dump_traceback_later(limit, exit=True)
            outcome = run_case(index, case, folder)
            faulthandler.cancel_dump_traceback_later()
            report.write(json.dumps(outcome) + "\n")
            report.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
