"""Every bad input and fault of the fault-injection suite, run as a user meets it, as a table.

Each case of ``tests/faults/cases.py`` runs in a fresh folder under a time limit and is
classified: *named error* (exit 2, the expected one-line message), *right result* (a case that
must succeed did, e.g. a Latin-1 OBJ loads), or a failure: *traceback*, *hang* (past the
limit), *silent wrong result* (exit 0 where an error was due, or not the expected outcome),
*data lost* (a workspace file gone or changed), *file outside* (written outside the workspace).

Usage: OMP_NUM_THREADS=1 PYTHONPATH=src:. python benchmarks/fault_table.py
Writes benchmarks/results/fault_table.md.
"""

from __future__ import annotations

import argparse
import shutil
import signal
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from rapomdp.io import write_text_atomic  # noqa: E402
from tests.faults.cases import CASES  # noqa: E402
from tests.faults.harness import Case, Outcome, files_outside  # noqa: E402

RESULTS = REPO / "benchmarks" / "results" / "fault_table.md"
FAILURES = {"traceback": "tracebacks", "hang": "hangs",
            "silent wrong result": "silent wrong results", "data lost": "cases losing data",
            "file outside": "files written outside the workspace"}


class Hang(Exception):
    pass


def _alarm(signum: int, frame: object) -> None:
    raise Hang


def classify(case: Case, outcome: Outcome | None, error: BaseException | None,
             root: Path) -> str:
    """The verdict on one case (the first failure found, else success)."""
    if isinstance(error, Hang):
        return "hang"
    if error is not None:
        return "traceback" if not isinstance(error, AssertionError) else "silent wrong result"
    assert outcome is not None
    if outcome.traceback:
        return "traceback"
    if files_outside(root, ("ws", "input", "tiny.yaml", "pids")):
        return "file outside"
    if outcome.lost:
        return "data lost"
    if case.expect not in outcome.message:
        return "silent wrong result"
    if case.succeeds:
        return "right result" if outcome.exit_code == 0 else "silent wrong result"
    return "named error" if outcome.exit_code == 2 else "silent wrong result"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit-s", type=float, default=180.0, help="a case past it hangs")
    args = parser.parse_args()
    signal.signal(signal.SIGALRM, _alarm)
    rows, verdicts = [], Counter()
    for case in CASES:
        root = Path(tempfile.mkdtemp(prefix="fault-"))
        outcome, error = None, None
        start = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, args.limit_s)
        try:
            outcome = case.run(root)
        except BaseException as exc:  # noqa: BLE001 - every escape is a finding
            error = exc
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        seconds = time.perf_counter() - start
        verdict = classify(case, outcome, error, root)
        verdicts[verdict] += 1
        shown = (outcome.message if outcome is not None else f"{type(error).__name__}: {error}")
        shown = shown.replace(str(root), "T").replace("|", "\\|").replace("`", "'")
        if len(shown) > 150:
            shown = shown[:147] + "..."
        rows.append(f"| {case.name} | {case.fault.replace('|', '/')} | {verdict} | "
                    f"{'none' if outcome is not None and not outcome.lost else '?'} | "
                    f"{seconds:.1f} | {shown} |")
        shutil.rmtree(root, ignore_errors=True)
        print(f"{case.name}: {verdict} ({seconds:.1f} s)", file=sys.stderr, flush=True)
    lines = [
        "| case | fault or bad input | result | files lost | s | what the user sees |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
        f"{len(CASES)} cases: {verdicts['named error']} named errors, "
        f"{verdicts['right result']} right results; "
        + ", ".join(f"{label}: {verdicts[name]}" for name, label in FAILURES.items()),
    ]
    text = "\n".join(lines) + "\n"
    sys.stdout.write(text)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(RESULTS, text)


if __name__ == "__main__":
    main()
