"""The ``evaluate`` configuration section: which methods run, from where, for how long."""

from __future__ import annotations

from pydantic import Field, field_validator

from rapomdp.section import Section

#: Display names of the methods (the paper's Table 1 rows, then extra observation models).
METHOD_NAMES = {
    "static": "Static",
    "random": "Random",
    "vptree": "VP-tree",
    "classifier": "Classifier",
    "ra": "RA-POMDP",
    "ra_class": "RA-POMDP (per-class)",
    "blackbox": "Black-box POMDP",
}


class RandomWalkConfig(Section):
    """The Random method: a walk among the nearest reachable viewpoints, never revisiting."""

    neighbours: int = Field(8, ge=1, description="candidates: the k nearest reachable viewpoints")
    belief_threshold: float = Field(
        0.9, gt=0, le=1, description="stop rule: declare once max belief reaches this")
    max_moves: int = Field(10, ge=0, description="stop rule: declare after this many moves")
    observation_model: str = Field(
        "classifier", description="observation model of its belief update (an observe model)")


class EvaluateConfig(Section):
    """The closed-loop evaluation (paper Sec. 5.2): every test model x start x method."""

    methods: list[str] = Field(
        ["static", "random", "vptree", "classifier", "ra"],
        description="static, random, or an observation model solved by the solve stage "
        "(vptree, classifier, ra, ra_class, blackbox)")
    starts_per_model: int = Field(
        4, ge=1, description="start viewpoints per test model, drawn (seeded) among reachable "
        "(default 4: 32 classes x 4 test models x 4 = 512 episodes per method)")
    max_moves: int = Field(
        30, ge=0, description="step budget: after this many moves a method must declare")
    revisit: bool = Field(
        False, description="let the POMDP methods move back to a viewpoint they have seen "
        "(the noiseless sensor would show the same image, counted as new evidence)")
    random: RandomWalkConfig = RandomWalkConfig()
    lambdas: list[float] = Field(
        [0.5, 2.0, 8.0], description="accuracy against energy: wrong-declaration costs λ (m) "
        "each POMDP method is also solved and run at (solve.wrong_declaration_cost_m, Table "
        "1's, is always a point); [] for Table 1 alone")
    random_thresholds: list[float] = Field(
        [0.6, 0.9, 0.97], description="accuracy against energy: Random's stop beliefs "
        "(random.belief_threshold, Table 1's, is always a point)")
    figure_class: str = Field("bicycle", description="the class of Fig. 3 and the trajectories "
                              "(the first class when the dataset has no such class)")

    @field_validator("lambdas")
    @classmethod
    def _positive(cls, values: list[float]) -> list[float]:
        if any(v <= 0 for v in values):
            raise ValueError("every λ must be positive (metres of movement energy)")
        return values

    @field_validator("random_thresholds")
    @classmethod
    def _beliefs(cls, values: list[float]) -> list[float]:
        if any(not 0 < v <= 1 for v in values):
            raise ValueError("every stop belief must be in (0, 1]")
        return values

    @field_validator("methods")
    @classmethod
    def _known(cls, methods: list[str]) -> list[str]:
        unknown = [m for m in methods if m not in METHOD_NAMES]
        if unknown:
            raise ValueError(f"unknown method(s) {unknown}; methods are: "
                             f"{', '.join(METHOD_NAMES)}")
        if len(set(methods)) != len(methods):
            raise ValueError("a method is listed twice")
        if not methods:
            raise ValueError("list at least one method")
        return methods
