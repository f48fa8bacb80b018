"""Bring your own recogniser (``train.network``): the key's form, the errors of a factory that
cannot be used, the checkpoint of a custom network, the tiny pipeline on a small ResNet from
training to the closed loop, and the black-box saliency of a recogniser without gradients."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from rapomdp.awareness.saliency import make_attribution
from rapomdp.awareness.stage import SaliencyMethod, saliency_method
from rapomdp.config import ConfigError, config_from_dict
from rapomdp.data.test_views import load_xrho_views
from rapomdp.io import load_npz, read_json
from rapomdp.pipeline import run_pipeline
from rapomdp.recognition.classifier import META_FILE, CheckpointError, Classifier
from rapomdp.recognition.custom import (
    CustomNetwork,
    CustomSpec,
    RecogniserError,
    build_recogniser,
)
from rapomdp.recognition.examples import SmallResNet
from rapomdp.recognition.network import (
    DepthAlexNet,
    DepthEnsemble,
    NetworkSpec,
    build_network,
    member_networks,
)
from rapomdp.recognition.preprocess import PreprocessParams
from rapomdp.recognition.stage import load_stage_classifier, run_train_stage
from rapomdp.recognition.training import member_seed, network_spec
from rapomdp.workspace import StageError, StageInputs, Workspace
from tests.conftest import SMALL_SPLIT, TEST_CONTEXT, TINY_PIPELINE
from tests.recognition.custom_nets import quantised

RESNET = "rapomdp.recognition.examples:small_resnet"
QUANTISED = "tests.recognition.custom_nets:quantised"
CLASSES = ["cup", "bicycle", "teapot"]
PARAMS = PreprocessParams(input_size_px=32)
#: The closed-loop tests' tiny pipeline, fewer methods and episodes (the recogniser is what
#: is tested here, not the planners).
TINY = {**TINY_PIPELINE, "seed": 5,
        "dataset": {"classes": CLASSES, "split": SMALL_SPLIT},
        "viewpoints": {"count": 16}, "solve": {"timeout_s": 2.0},
        "train": {**TINY_PIPELINE["train"], "network": RESNET},
        "evaluate": {"methods": ["static", "classifier", "ra"], "starts_per_model": 2,
                     "max_moves": 4}}


@pytest.mark.parametrize("value", ["resnet", "my_nets.resnet", "my_nets:", ":resnet",
                                   "my nets:resnet", "my_nets:resnet.build", "AlexNet"])
def test_the_configuration_refuses_a_malformed_network(value: str) -> None:
    with pytest.raises(ConfigError) as info:
        config_from_dict({"train": {"network": value}})
    assert ("train.network: expected 'alexnet' or an import path 'package.module:factory' "
            f"(a module's dotted path, a colon, the name of a function in it) (got {value!r})"
            ) in str(info.value)
    assert config_from_dict({"train": {"network": RESNET}}).train.network == RESNET


@pytest.mark.parametrize(("path", "problem"), [
    ("tests.recognition.nowhere:net",
     "module 'tests.recognition.nowhere' not found (No module named 'tests.recognition.nowhere');"
     " is it installed or on PYTHONPATH?"),
    ("tests.recognition.custom_nets:absent",
     "module 'tests.recognition.custom_nets' has no attribute 'absent'"),
    ("tests.recognition.custom_nets:NOT_CALLABLE",
     "'NOT_CALLABLE' is a int, not callable: expected a function factory(classes, "
     "input_size_px) -> torch.nn.Module"),
    ("tests.recognition.custom_nets:not_a_module",
     "the factory returned a function, not a torch.nn.Module"),
    ("tests.recognition.custom_nets:one_logit_too_many",
     "its output on a probe batch (2, 1, 32, 32) has shape (2, 4); expected logits (2, 3): one "
     "per class"),
    ("tests.recognition.custom_nets:fails",
     "calling it as factory(classes=3, input_size_px=32) failed: RuntimeError: no weights for "
     "this input size"),
])
def test_a_factory_that_cannot_be_used_is_named_with_what_failed(path: str, problem: str) -> None:
    """The train stage builds its network from the configuration: each failure names the key,
    the import path and the problem (a StageError: the command line prints it, no traceback)."""
    train = config_from_dict({"train": {"network": path,
                                        "preprocess": {"input_size_px": 32}}}).train
    with pytest.raises(RecogniserError) as info:
        build_network(network_spec(3, train))
    assert str(info.value) == f"train.network {path!r}: {problem}"
    assert isinstance(info.value, StageError)


def test_a_factory_module_that_fails_to_import_is_told_apart_from_a_missing_one(
        tmp_path, monkeypatch) -> None:
    (tmp_path / "broken_nets.py").write_text("import not_installed_anywhere\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(RecogniserError, match="importing module 'broken_nets' failed: No "
                       "module named 'not_installed_anywhere'"):
        build_recogniser("broken_nets:net", 3, 32)


def test_the_spec_of_a_configuration_and_the_grad_cam_layer() -> None:
    spec = network_spec(3, config_from_dict({"train": {"network": RESNET, "width": 2.0,
                                                       "preprocess": {"input_size_px": 32}}}
                                            ).train)
    assert spec == CustomSpec(RESNET, 3, 32)  # width and dropout are DepthAlexNet's
    assert isinstance(network_spec(3, config_from_dict({}).train), NetworkSpec)
    network = build_network(spec)
    assert isinstance(network, CustomNetwork) and isinstance(network.module, SmallResNet)
    # the module names its layer (the last residual block); else its last Conv2d
    assert network.last_conv is network.module.blocks[-1]
    quantised_net = CustomNetwork(CustomSpec(QUANTISED, 3, 32))
    assert quantised_net.last_conv is quantised_net.module.features[2]
    linear = CustomNetwork(CustomSpec("tests.recognition.custom_nets:linear", 3, 32))
    with pytest.raises(RecogniserError, match="saliency.method 'gradcam' needs a convolution "
                       "to attribute to, and this recogniser has no torch.nn.Conv2d"):
        make_attribution("gradcam", linear, 32)
    maps = make_attribution("gradcam", network.eval(), 32).attribute(
        torch.linspace(-1, 1, 2 * 32 * 32).reshape(2, 1, 32, 32), torch.tensor([0, 2]))
    assert maps.shape == (2, 32, 32) and float(maps.min()) >= 0 and float(maps.max()) <= 1


def test_a_custom_checkpoint_records_its_factory_and_loads_to_the_same_outputs(
        tmp_path, intrinsics, render_model) -> None:
    torch.manual_seed(0)
    network = build_network(CustomSpec(RESNET, len(CLASSES), 32, members=2))
    assert isinstance(network, DepthEnsemble)
    classifier = Classifier(network, CLASSES, PARAMS, intrinsics.fx, intrinsics.fy)
    classifier.save(tmp_path, config_hash="abc123")
    record = read_json(tmp_path / META_FILE)["network"]
    assert record == {"kind": "custom", "factory": RESNET, "classes": 3, "input_size_px": 32,
                      "members": 2}
    loaded = Classifier.load(tmp_path, classes=CLASSES, preprocessing=PARAMS,
                             config_hash="abc123", device="cpu")
    assert [type(m.module) for m in member_networks(loaded.network)] == [SmallResNet] * 2
    depth = render_model("cup", np.array([[0.6, 0.0, 0.1], [0.0, -0.6, 0.2], [0.3, 0.3, 0.4]]))
    np.testing.assert_array_equal(loaded.predict(depth), classifier.predict(depth))
    # a DepthAlexNet's record has no kind, as every checkpoint before the option
    alexnet = Classifier(DepthAlexNet(NetworkSpec(3, 32, width=0.125)), CLASSES, PARAMS,
                         intrinsics.fx, intrinsics.fy)
    alexnet.save(tmp_path / "alexnet", config_hash="abc123")
    assert "kind" not in read_json(tmp_path / "alexnet" / META_FILE)["network"]
    # a factory that is gone: the checkpoint names it and what failed
    meta = read_json(tmp_path / META_FILE)
    meta["network"]["factory"] = "tests.recognition.custom_nets:absent"
    (tmp_path / META_FILE).write_text(json.dumps(meta))
    with pytest.raises(CheckpointError) as info:
        Classifier.load(tmp_path)
    assert str(info.value) == (
        f"{tmp_path / META_FILE}: cannot rebuild the recogniser the checkpoint names: "
        "train.network 'tests.recognition.custom_nets:absent': module "
        "'tests.recognition.custom_nets' has no attribute 'absent'")


def test_the_saliency_method_falls_back_only_from_a_gradient_method(intrinsics,
                                                                     render_model) -> None:
    torch.manual_seed(0)
    depth = render_model("cup", np.array([[0.6, 0.0, 0.1], [0.0, -0.6, 0.2]]))

    def classifier(path: str) -> Classifier:
        return Classifier(build_network(CustomSpec(path, 3, 32)), CLASSES, PARAMS,
                          intrinsics.fx, intrinsics.fy)

    rounding = classifier(QUANTISED)
    assert saliency_method(rounding, depth, 0, "occlusion") == SaliencyMethod("occlusion", None)
    assert saliency_method(rounding, depth, 0, "integrated_gradients") == SaliencyMethod(
        "occlusion", "saliency: the recogniser gives no input gradients (the gradient is zero "
        "on every pixel of 2 views); the black-box method 'occlusion' is used instead of "
        "'integrated_gradients'")
    assert saliency_method(classifier(RESNET), depth, 1, "gradient") == SaliencyMethod(
        "gradient", None)


@pytest.fixture(scope="module")
def resnet_workspace(tmp_path_factory):
    """:data:`TINY` (a small ResNet) run to the evaluate stage."""
    config = config_from_dict(TINY)
    ws = Workspace(tmp_path_factory.mktemp("resnet"))
    run_pipeline(config, ws, until="evaluate", context=TEST_CONTEXT)
    return ws, config


def test_a_small_resnet_runs_from_training_to_the_closed_loop(resnet_workspace) -> None:
    ws, config = resnet_workspace
    root = ws.root
    assert read_json(root / "train" / META_FILE)["network"] == {
        "kind": "custom", "factory": RESNET, "classes": 3, "input_size_px": 32, "members": 1}
    assert config.section("train")["network"] == RESNET  # in the stage keys
    # the checkpoint reloads to the probabilities the classifier_eval stage recorded
    classifier = load_stage_classifier(config, root / "train", CLASSES, threads=1)
    assert isinstance(classifier.network, CustomNetwork)
    assert isinstance(classifier.network.module, SmallResNet)
    stored = load_npz(root / "classifier_eval" / "probabilities.npz")
    xrho = load_xrho_views(root / "xrho", root / "dataset")
    test_models = xrho.dataset.with_role("test")
    again = np.stack([classifier.predict(xrho.load(m).sensed) for m in test_models])
    assert again.shape == stored["xrho"].shape == (3, 16, 3)
    np.testing.assert_allclose(again, stored["xrho"], rtol=0, atol=1e-6)
    # saliency: a ResNet has input gradients, so the configured method ran
    record = read_json(root / "saliency" / "saliency.json")
    assert record["method"] == "mask" and "configured_method" not in record
    maps = [load_npz(p)["saliency"].astype(np.float32)
            for p in sorted((root / "saliency" / "maps").rglob("*.npz"))]
    assert len(maps) == 3 and all(m.max() <= 1 and m.min() >= 0 and m.max() > 0 for m in maps)
    # observe, solve, evaluate
    models = load_npz(root / "observe" / "observation_models.npz")
    assert models["ra"].shape == (16, 3, 3)
    np.testing.assert_allclose(models["ra"].sum(axis=2), 1.0, atol=1e-6)
    assert (root / "solve" / "policy_ra.npz").exists()
    rows = (root / "evaluate" / "table1.csv").read_text().splitlines()
    assert [r.split(",")[:2] for r in rows[1:]] == [["static", "6"], ["classifier", "6"],
                                                    ["ra", "6"]]
    assert all(0 <= float(r.split(",")[2]) <= 1 for r in rows[1:])


def test_a_recogniser_without_input_gradients_gets_the_black_box_saliency(
        resnet_workspace, tmp_path_factory, capsys) -> None:
    source, _ = resnet_workspace
    config = config_from_dict({**TINY, "train": {**TINY["train"], "network": QUANTISED}})
    ws = Workspace(tmp_path_factory.mktemp("quantised"))
    results = run_pipeline(config, ws, until="saliency", context=TEST_CONTEXT,
                           share_from=[source])
    assert [r.name for r in results if r.shared_from] == ["dataset", "render"]
    note = ("saliency: the recogniser gives no input gradients (the gradient is zero on every "
            "pixel of 8 views); the black-box method 'occlusion' is used instead of 'mask'")
    assert note in capsys.readouterr().err.splitlines()
    record = read_json(ws.root / "saliency" / "saliency.json")
    assert record["method"] == "occlusion"
    assert record["configured_method"] == "mask" and record["method_note"] == note
    assert record["config"]["method"] == "mask"
    maps = [load_npz(p)["saliency"].astype(np.float32)
            for p in sorted((ws.root / "saliency" / "maps").rglob("*.npz"))]
    assert len(maps) == 3 and all(m.max() <= 1 and m.min() >= 0 for m in maps)
    # its weights trained: the gradient of the loss reaches them through the quantisation
    torch.manual_seed(member_seed(config.train_seed, 0))
    initial = quantised(3, 32).state_dict()
    trained = load_stage_classifier(config, ws.root / "train", CLASSES).network.state_dict()
    assert not torch.equal(trained["module.head.weight"], initial["head.weight"])


def test_an_ensemble_of_a_custom_recogniser_trains_each_member_from_its_own_seed(
        resnet_workspace, tmp_path) -> None:
    source, _ = resnet_workspace
    config = config_from_dict({**TINY, "train": {**TINY["train"], "network": QUANTISED,
                                                 "ensemble": 2, "epochs": 1}})
    inputs = StageInputs.of("train", {"dataset": source.root / "dataset",
                                      "render": source.root / "render"})
    run_train_stage(config, inputs, tmp_path, TEST_CONTEXT)
    assert read_json(tmp_path / META_FILE)["network"]["members"] == 2
    classifier = load_stage_classifier(config, tmp_path, CLASSES)
    first, second = member_networks(classifier.network)
    assert isinstance(classifier.network, DepthEnsemble)
    assert not torch.equal(first.module.head.weight, second.module.head.weight)
    assert read_json(tmp_path / "metrics.json")["ensemble"] == 2


def test_the_train_stage_refuses_a_factory_that_cannot_be_used(resnet_workspace,
                                                              tmp_path) -> None:
    source, _ = resnet_workspace
    config = config_from_dict({**TINY, "train": {**TINY["train"],
                                                 "network": "tests.recognition.custom_nets:fails"}})
    inputs = StageInputs.of("train", {"dataset": source.root / "dataset",
                                      "render": source.root / "render"})
    with pytest.raises(RecogniserError, match=r"^train.network 'tests.recognition.custom_nets:"
                       r"fails': calling it as factory\(classes=3, input_size_px=32\) failed"):
        run_train_stage(config, inputs, tmp_path, TEST_CONTEXT)
    assert list(tmp_path.iterdir()) == []
