"""Seconds of each stage of a workspace, from its ``stage.json`` records, and their total.

Every stage records the wall time of its own run (``seconds``) and when it finished; the list
is in pipeline order, and a stage that was never run shows as missing. The total is the sum of
the stages' own times, so it leaves out what runs between them (the CLI's start-up, ``dataset
preview``); ``span`` is the wall clock from the first stage's start to the last one's end,
gaps included (a stage redone later stretches it). With two workspaces the second column is
the other one's and the last their ratio.

Usage: python benchmarks/demo_stage_times.py [WORKSPACE] [OTHER]   (default runs/demo)
"""

from __future__ import annotations

import argparse
import json
from datetime import datetime, timedelta
from pathlib import Path

from rapomdp.pipeline import STAGE_NAMES

STAGE_RECORD = "stage.json"


def stage_records(workspace: Path) -> dict[str, dict]:
    """The ``stage.json`` record of every stage folder of ``workspace``, by stage name."""
    records = {}
    for name in STAGE_NAMES:
        path = workspace / name / STAGE_RECORD
        if path.is_file():
            records[name] = json.loads(path.read_text())
    return records


def stage_seconds(workspace: Path) -> dict[str, float]:
    """Each recorded stage's own seconds, in pipeline order."""
    return {name: float(r["seconds"]) for name, r in stage_records(workspace).items()}


def span_seconds(workspace: Path) -> float | None:
    """Wall clock from the first stage's start to the last stage's end (None: no records)."""
    starts, ends = [], []
    for record in stage_records(workspace).values():
        if "finished" not in record:
            continue
        end = datetime.strptime(record["finished"], "%Y-%m-%dT%H:%M:%S%z")
        ends.append(end)
        starts.append(end - timedelta(seconds=float(record["seconds"])))
    return (max(ends) - min(starts)).total_seconds() if ends else None


def _minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {seconds % 60:04.1f} s"


def table(workspaces: list[Path]) -> str:
    """One line per stage (seconds in each workspace, and the ratio of two), then the totals."""
    times = [stage_seconds(w) for w in workspaces]
    lines = [f"{'stage':<16}" + "".join(f"{w.name[-14:]:>16}" for w in workspaces)
             + ("   ratio" if len(workspaces) == 2 else "")]
    for name in STAGE_NAMES:
        cells = [t.get(name) for t in times]
        line = f"{name:<16}" + "".join(f"{c:>16.1f}" if c is not None else f"{'missing':>16}"
                                         for c in cells)
        if len(cells) == 2 and cells[0] and cells[1] is not None:
            line += f"   {cells[1] / cells[0]:5.2f}"
        lines.append(line)
    totals = [sum(t.values()) for t in times]
    lines.append(f"{'total':<16}" + "".join(f"{s:>16.1f}" for s in totals)
                 + (f"   {totals[1] / totals[0]:5.2f}" if len(totals) == 2 and totals[0] else ""))
    lines.append(f"{'':<16}" + "".join(f"{_minutes(s):>16}" for s in totals))
    spans = [span_seconds(w) for w in workspaces]
    lines.append(f"{'span':<16}" + "".join(f"{_minutes(s):>16}" if s is not None else
                                            f"{'-':>16}" for s in spans))
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("workspaces", type=Path, nargs="*", default=[Path("runs/demo")])
    args = parser.parse_args()
    if len(args.workspaces) > 2:
        parser.error("one or two workspaces")
    print(table(args.workspaces))


if __name__ == "__main__":
    main()
