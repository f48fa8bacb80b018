"""The network and its training: a separable toy set is learned; views are split per model; an
ensemble's members are trained from their own seeds."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rapomdp.config import PreprocessConfig, TrainConfig
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.network import DepthAlexNet, DepthEnsemble, NetworkSpec
from rapomdp.recognition.training import (
    LabelledViews,
    member_seed,
    network_spec,
    train_classifier,
    validation_mask,
)

TOY_CLASSES = ["disc", "cross", "bar", "ring"]


def toy_views(per_class: int, seed: int) -> LabelledViews:
    """Depth images (160x120) of four flat shapes at random distance, size, place and tilt."""
    rng = np.random.default_rng(seed)
    n = per_class * len(TOY_CLASSES)
    labels = np.repeat(np.arange(len(TOY_CLASSES)), per_class)
    v, u = np.mgrid[0:120, 0:160].astype(np.float32)
    distance = rng.uniform(0.5, 0.8, n)[:, None, None]
    half = (rng.uniform(0.08, 0.12, n) * 144.3)[:, None, None] / distance  # pixels
    du = u[None] - (80 + rng.uniform(-15, 15, n))[:, None, None]
    dv = v[None] - (60 + rng.uniform(-10, 10, n))[:, None, None]
    r = np.hypot(du, dv)
    shapes = {
        0: r <= half,
        1: (np.abs(du) <= half) & (np.abs(dv) <= half)
        & ((np.abs(du) <= 0.3 * half) | (np.abs(dv) <= 0.3 * half)),
        2: (np.abs(du) <= 1.6 * half) & (np.abs(dv) <= 0.3 * half),
        3: (r <= half) & (r >= 0.6 * half),
    }
    mask = np.select([labels[:, None, None] == k for k in shapes], list(shapes.values()))
    tilt = rng.uniform(-0.001, 0.001, (n, 1, 1)) * du
    depth = np.where(mask, distance + tilt, 0.0).astype(np.float32)
    return LabelledViews(depth, labels, labels.copy(), np.arange(n))


def test_network_shapes_follow_the_spec():
    spec = NetworkSpec(classes=7, input_size_px=64, width=0.25)
    net = DepthAlexNet(spec)
    assert net.feature_shape == (64, 3, 3)
    assert net(torch.zeros(5, 1, 64, 64)).shape == (5, 7)
    linear = [m for m in net.modules() if isinstance(m, torch.nn.Linear)]
    assert len(linear) == 1 and linear[0].in_features == 64 * 3 * 3  # one linear layer
    assert isinstance(net.last_conv, torch.nn.Conv2d) and net.last_conv.out_channels == 64


def test_network_learns_a_separable_toy_set():
    cfg = TrainConfig(
        width=0.125, epochs=16, batch_size=32, learning_rate=1e-3, dropout=0.0,
        preprocess=PreprocessConfig(input_size_px=32),
    )
    train, val = toy_views(60, seed=1), toy_views(25, seed=2)
    classifier, history = train_classifier(
        train, val, TOY_CLASSES, cfg, 144.3, 144.3, seed=0, device=torch.device("cpu")
    )
    assert history.val_accuracy[-1] > 0.95
    assert history.train_loss[-1] < history.train_loss[0]
    probabilities = classifier.predict(val.depth)
    assert probabilities.shape == (len(val), 4)
    np.testing.assert_allclose(probabilities.sum(axis=1), 1.0, atol=1e-5)
    assert (probabilities.argmax(axis=1) == val.labels).mean() > 0.95


def test_a_normals_network_learns_the_toy_set_with_the_preprocessing_scale(tmp_path):
    """The network trains with the normals layer, its scale the input's depth unit over its
    pixel side (0.2 m · 32 px / 0.5 m), keeps its last epoch, and the checkpoint rebuilds it."""
    cfg = TrainConfig(width=0.125, epochs=8, batch_size=32, dropout=0.0,
                      preprocess=PreprocessConfig(input_size_px=32))
    spec = network_spec(4, cfg)
    assert spec.input_channels == 4
    assert spec.normal_scale == pytest.approx(0.2 * 32 / 0.5) and spec.input_background == -1.0
    train, val = toy_views(40, seed=1), toy_views(20, seed=2)
    classifier, history = train_classifier(train, val, TOY_CLASSES, cfg, 144.3, 144.3, seed=0,
                                           device=torch.device("cpu"))
    network = classifier.network
    assert isinstance(network, DepthAlexNet) and network.spec == spec
    assert history.train_loss[-1] < 0.5 * history.train_loss[0]
    assert history.val_accuracy[-1] > 0.6  # chance 0.25
    assert history.kept == [0] * 7 + [1]  # the last epoch's weights
    classifier.save(tmp_path, config_hash="abc123")
    loaded = Classifier.load(tmp_path)
    assert loaded.network.spec == spec
    np.testing.assert_array_equal(loaded.predict(val.depth), classifier.predict(val.depth))


def test_training_is_deterministic_for_a_seed():
    cfg = TrainConfig(width=0.125, epochs=1, batch_size=32,
                      preprocess=PreprocessConfig(input_size_px=32))
    data = toy_views(10, seed=3)
    runs = [train_classifier(data, data, TOY_CLASSES, cfg, 144.3, 144.3, seed=5,
                             device=torch.device("cpu"))[0].predict(data.depth) for _ in range(2)]
    np.testing.assert_array_equal(runs[0], runs[1])


def test_extents_found_once_train_the_network_of_extents_found_per_batch(monkeypatch):
    from rapomdp.recognition import training

    cfg = TrainConfig(width=0.125, epochs=2, batch_size=32,
                      preprocess=PreprocessConfig(input_size_px=32))
    data = toy_views(10, seed=3)

    def weights() -> list[torch.Tensor]:
        classifier, _ = train_classifier(data, data, TOY_CLASSES, cfg, 144.3, 144.3, seed=5,
                                         device=torch.device("cpu"))
        return list(classifier.network.state_dict().values())

    once = weights()
    monkeypatch.setattr(training, "object_extents", lambda depth: None)  # per batch, as before
    per_batch = weights()
    assert all(torch.equal(a, b) for a, b in zip(once, per_batch, strict=True))


def test_validation_holds_out_a_fraction_of_every_models_views():
    models = np.repeat(np.arange(4), 50)
    data = LabelledViews(np.zeros((200, 2, 2), np.float32), models, models, np.arange(200))
    held = validation_mask(data, 0.1, np.random.default_rng(0))
    np.testing.assert_array_equal(np.bincount(models[held]), [5, 5, 5, 5])
    assert not validation_mask(data, 0.0, np.random.default_rng(0)).any()


def test_noise_augmentation_perturbs_only_the_object():
    from rapomdp.config import AugmentConfig, NoiseConfig
    from rapomdp.recognition.training import augment_batch

    depth = toy_views(4, seed=4).depth
    noisy, shift, scale = augment_batch(
        depth, AugmentConfig(noise=True, shift=0.05, scale=0.1), NoiseConfig(),
        np.random.default_rng(0))
    object_px = depth > 0
    np.testing.assert_array_equal(noisy > 0, object_px)  # no holes: surface angles unknown
    error = np.abs(noisy - depth)[object_px]
    assert 0.0005 < error.mean() < 0.01  # millimetres: axial noise and disparity steps
    assert np.all(np.abs(shift) <= 0.05) and np.all((scale >= 0.9 - 1e-9) & (scale <= 1.1))


def test_a_kept_epoch_far_below_the_best_gets_a_note_naming_both():
    from rapomdp.recognition.training import History, validation_drop_note

    def history(curves: list[list[float]], kept: list[int]) -> History:
        h = History()
        for member, (curve, k) in enumerate(zip(curves, kept, strict=True)):
            for epoch, accuracy in enumerate(curve, start=1):
                h.member.append(member)
                h.epoch.append(epoch)
                h.val_accuracy.append(accuracy)
                h.kept.append(int(epoch == k))
        return h

    collapsed = [0.60, 0.708, 0.60, 0.706, 0.589, 0.405]  # the study's default seed 1, late
    note = validation_drop_note(history([collapsed], kept=[6]))
    assert note is not None and "kept epoch 6 validates 0.405, epoch 2 0.708" in note
    assert "another seed (train.seed)" in note
    # the best epoch kept, or a last epoch within 0.05 of the best: nothing to say
    assert validation_drop_note(history([collapsed], kept=[2])) is None
    assert validation_drop_note(history([[0.60, 0.70, 0.66]], kept=[3])) is None
    # an ensemble names the member; no validation views (NaN) says nothing
    two = validation_drop_note(history([[0.7, 0.7], [0.7, 0.6]], kept=[2, 2]))
    assert two is not None and "member 2: the kept epoch 2 validates 0.600" in two
    assert "member 1" not in two
    assert validation_drop_note(history([[float("nan")] * 3], kept=[3])) is None


def test_an_ensemble_is_its_members_trained_from_their_own_seeds():
    cfg = TrainConfig(width=0.125, epochs=2, batch_size=32,
                      preprocess=PreprocessConfig(input_size_px=32))
    data = toy_views(10, seed=3)
    single, _ = train_classifier(data, data, TOY_CLASSES, cfg, 144.3, 144.3, seed=5,
                                 device=torch.device("cpu"), progress=False)
    ensemble, history = train_classifier(
        data, data, TOY_CLASSES, cfg.model_copy(update={"ensemble": 3}), 144.3, 144.3,
        seed=5, device=torch.device("cpu"), progress=False)
    assert isinstance(ensemble.network, DepthEnsemble)
    assert ensemble.network.spec.members == 3
    assert history.member == [0, 0, 1, 1, 2, 2] and history.epoch == [1, 2] * 3
    inputs = torch.from_numpy(ensemble.preprocess(data.depth).images)
    with torch.inference_mode():
        members = [torch.softmax(m(inputs), dim=1).numpy() for m in ensemble.network.members]
    # the first member is the single classifier of the seed; the others are other draws
    np.testing.assert_array_equal(members[0], single.predict(data.depth))
    assert not np.allclose(members[1], members[0]) and not np.allclose(members[2], members[1])
    np.testing.assert_allclose(ensemble.predict(data.depth), np.mean(members, axis=0),
                               atol=1e-6)


def test_member_seeds_are_the_seed_then_draws_no_other_seed_shares():
    assert member_seed(7, 0) == 7
    seeds = {member_seed(s, m) for s in range(4) for m in range(1, 4)}
    assert len(seeds) == 12 and not seeds & set(range(4))
    assert member_seed(7, 2) == member_seed(7, 2)
