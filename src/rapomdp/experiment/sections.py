"""What the evaluate and report stages read: the configuration sections their keys hash and the
report's input stages (a light module: the stage graph, e.g. for ``rapomdp status``, is read
without loading the stages' code)."""

from __future__ import annotations

from rapomdp.recognition.artefacts import TRAIN_SECTIONS

EVALUATE_SECTIONS = (*TRAIN_SECTIONS, "viewpoints", "evaluate")
REPORT_SECTIONS = ("seed",)
REPORT_INPUTS = ("dataset", "train", "classifier_eval", "observe", "robot", "solve", "evaluate")
