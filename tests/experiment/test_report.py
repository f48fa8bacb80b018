"""The report stage on a workspace whose stages (but the dataset) are synthetic."""

from __future__ import annotations

import csv
import dataclasses
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from typer.testing import CliRunner  # noqa: E402

from rapomdp import pipeline as pipeline_module  # noqa: E402
from rapomdp.cli import app  # noqa: E402
from rapomdp.config import Config  # noqa: E402
from rapomdp.context import RunContext
from rapomdp.data.dataset import load_dataset  # noqa: E402
from rapomdp.document import Table, table_html  # noqa: E402
from rapomdp.experiment import report as report_module  # noqa: E402
from rapomdp.experiment.episode_table import EpisodeTable  # noqa: E402
from rapomdp.experiment.metrics import (  # noqa: E402
    per_class,
    per_class_markdown,
    table1,
    table1_markdown,
)
from rapomdp.experiment.report import run_report_stage, write_report  # noqa: E402
from rapomdp.io import save_npz, write_json_atomic  # noqa: E402
from rapomdp.pipeline import get_stage, run_pipeline  # noqa: E402
from rapomdp.workspace import Stage, StageError, StageInputs, Workspace  # noqa: E402
from tests.conftest import TEST_CONTEXT, tiny_config  # noqa: E402

QUALITY = """model,log_likelihood,brier,auc,mean_p_correct,accuracy
ra,-0.412,0.131,0.74,0.61,0.58
classifier,-0.533,0.17,0.66,0.55,0.58
"""
VALIDATION = """model,log_likelihood,brier,auc,mean_p_correct,accuracy
ra_paper,-0.61,0.2,0.6,0.5,0.52
ra_transfer,-0.45,0.15,0.7,0.52,0.52
classifier,-0.7,0.22,0.62,0.5,0.52
"""
#: The observe stage's choice: ra_transfer, configured by name.
CALIBRATION = {"ra_model": "transfer", "ra_model_configured": "transfer", "method": "logistic",
               "variants": {"ra_paper": {"method": "logistic"},
                            "ra_transfer": {"method": "salient_view_transfer"}}}


def _observation_models(out: Path) -> None:
    """ra is ra_transfer (one array); ra_paper and classifier differ; two evidence groups."""
    rng = np.random.default_rng(1)
    chosen, other, third = (rng.dirichlet(np.ones(3), size=(16, 3)) for _ in range(3))
    save_npz(out / "observation_models.npz", models=np.array(["ra", "ra_paper", "ra_transfer",
                                                              "classifier"]),
             temperatures=np.ones(4), ra=chosen, ra_paper=other, ra_transfer=chosen,
             classifier=third, evidence_groups=np.array([0, 0, 0, 1, 1, 1]))

METHODS = ["static", "ra"]


def _episodes(classes: list[str]) -> EpisodeTable:
    """25 episodes per method: Static declares at once and is right 9 times (accuracy 0.360);
    RA-POMDP moves 4 times and is always right."""
    n = 25
    class_index = np.tile(np.arange(n) % len(classes), 2)
    correct = np.concatenate([np.arange(n) < 9, np.ones(n, dtype=bool)])
    moves = np.concatenate([np.zeros(n, dtype=np.int64), np.full(n, 4)])
    offsets = np.concatenate([[0], np.cumsum(moves + 1)])
    steps = int(offsets[-1])
    return EpisodeTable(
        classes=list(classes), methods=METHODS, method=np.repeat(METHODS, n),
        class_index=class_index, model=np.array([f"m{c}" for c in class_index]),
        start=np.zeros(2 * n, dtype=np.int64),
        declared=np.where(correct, class_index, (class_index + 1) % len(classes)),
        exhausted=np.zeros(2 * n, dtype=bool), correct=correct,
        belief=np.where(correct, 0.8, 0.3), moves=moves, distance_m=0.2 * moves,
        energy=1.5 * moves, offsets=offsets, step_viewpoints=np.arange(steps) % 16,
        step_outputs=np.full((steps, len(classes)), 1 / len(classes)),
        step_beliefs=np.full((steps, len(classes)), 1 / len(classes)),
        cpu_seconds=np.full(2 * n, 0.01))


def _png(path: Path) -> None:
    fig, ax = plt.subplots(figsize=(1, 1))
    ax.plot([0, 1], [1, 0])
    fig.savefig(path, dpi=20)
    plt.close(fig)


def _writer(texts: dict[str, str], jsons: dict[str, object], pngs: tuple[str, ...],
            episodes: bool = False, models: bool = False):
    def run(config: Config, inputs: StageInputs, out: Path, context: RunContext) -> None:
        if models:
            _observation_models(out)
        if episodes:
            classes = load_dataset(inputs.dataset).classes
            save_npz(out / "episodes.npz", **_episodes(classes).arrays())
        for name, text in texts.items():
            (out / name).write_text(text)
        for name, data in jsons.items():
            write_json_atomic(out / name, data)
        for name in pngs:
            _png(out / name)

    return run


EVALUATE = {"episodes": 30, "images": 171, "images_per_s": 412.5,
            "methods": ["Static", "Random", "Classifier", "RA-POMDP"],
            "figure_class": "bicycle", "workers": 2,
            "seconds": {"episodes_cpu": 1.94, "episodes_wall": 1.2, "total": 2.5}}
SYNTHETIC = {
    "train": _writer({}, {"metrics.json": {}}, ("training.png",)),
    "classifier_eval": _writer({}, {"metrics.json": {
        "xrho": {"images": 48, "accuracy": 0.6458, "chance": 0.3333},
        "sphere": {"images": 18, "accuracy": 0.7222, "chance": 0.3333}}},
        ("confusion_xrho.png", "accuracy_hemisphere.png")),
    "observe": _writer({"quality.csv": QUALITY, "validation.csv": VALIDATION},
                       {"calibration.json": CALIBRATION}, ("calibration.png",), models=True),
    "robot": _writer({}, {"robot.json": {
        "viewpoints": 16, "reachable": 9, "reachable_fraction": 0.5625, "ik_seconds": 1.25,
        "manipulability": {"min": 0.02, "median": 0.08, "max": 0.11}}}, ("robot.png",)),
    "solve": _writer({}, {"solve_summary.json": {
        "ra": {"lower": -3.21, "upper": -3.2, "seconds": 1.5, "vectors": 40},
        "classifier": {"lower": -4.0, "upper": -3.99, "seconds": 2.0, "vectors": 31}}}, ()),
    "evaluate": _writer({}, {"evaluate.json": EVALUATE}, ("fig3.png", "trajectories.png"),
                        episodes=True),
}


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> tuple[Workspace, Config]:
    """A real tiny dataset stage and synthetic train ... evaluate stages."""
    config = tiny_config()
    ws = Workspace(tmp_path_factory.mktemp("ws"))
    run_pipeline(config, ws, until="dataset", context=TEST_CONTEXT)
    for name, run in SYNTHETIC.items():
        ws.run(Stage(name, run, inputs=("dataset",)), config, context=TEST_CONTEXT)
    (ws.root / "config.yaml").write_text(config.to_yaml())
    return ws, config


def _inputs(ws: Workspace) -> StageInputs:
    return ws.inputs(get_stage("report"))


def _fake_fig1(calls: list[tuple[str, Path]]):
    def fig1(ws: Workspace, class_name: str, out_dir: Path) -> tuple[Path, Path]:
        calls.append((class_name, out_dir))
        _png(out_dir / f"fig1_{class_name}.png")
        (out_dir / f"fig1_{class_name}.html").write_text("<html></html>")
        return out_dir / f"fig1_{class_name}.png", out_dir / f"fig1_{class_name}.html"

    return fig1


def test_report_holds_the_tables_figures_and_numbers(synthetic, tmp_path: Path) -> None:
    ws, config = synthetic
    out = tmp_path / "report"
    calls: list[tuple[str, Path]] = []
    page, md = write_report(config, _inputs(ws), out, fig1=_fake_fig1(calls))
    assert (page, md) == (out / "report.html", out / "report.md")
    assert calls == [("bicycle", out)]  # the evaluate stage's figure class
    text, html = md.read_text(), page.read_text()
    # Table 1 and the per-class table are computed from the episodes, as evaluate writes them
    episodes = _episodes(load_dataset(ws.require("dataset")).classes)
    expected = (table1_markdown(table1(episodes, METHODS)).splitlines()[2:]
                + per_class_markdown(per_class(episodes, METHODS), METHODS).splitlines()[4:])
    for row in (*expected, "| Static | 0.360 [0.202, 0.555] | 0.480 ± 0.101 | — | — | — | 25 |",
                "| ra | -0.412 | 0.131 | 0.740 | 0.610 | 0.580 |"):
        assert row in text
    assert "| RA-POMDP | 1.000 [" in text and "| 4.000 ± 0.000 | 0.800 ± 0.000 |" in text
    # the story paragraph, from the numbers (these synthetic episodes share no start pairs)
    assert ("On this run RA-POMDP is the most accurate method (1.000 of 25 episodes); Static, "
            "one view, reaches 0.360.") in text
    assert "No paired comparison: methods 'static' and 'ra' did not run from the same" in text
    assert "<td>RA-POMDP</td><td>1.000 [" in html
    assert "30 episodes" in text and "171 depth images" in text
    assert "(412.5 images per CPU second)" in text
    assert ("Time: the episodes took 1.9 s of CPU time, 1.2 s of wall time over 2 worker(s), "
            "the stage 2.5 s in all.") in text and "episodes_cpu" not in text
    # Table 1's columns are defined right after it
    assert text.index("Columns: Accuracy — the fraction of episodes") > text.index("| Static |")
    assert "# steps — the moves made" in text and "Belief — the method's final belief" in text
    # every stage the workspace ran is in the stage table, the configuration is shown
    for stage in ("dataset", "train", "classifier_eval", "robot", "solve", "evaluate"):
        assert re.search(rf"^\| {stage} \| [0-9a-f]{{12}} \|", text, flags=re.M), stage
    assert "```yaml\nseed: 3  # every stage" in text
    assert "wrong_declaration_cost_m: 8.0  # lambda" in text
    assert "<details><summary>The configuration of this run" in html
    assert "| test viewpoints X_rho | 48 | 0.646 | 0.333 |" in text
    assert "| ra | -3.2100 | -3.2000 | 0.0100 | 1.5 | 40 |" in text
    # the solver's gap, with what it means for the policy
    assert ("`ra`: stopped at the iteration budget (solve.iterations: 25) with a gap of 0.01 m: "
            "its policy may cost up to 0.01 m more per episode than an optimal one, as much as "
            "0.0012 wrong declaration(s) at λ = 8 m; its mean episode energy in Table 1 is "
            "6.00 m, so the gap is 0.0017 times what an episode spends moving") in text
    assert "`classifier`: stopped at the iteration budget" in text  # no episodes: no energy
    assert "the policy the solver returned; no policy is worth more than the upper" in text
    # RA-POMDP's model named, with the held-out table of every variant
    assert ("RA-POMDP's observation model (`ra`) is `ra_transfer`, as configured "
            "(`observe.ra_model: transfer`); the held-out validation below shows how the "
            "variants compare") in text
    assert "| ra_transfer (chosen) | -0.450 | 0.150 | 0.700 | 0.520 | 0.520 |" in text
    assert "| ra_paper | -0.610 |" in text and "held-out accuracy |" in text
    assert text.index("(chosen)") < text.index("| ra | -0.412 |")  # the choice, then the test
    assert ("Equal rows: `ra` and `ra_transfer` are one model (`ra` is the chosen variant), so "
            "their rows are equal by construction.") in text
    # calibration.png's caption says what the chosen model draws: no map
    assert ("RA-POMDP's model (ra_transfer) gives the same (class, viewpoint) pairs") in text
    assert "ra_transfer has no map from the score alone" in text
    assert "fitted score-to-correctness map of RA-POMDP's model" not in text
    # Fig. 3's caption names both panels
    assert ("Fig. 3: the mean belief in the true class after each image, per method: left, the "
            "test models of class bicycle; right, the mean over the 3 classes") in text
    # the final beliefs' reliability data carry every bin's count (uniform beliefs: 1/3)
    with open(out / "belief_reliability.csv", newline="") as handle:
        bins = list(csv.DictReader(handle))
    assert {r["curve"] for r in bins} == {"Static", "RA-POMDP"}
    for method in ("Static", "RA-POMDP"):
        counts = [int(r["count"]) for r in bins if r["curve"] == method]
        assert counts == [0, 0, 0, 25, 0, 0, 0, 0, 0, 0]
    assert "[belief_reliability.csv](belief_reliability.csv)" in text
    assert "9/16 viewpoints reachable (56 %)" in text
    assert f"seed {config.seed}" in text and "Configuration hash" in text
    # every image the report links lies in its folder, as a PNG
    links = re.findall(r"!\[[^]]*\]\(([^)]+)\)", text)
    sources = re.findall(r'<img src="([^"]+)"', html)
    assert sorted(links) == sorted(sources)
    assert set(links) == {"fig3.png", "trajectories.png", "fig1_bicycle.png", "calibration.png",
                          "confusion_xrho.png", "accuracy_hemisphere.png", "training.png",
                          "robot.png", "belief_reliability.png"}
    for name in links:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # one <table> per markdown table: Table 1, per class, held-out validation, quality, the
    # final beliefs' calibration, provenance, classifier, solver
    assert html.count("<table>") == len(re.findall(r"^\|---", text, flags=re.M)) == 8
    assert ("| Method | Accuracy | Belief in the true class | Confidence | "
            "Confidence − accuracy | ECE | ECE if calibrated (95 %) |") in text
    assert "ECE if calibrated: the 95th percentile of the ECE a reporter calibrated" in text
    # the fixture's beliefs stay uniform over 3 classes: confidence 1/3 whatever was declared
    assert "| Static | 0.360 | 0.480 | 0.333 | -0.027 | 0.027 |" in text
    assert "| RA-POMDP | 1.000 | 0.800 | 0.333 | -0.667 | 0.667 |" in text
    # optional inputs that are absent are named with the command that makes them
    assert "Fig. 2: one class" not in text
    # Fig. 2 is optional: said how to make, but not a missing figure
    assert "Fig. 2 (one class's saliency volume in two-class problems) is optional: " \
        "`rapomdp figure fig2 -w" in text and "fig2.png (not found)" not in text
    # the interactive Fig. 1 is linked, relative to the report folder
    assert "[fig1_bicycle.html](fig1_bicycle.html)" in text
    assert '<a href="fig1_bicycle.html">fig1_bicycle.html</a>' in html
    assert "vptree/vptree.json not found" in text
    assert 'class="missing"' in html


def test_optional_inputs_are_shown_when_present(synthetic, tmp_path: Path) -> None:
    ws, config = synthetic
    (ws.root / "figures").mkdir(exist_ok=True)
    _png(ws.root / "figures" / "fig2.png")
    (ws.root / "figures" / "fig2.html").write_text("<html></html>")
    (ws.root / "vptree").mkdir(exist_ok=True)
    write_json_atomic(ws.root / "vptree" / "vptree.json", {"accuracy_test_xrho": 0.4167})
    choice = {"variant": "class", "rule": "too little evidence",
              "reason": "too little held-out evidence to choose: class 'cup' (1) has fewer "
                        "than 2 held-out objects; the robust default 'class'"}
    write_json_atomic(ws.root / "observe" / "calibration.json",
                      {**CALIBRATION, "ra_model": "class", "ra_model_configured": "mixture",
                       "ra_model_choice": choice})
    try:
        _, md = write_report(config, _inputs(ws), tmp_path / "r", fig1=_fake_fig1([]))
    finally:
        (ws.root / "figures" / "fig2.png").unlink()
        (ws.root / "figures" / "fig2.html").unlink()
        (ws.root / "vptree" / "vptree.json").unlink()
        write_json_atomic(ws.root / "observe" / "calibration.json", CALIBRATION)
    text = md.read_text()
    # the choice says when the held-out evidence was too little, and why
    assert ("RA-POMDP's observation model (`ra`) is `ra_class`, the fallback of "
            "`observe.ra_model: mixture` (too little evidence): too little held-out evidence to "
            "choose: class 'cup' (1) has fewer than 2 held-out objects; the robust default "
            "'class'. ") in text
    assert "![Fig. 2: one class" in text and (tmp_path / "r" / "fig2.png").exists()
    assert "[fig2.html](fig2.html)" in text and (tmp_path / "r" / "fig2.html").exists()
    assert "over X_rho: 0.417." in text and "vptree.json not found" not in text


def test_missing_files_and_fig1_failures_become_lines(synthetic, tmp_path: Path) -> None:
    ws, config = synthetic
    inputs = _inputs(ws)
    broken = tmp_path / "evaluate"
    broken.mkdir()
    save_npz(broken / "episodes.npz",
             **_episodes(load_dataset(ws.require("dataset")).classes).arrays())
    inputs = dataclasses.replace(inputs, evaluate_dir=broken)
    # the real Fig. 1 needs the render, saliency and volume stages, absent here
    _, md = write_report(config, inputs, tmp_path / "r")
    text = md.read_text()
    assert "| Static | 0.360 [" in text
    assert "evaluate.json (not found) — made by `rapomdp evaluate -w" in text
    assert "fig3.png (not found)" in text and "episodes.npz (not found)" not in text
    (broken / "episodes.npz").unlink()
    _, md = write_report(config, inputs, tmp_path / "r2")
    assert "episodes.npz (not found) — made by `rapomdp evaluate -w" in md.read_text()
    assert "Fig. 1 for class bicycle could not be made" in text
    assert "stage 'render' has not been run" in text
    assert "figure fig1 -w" in text


def test_a_missing_required_stage_is_named(synthetic, tmp_path: Path) -> None:
    ws, config = synthetic
    inputs = _inputs(ws)
    inputs = dataclasses.replace(inputs, solve_dir=None)
    with pytest.raises(StageError, match="report: needs the stage.s. solve"):
        run_report_stage(config, inputs, tmp_path / "r", TEST_CONTEXT)
    inputs = dataclasses.replace(inputs, solve_dir=tmp_path / "nowhere")
    with pytest.raises(StageError, match="solve"):
        write_report(config, inputs, tmp_path / "r")


def test_report_stage_runs_in_the_pipeline_and_the_cli(synthetic, monkeypatch) -> None:
    ws, config = synthetic
    monkeypatch.setattr(report_module, "write_fig1", _fake_fig1([]))

    def only_the_report(config: Config, workspace: Workspace, until: str, force, on_result,
                        context):
        # the synthetic stages are not the real ones: run the report stage alone
        assert (until, force) == ("report", ["report"])
        return [workspace.run(get_stage("report"), config, force=True, context=context)]

    monkeypatch.setattr(pipeline_module, "run_pipeline", only_the_report)  # cli imports it lazily
    result = CliRunner().invoke(app, ["report", "-w", str(ws.root), "-c",
                                      str(ws.root / "config.yaml")])
    assert result.exit_code == 0, result.output
    assert result.stdout.split() == [str(ws.root / "report" / "report.html"),
                                     str(ws.root / "report" / "report.md")]
    assert "report" in ws.manifest()["stages"]
    assert "| RA-POMDP | 1.000 [" in (ws.root / "report" / "report.md").read_text()


def test_tables_convert_to_html_escaped() -> None:
    table = Table(["a", "b | c"], [["1", "<2>"], ["3", ""]])
    assert table_html(table) == ("<table>\n<thead><tr><th>a</th><th>b | c</th></tr></thead>\n"
                                 "<tbody><tr><td>1</td><td>&lt;2&gt;</td></tr>"
                                 "<tr><td>3</td><td></td></tr></tbody>\n</table>")


def test_the_mixture_is_named_with_its_weights_or_its_fallback(synthetic, tmp_path: Path) -> None:
    ws, config = synthetic
    mixture = {**CALIBRATION, "ra_model": "mixture", "ra_model_configured": "mixture",
               "variants": {**CALIBRATION["variants"], "ra_mixture": {
                   "method": "held_out_mixture",
                   "weights": {"ra_paper": 0.15, "ra_transfer": 0.85, "ra_class": 1e-9}}},
               "ra_model_choice": {"variant": "mixture", "rule": "mixture", "reason": "r"}}
    fallback = {**CALIBRATION, "ra_model": "class", "ra_model_configured": "mixture",
                "ra_model_choice": {"variant": "class", "rule": "too little evidence",
                                    "reason": "too little held-out evidence to choose"}}
    texts = []
    try:
        for i, record in enumerate((mixture, fallback)):
            write_json_atomic(ws.root / "observe" / "calibration.json", record)
            _, md = write_report(config, _inputs(ws), tmp_path / f"r{i}", fig1=_fake_fig1([]))
            texts.append(md.read_text())
    finally:
        write_json_atomic(ws.root / "observe" / "calibration.json", CALIBRATION)
    assert ("RA-POMDP's observation model (`ra`) is `ra_mixture`, the RA variants averaged with "
            "weights fitted on the held-out labels (`observe.ra_model: mixture`, the default; "
            "each held-out object scored by the variants fitted without its group, the test "
            "models play no part): `ra_transfer` 0.85, `ra_paper` 0.15.") in texts[0]
    assert "`ra_class` 0.00" not in texts[0]  # weights below 0.005 are left out
    assert ("RA-POMDP's observation model (`ra`) is `ra_class`, the fallback of "
            "`observe.ra_model: mixture` (too little evidence): too little held-out evidence "
            "to choose.") in texts[1]
