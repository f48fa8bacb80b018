"""The README's generated block: built from the workspace's artefacts, idempotent, refused
without its markers or its stages."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.experiment.readme import BEGIN, END, update_readme
from rapomdp.io import write_json_atomic
from rapomdp.pipeline import run_pipeline
from rapomdp.workspace import Stage, StageError, StageInputs, Workspace
from tests.conftest import TEST_CONTEXT, tiny_config

TABLE1 = "| Method | Accuracy [95 % CI] |\n|---|---|\n| Static | 0.421 [0.380, 0.463] |\n"
TRADEOFF = "| Method | λ | Accuracy |\n|---|---|---|\n| RA-POMDP | 2 | 0.612 |\n"
QUALITY = "| model | AUC |\n|---|---|\n| ra | 0.733 |\n"
PNG = b"\x89PNG\r\n\x1a\n-not-a-real-image-"
FIG1 = b"\x89PNG\r\n\x1a\n-the-report's-fig-1-"
#: The evaluate stage's held-out comparison: RA-POMDP against Random on 6 held-out objects.
HELD_OUT = json.dumps({
    "reference": "ra", "order": ["random", "ra"], "unpaired": [],
    "methods": {"random": {"accuracy": 0.5, "energy_m": 1.5, "episodes": 24, "objects": 6},
                "ra": {"accuracy": 0.75, "energy_m": 1.25, "episodes": 24, "objects": 6}},
    "paired": {"random": {"difference": -0.25, "low": -0.4, "high": -0.1, "pairs": 24,
                          "objects": 6}}})


def _writer(files: dict[str, str | bytes], metrics: dict | None = None):
    def run(config: Config, inputs: StageInputs, out: Path, context: RunContext) -> None:
        for name, data in files.items():
            (out / name).parent.mkdir(parents=True, exist_ok=True)
            (out / name).write_bytes(data if isinstance(data, bytes) else data.encode())
        if metrics is not None:
            write_json_atomic(out / "metrics.json", metrics)

    return run


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Workspace:
    ws = Workspace(tmp_path_factory.mktemp("ws"))
    config = tiny_config()
    run_pipeline(config, ws, until="dataset", context=TEST_CONTEXT)
    stages = {
        "classifier_eval": _writer({}, {"xrho": {"images": 48, "accuracy": 0.5417,
                                                 "chance": 0.3333},
                                        "sphere": {"images": 18, "accuracy": 0.6,
                                                   "chance": 0.3333}}),
        "observe": _writer({"quality.md": QUALITY}),
        "evaluate": _writer({"table1.md": TABLE1, "tradeoff.md": TRADEOFF, "fig3.png": PNG,
                             "tradeoff.png": PNG, "held_out/comparison.json": HELD_OUT}),
        # the report's Fig. 1 of the figure class (no evaluate.json: the configured bicycle),
        # and one of another class, which is not the lead figure
        "report": _writer({"fig1_bicycle.png": FIG1, "fig1_cup.png": PNG}),
    }
    for name, run in stages.items():
        ws.run(Stage(name, run), config, context=TEST_CONTEXT)
    return ws


def test_the_block_holds_the_workspace_numbers_and_is_idempotent(finished, tmp_path) -> None:
    readme = tmp_path / "README.md"
    readme.write_text(f"# Title\n\nbefore\n\n{BEGIN}\nstale numbers 0.999\n{END}\n\nafter\n")
    update_readme(finished, readme)
    text = readme.read_text()
    assert text.startswith("# Title\n\nbefore\n\n" + BEGIN + "\n")
    assert text.endswith(END + "\n\nafter\n")
    assert "stale numbers 0.999" not in text
    block = text[text.index(BEGIN):text.index(END)]
    for part in (TABLE1.strip(), TRADEOFF.strip(), QUALITY.strip()):
        assert part in block
    assert "right on 54.2% of the test models' views from X_rho (chance 33.3%)" in block
    # the held-out comparison, Table 1's forecast, in the order the methods ran
    assert "On the 6 held-out objects, with 95 % intervals that resample them, RA-POMDP is " \
        "more accurate than Random (by 0.250)." in block
    assert "| Random | 0.500 | 1.50 | -0.250 [-0.400, -0.100] | 24 |\n| RA-POMDP | 0.750 | " \
        "1.25 | — | 24 |" in block
    assert "1 test model(s) per class (3 classes" in block  # the tiny split, from the dataset
    assert "](docs/figures/demo_tradeoff.png)" in block
    assert (tmp_path / "docs" / "figures" / "demo_fig3.png").read_bytes() == PNG
    # the README's lead figure: the report's Fig. 1 of the figure class
    assert (tmp_path / "docs" / "figures" / "demo_fig1.png").read_bytes() == FIG1
    update_readme(finished, readme)
    assert readme.read_text() == text


def test_figures_go_where_the_user_says(finished, tmp_path: Path) -> None:
    readme = tmp_path / "README.md"
    readme.write_text(f"{BEGIN}\n{END}\n")
    update_readme(finished, readme, tmp_path / "pictures")
    assert "](pictures/demo_fig3.png)" in readme.read_text()
    assert sorted(p.name for p in (tmp_path / "pictures").iterdir()) == [
        "demo_fig1.png", "demo_fig3.png", "demo_tradeoff.png"]
    assert not (tmp_path / "docs").exists()


def test_no_markers_or_no_stages_is_a_named_error(finished, tmp_path: Path) -> None:
    readme = tmp_path / "README.md"
    readme.write_text("# no block here\n")
    with pytest.raises(StageError, match="no generated-results block; add the two lines"):
        update_readme(finished, readme)
    assert readme.read_text() == "# no block here\n"
    readme.write_text(f"{BEGIN}\n{END}\n")
    empty = Workspace(tmp_path / "empty")
    with pytest.raises(StageError, match=r"stage\(s\) dataset, classifier_eval, observe, "
                                         r"evaluate have not run"):
        update_readme(empty, readme)


def test_the_block_shows_every_methods_final_belief_calibration(tmp_path) -> None:
    from rapomdp.data.dataset import load_dataset
    from rapomdp.io import save_npz
    from tests.experiment.test_report import _episodes

    ws = Workspace(tmp_path / "ws")
    config = tiny_config()
    run_pipeline(config, ws, until="dataset", context=TEST_CONTEXT)
    classes = load_dataset(ws.require("dataset")).classes

    def evaluate(config: Config, inputs: StageInputs, out: Path, context: RunContext) -> None:
        _writer({"table1.md": TABLE1})(config, inputs, out, context)
        save_npz(out / "episodes.npz", **_episodes(classes).arrays())

    stages = {"classifier_eval": _writer({}, {"xrho": {"images": 48, "accuracy": 0.5,
                                                       "chance": 0.3333},
                                              "sphere": {"images": 18, "accuracy": 0.6,
                                                         "chance": 0.3333}}),
              "observe": _writer({"quality.md": QUALITY}), "evaluate": evaluate}
    for name, run in stages.items():
        ws.run(Stage(name, run), config, context=TEST_CONTEXT)
    readme = tmp_path / "README.md"
    readme.write_text(f"{BEGIN}\n{END}\n")
    text = update_readme(ws, readme).read_text()
    assert not (tmp_path / "docs" / "figures" / "demo_fig1.png").exists()  # no report yet
    assert "**Calibration of the final belief**" in text
    # Static right 9 of 25 with belief 0.8 / 0.3 in the true class, uniform over 3 classes
    assert "| Static | 0.360 | 0.480 | 0.333 | -0.027 | 0.027 |" in text
    assert "| RA-POMDP | 1.000 | 0.800 | 0.333 | -0.667 | 0.667 |" in text
