"""A ``.pomdpx`` writer for the active-recognition MOMDP (for the reference SARSOP toolkit).

The viewpoint is a fully observed state variable (``fullyObs="true"``), so SARSOP runs in its
MOMDP mode; it has one extra value ``done``, the absorbing terminal state entered by a
declaration. The class is a hidden variable that never changes. Tables are written entry by
entry (unlisted entries are 0), so no entry relies on override order.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rapomdp.io import write_text_atomic
from rapomdp.planning.momdp import FORBIDDEN_REWARD, ActiveRecognitionProblem


def escape(text: str) -> str:
    """XML character data: &, < and > escaped (xml.sax.saxutils would import urllib)."""
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _num(x: float) -> str:
    return repr(float(x))


def format_pomdpx(problem: ActiveRecognitionProblem, description: str = "") -> str:
    """The ``.pomdpx`` text of an active-recognition problem.

    The viewpoint is a fully observed variable (SARSOP's MOMDP mode), the class a hidden one;
    the reference ``pomdpsol`` solves the file.

    Args:
        problem: The MOMDP.
        description: A line for the file's ``<Description>``.

    Returns:
        The XML text.
    """
    n_v, n_c = problem.n_viewpoints, problem.n_classes
    views = [f"v{v}" for v in range(n_v)]
    classes = [f"c{c}" for c in range(n_c)]
    labels = [f"o{c}" for c in range(n_c)]
    targets = problem.targets
    moves = [f"move{j}" for j in targets]
    declares = [f"declare{k}" for k in range(n_c)]
    cost = problem.move_cost()
    P = problem.observation_model
    out: list[str] = []
    w = out.append
    w('<?xml version="1.0" encoding="ISO-8859-1"?>')
    w('<pomdpx version="0.1" id="rapomdp-active-recognition" '
      'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" '
      'xsi:noNamespaceSchemaLocation="pomdpx.xsd">')
    desc = description or (
        f"Active recognition: {n_v} viewpoints x {n_c} classes; class names: "
        + ", ".join(problem.class_names)
    )
    w(f"<Description>{escape(desc)}</Description>")
    w(f"<Discount>{_num(problem.discount)}</Discount>")
    w("<Variable>")
    w('<StateVar vnamePrev="view_0" vnameCurr="view_1" fullyObs="true">')
    w(f"<ValueEnum>{' '.join(views)} done</ValueEnum></StateVar>")
    w('<StateVar vnamePrev="class_0" vnameCurr="class_1">')
    w(f"<ValueEnum>{' '.join(classes)}</ValueEnum></StateVar>")
    w(f'<ObsVar vname="label"><ValueEnum>{" ".join(labels)}</ValueEnum></ObsVar>')
    w(f'<ActionVar vname="action"><ValueEnum>{" ".join(moves + declares)}</ValueEnum>'
      "</ActionVar>")
    w('<RewardVar vname="reward"/>')
    w("</Variable>")
    # initial belief: known viewpoint, class distribution
    w("<InitialStateBelief>")
    w("<CondProb><Var>view_0</Var><Parent>null</Parent><Parameter type=\"TBL\">")
    w(f"<Entry><Instance>{views[problem.start_viewpoint]}</Instance>"
      "<ProbTable>1.0</ProbTable></Entry>")
    w("</Parameter></CondProb>")
    w("<CondProb><Var>class_0</Var><Parent>null</Parent><Parameter type=\"TBL\">")
    w(f"<Entry><Instance>-</Instance><ProbTable>"
      f"{' '.join(_num(x) for x in problem.start_belief)}</ProbTable></Entry>")
    w("</Parameter></CondProb>")
    w("</InitialStateBelief>")
    # transitions
    w("<StateTransitionFunction>")
    w("<CondProb><Var>view_1</Var><Parent>action view_0</Parent><Parameter type=\"TBL\">")
    for m, j in zip(moves, targets, strict=True):
        for v in views:
            w(f"<Entry><Instance>{m} {v} {views[j]}</Instance><ProbTable>1.0</ProbTable></Entry>")
        w(f"<Entry><Instance>{m} done done</Instance><ProbTable>1.0</ProbTable></Entry>")
    for d in declares:
        w(f"<Entry><Instance>{d} * done</Instance><ProbTable>1.0</ProbTable></Entry>")
    w("</Parameter></CondProb>")
    w("<CondProb><Var>class_1</Var><Parent>class_0</Parent><Parameter type=\"TBL\">")
    w("<Entry><Instance>- -</Instance><ProbTable>identity</ProbTable></Entry>")
    w("</Parameter></CondProb>")
    w("</StateTransitionFunction>")
    # observations: the label on arrival, by class and arrival viewpoint
    w("<ObsFunction>")
    w("<CondProb><Var>label</Var><Parent>action view_1 class_1</Parent>"
      "<Parameter type=\"TBL\">")
    for vi in range(n_v):
        for c in range(n_c):
            w(f"<Entry><Instance>* {views[vi]} {classes[c]} -</Instance>"
              f"<ProbTable>{' '.join(_num(x) for x in P[vi, c])}</ProbTable></Entry>")
    # in the terminal state the label carries nothing; pomdpsol accepts ``uniform`` only in
    # the initial belief, so the row is written out (all mass on the first label: exact)
    done_row = " ".join(["1.0"] + ["0.0"] * (n_c - 1))
    w(f"<Entry><Instance>* done * -</Instance><ProbTable>{done_row}</ProbTable></Entry>")
    w("</Parameter></CondProb>")
    w("</ObsFunction>")
    # rewards: move cost by (from, to); declaration by (declared, true class); 0 when done
    w("<RewardFunction>")
    w("<Func><Var>reward</Var><Parent>action view_0 class_0</Parent><Parameter type=\"TBL\">")
    for a, m in enumerate(moves):
        for vi in range(n_v):
            r = float(-cost[vi, a]) if np.isfinite(cost[vi, a]) else FORBIDDEN_REWARD
            if r != 0:
                w(f"<Entry><Instance>{m} {views[vi]} *</Instance>"
                  f"<ValueTable>{_num(r)}</ValueTable></Entry>")
    for k, d in enumerate(declares):
        for c in range(n_c):
            if c != k and problem.lambda_ != 0:
                for v in views:
                    w(f"<Entry><Instance>{d} {v} {classes[c]}</Instance>"
                      f"<ValueTable>{_num(-problem.lambda_)}</ValueTable></Entry>")
    w("</Parameter></Func>")
    w("</RewardFunction>")
    w("</pomdpx>")
    return "\n".join(out) + "\n"


def write_pomdpx(
    problem: ActiveRecognitionProblem, path: str | os.PathLike[str], description: str = ""
) -> Path:
    """Write the problem as ``.pomdpx`` (atomically, :func:`format_pomdpx`'s text).

    Args:
        problem: The MOMDP.
        path: The file to write.
        description: A line for the file's ``<Description>``.

    Returns:
        ``path``.
    """
    return write_text_atomic(Path(path), format_pomdpx(problem, description))
