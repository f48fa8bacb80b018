"""Do the observation models' wrong labels transfer to new objects?

The belief of RA-POMDP and of the Classifier POMDP fuses the CNN's labels through
P(o | class, viewpoint), fitted on the held-out (volume) objects: P(correct) on the diagonal,
and the *wrong-label* part — where a class's mistakes go — counted on those few objects
(``wrong_label_distribution`` with ``observe.confusion_pseudo_count`` for the RA variants,
the per-viewpoint counts with ``observe.classifier_pseudo_count`` for the Classifier,
kernel-pooled counts for ``ra_transfer``). This benchmark shrinks only that part toward uniform
wrong labels, keeping each row's P(correct):

    P_a(o | c, x) = (1 - a) P(o | c, x) + a (1 - P(c | c, x)) / (C - 1)    for o != c

and measures, per workspace:

1. **held out** (may drive a choice): each volume group (the k-th volume model of every class)
   scored by the models the observe stage fits without it (:func:`held_out_groups`,
   :func:`fit_observation_models`; a class's rows only read its own objects, so this is
   leave-one-object-out for every wrong-label row), shrunk by each ``a``: the mean
   log-likelihood per observation and per object, the mean log-share of the wrong label among
   the wrong labels (the term ``a`` changes), the paired difference to today's model (a = 0)
   with its standard error over held-out objects, and the belief temperature refitted on the
   observe stage's held-out walks (:func:`held_out_temperatures`) with that walk's belief log
   loss; also a joint grid with P(correct) mixed toward the classes' mean by ``b``
   (:func:`shrink_correct`), the RA wrong labels' ``confusion_pseudo_count`` refitted over a
   grid, and whether leave-one-object-out among the held-out objects predicts how the counts
   carry to the test models (top wrong label's share, per-class accuracy gap, one-view
   accuracy level; the test side a diagnostic);
2. **an upper-bound diagnostic on the test episodes** (reads the test models' outcomes: it may
   not drive a choice): every recorded RA-POMDP and Classifier-POMDP episode's views re-fused by
   (a) the workspace's own belief (checked against the recorded declarations and beliefs),
   (b) uniform wrong labels (a = 1) and (c) the held-out-chosen ``a``, each tempered by the
   recorded temperature and by the one refitted for ``a``, (f) the held-out-chosen (a, b),
   (d, e) the recorded one-calibration ``ra_paper`` as it is and with a = 1; beside the majority
   vote and the mean softmax of the same views. Accuracy and mean confidence (final belief in
   the declared class) - accuracy; the views' one-view label accuracy, start and later;
3. per class on the test episodes: what the method declares, its recall, the CNN's one-view
   accuracy on the test and the held-out objects, and the model's P(correct).

Only workspaces whose ``report/`` exists are read; nothing is written into them.

    OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/confusion_transfer.py \\
        --root runs/study-learned [--workspaces learned/seed-0 ...] \\
        [--alphas 0 0.25 0.5 0.75 0.9 1] [--per-class real-cad-dev-learned/seed-0]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.awareness.evidence import Evidence, observed_probabilities
from rapomdp.awareness.mixture import MIXTURE_VARIANT
from rapomdp.awareness.observation import ObservationModel
from rapomdp.awareness.temperature import held_out_temperatures
from rapomdp.awareness.variants import fit_observation_models
from rapomdp.data.dataset import load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.experiment.methods import BayesBelief
from rapomdp.io import load_npz
from rapomdp.recognition.belief import (
    TEMPERATURE_NEIGHBOURS,
    TEMPERATURE_WALK_LENGTH,
    TEMPERATURE_WALKS_PER_ROW,
    held_out_groups,
    temper,
)
from rapomdp.workspace import Workspace

ALPHAS = (0.0, 0.25, 0.5, 0.75, 0.9, 1.0)
PSEUDO_COUNTS = (0.0, 1.0, 4.0, 16.0, 64.0, 256.0)
METHODS = {"ra": "RA-POMDP", "classifier": "Classifier"}


def shrink_wrong_labels(probabilities: np.ndarray, alpha: float) -> np.ndarray:
    """The model (V, C, C) with each row's wrong labels mixed toward uniform by ``alpha``,
    its P(correct) kept (0: the model; 1: uniform wrong labels)."""
    p = np.asarray(probabilities, dtype=np.float64)
    c = p.shape[2]
    if p.shape[1] != c:
        raise ValueError("typed models (observe.belief: nuisance) are not handled")
    idx = np.arange(c)
    right = p[:, idx, idx]  # (V, C)
    out = (1.0 - alpha) * p + alpha * ((1.0 - right) / (c - 1))[:, :, None]
    out[:, idx, idx] = right
    return out


def shrink_correct(probabilities: np.ndarray, beta: float) -> np.ndarray:
    """The model (V, C, C) with each class's P(correct | c, x) mixed by ``beta`` toward the
    mean over the classes at x, its wrong labels rescaled to the rest (proportions kept)."""
    p = np.asarray(probabilities, dtype=np.float64)
    idx = np.arange(p.shape[2])
    right = p[:, idx, idx]  # (V, C)
    moved = (1.0 - beta) * right + beta * right.mean(axis=1, keepdims=True)
    out = p * ((1.0 - moved) / np.maximum(1.0 - right, 1e-12))[:, :, None]
    out[:, idx, idx] = moved
    return out


def wrong_log_share(model: np.ndarray, labels: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """log P(o | c, x, o != c) of each wrong outcome (flat): the term the shrinkage changes."""
    observed, right = observed_probabilities(model, labels, predicted)
    wrong = predicted != labels[:, None]
    return np.log(np.maximum(observed[wrong], 1e-300)) - np.log(np.maximum(1.0 - right[wrong],
                                                                          1e-300))


class Held:
    """One workspace's held-out evidence and its leave-one-group-out fits."""

    def __init__(self, root: Path) -> None:
        self.workspace = Workspace(root)
        self.config = self.workspace.config()
        self.recorded = RecordedObservation.load(root / "observe")
        if self.recorded.variant == f"ra_{MIXTURE_VARIANT}":  # refits single variants by name
            raise SystemExit(f"{root}: RA-POMDP's model is the mixture of RA variants "
                             "(observe.ra_model: mixture); this benchmark refits one "
                             "variant by name: run it on a workspace with ra_model auto "
                             "or a variant")
        self.evidence: Evidence = self.recorded.evidence
        self.directions = self.recorded.arrays["directions"]
        self.names = {"ra": self.recorded.variant, "classifier": "classifier"}
        self.masks = held_out_groups(self.evidence.labels, self.evidence.groups)
        self.folds = [self.fit(self.evidence.subset(~held)) for held in self.masks]
        self.full = self.fit(self.evidence)
        self._temperatures: dict[tuple[str, float, float], tuple[float, float]] = {}

    def fit(self, part: Evidence, pseudo_count: float | None = None) -> dict[str, np.ndarray]:
        cfg = self.config.observe
        if pseudo_count is not None:
            cfg = cfg.model_copy(update={"confusion_pseudo_count": pseudo_count})
        rec = self.recorded
        fitted = fit_observation_models(part, rec.scores, rec.classes, cfg, self.directions,
                                        rec.transfer_kernel, set(self.names.values()))
        return {key: fitted[name].probabilities for key, name in self.names.items()}

    def score(self, key: str, folds: list[dict[str, np.ndarray]], alpha: float,
              beta: float = 0.0) -> dict[str, np.ndarray]:
        """Per held-out object: mean log-likelihood over its views; flat wrong log-shares
        (``beta``: P(correct) shrunk toward the classes' mean, :func:`shrink_correct`)."""
        per_object = np.full(len(self.evidence.labels), np.nan)
        shares = []
        for held, models in zip(self.masks, folds, strict=True):
            part = self.evidence.subset(held)
            model = shrink_correct(shrink_wrong_labels(models[key], alpha), beta)
            observed, _ = observed_probabilities(model, part.labels, part.predicted)
            per_object[held] = np.log(np.maximum(observed, 1e-300)).mean(axis=1)
            shares.append(wrong_log_share(model, part.labels, part.predicted))
        return {"object": per_object, "wrong": np.concatenate(shares)}

    def test_score(self, key: str, alpha: float) -> dict[str, float]:
        """The test models' labels at every X_rho viewpoint under the model fitted on all the
        held-out evidence, shrunk by ``alpha`` (a diagnostic: reads the test models)."""
        labels = self.recorded.arrays["test_labels"]
        predicted = self.recorded.arrays["test_predictions"]
        model = shrink_wrong_labels(self.full[key], alpha)
        observed, _ = observed_probabilities(model, labels, predicted)
        return {"ll": float(np.log(np.maximum(observed, 1e-300)).mean()),
                "wrong": float(wrong_log_share(model, labels, predicted).mean())}

    def temperature(self, key: str, alpha: float, beta: float = 0.0) -> tuple[float, float]:
        """The belief temperature refitted with the shrunk fold models on the observe stage's
        held-out walks (same seed) and those walks' tempered belief log loss."""
        if (key, alpha, beta) in self._temperatures:
            return self._temperatures[key, alpha, beta]
        folds = [(held, {key: ObservationModel(
                    shrink_correct(shrink_wrong_labels(m[key], alpha), beta),
                    self.recorded.classes)})
                 for held, m in zip(self.masks, self.folds, strict=True)]
        t, report = held_out_temperatures(
            self.evidence, folds, self.directions, TEMPERATURE_WALK_LENGTH,
            TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS,
            class_seed(self.config.seed, "observe/temperature"))
        self._temperatures[key, alpha, beta] = t[key], report[key]["log_loss_tempered"]
        return self._temperatures[key, alpha, beta]


def held_out_table(held: Held, key: str, alphas: tuple[float, ...]
                   ) -> tuple[list[dict[str, float]], float]:
    rows = []
    base = held.score(key, held.folds, 0.0)["object"]
    covered = ~np.isnan(base)
    correct = held.evidence.correct[covered]
    for alpha in alphas:
        s = held.score(key, held.folds, alpha)
        d = (s["object"] - base)[covered]
        t, walk_loss = held.temperature(key, alpha)
        test = held.test_score(key, alpha)
        rows.append({"alpha": alpha, "ll_obs": float(np.nanmean(s["object"])),
                     "test_ll": test["ll"], "test_wrong": test["wrong"],
                     "wrong_share": float(s["wrong"].mean()), "diff": float(d.mean()),
                     "se": float(d.std(ddof=1) / np.sqrt(d.size)),
                     "better": float((d > 0).mean()), "t": t, "walk_loss": walk_loss})
    # every object's views count alike, so mean per observation = mean per object
    best = max(rows, key=lambda r: r["ll_obs"])["alpha"]
    print(f"  {METHODS[key]} ({held.names[key]}): {int(covered.sum())} held-out objects, "
          f"{correct.size} labels, {1 - correct.mean():.3f} wrong; "
          f"recorded temperature {recorded_temperature(held, key):.3f}")
    print(f"    {'a':>5} {'LL/obs':>8} {'log wrong-share':>15} {'dLL/obj vs a=0':>16} "
          f"{'(se)':>8} {'objs better':>11} {'T(a)':>6} {'walk logloss':>12} "
          f"{'| test LL/obs':>13} {'test wrong-share':>16}")
    for r in rows:
        mark = " <- LOO best" if r["alpha"] == best else ""
        print(f"    {r['alpha']:5.2f} {r['ll_obs']:8.4f} {r['wrong_share']:15.4f} "
              f"{r['diff']:+16.4f} {r['se']:8.4f} {r['better']:11.2f} {r['t']:6.3f} "
              f"{r['walk_loss']:12.4f} | {r['test_ll']:11.4f} {r['test_wrong']:16.4f}{mark}")
    print("    (the last two columns: the test models' one-view labels under the model fitted on "
          "every held-out object: a diagnostic, not for choosing)")
    return rows, best


def pseudo_count_table(held: Held, counts: tuple[float, ...]) -> None:
    """RA's wrong labels refitted with other ``confusion_pseudo_count`` (a = 0)."""
    print(f"  RA-POMDP ({held.names['ra']}) refitted with observe.confusion_pseudo_count "
          f"(today {held.config.observe.confusion_pseudo_count:g}):")
    print(f"    {'count':>6} {'LL/obs':>8} {'log wrong-share':>15}")
    for k in counts:
        folds = [held.fit(held.evidence.subset(~m), k) for m in held.masks]
        s = held.score("ra", folds, 0.0)
        print(f"    {k:6g} {np.nanmean(s['object']):8.4f} {s['wrong'].mean():15.4f}")


BETAS = (0.0, 0.25, 0.5, 0.75, 1.0)


def joint_table(held: Held, key: str, alphas: tuple[float, ...]) -> tuple[float, float]:
    """Held-out LL per observation over (a, b): wrong labels toward uniform by a, P(correct)
    toward the classes' mean by b; returns the best (a, b)."""
    base = held.score(key, held.folds, 0.0)["object"]
    covered = ~np.isnan(base)
    grid = {}
    for alpha in alphas:
        for beta in BETAS:
            grid[alpha, beta] = held.score(key, held.folds, alpha, beta)["object"]
    best = max(grid, key=lambda ab: np.nanmean(grid[ab]))
    d = (grid[best] - base)[covered]
    print(f"  {METHODS[key]}: held-out LL/obs with P(correct) shrunk toward the classes' mean "
          f"by b (rows) and wrong labels by a (columns); best (a, b) = {best}, "
          f"{d.mean():+.4f} ± {d.std(ddof=1) / np.sqrt(d.size):.4f} per object vs (0, 0)")
    corner = "b \\ a"
    print(f"    {corner:>6}" + "".join(f"{a:8.2f}" for a in alphas))
    for beta in BETAS:
        print("    " + f"{beta:6.2f}" + "".join(f"{np.nanmean(grid[a, beta]):8.4f}"
                                             for a in alphas))
    return best


def recorded_temperature(held: Held, key: str) -> float:
    arrays = held.recorded.arrays
    names = [str(n) for n in arrays["models"]]
    return float(arrays["temperatures"][names.index(key)])


def fuse(model: np.ndarray, viewpoints: np.ndarray, labels: np.ndarray,
         offsets: np.ndarray) -> np.ndarray:
    """Final beliefs (E, C) of episodes from a uniform prior, every step by ``model``:
    :class:`BayesBelief`, the closed loop's own update, on the labels."""
    belief = BayesBelief(model)
    one_hot = np.eye(model.shape[2])
    finals = []
    for start, end in zip(offsets[:-1], offsets[1:], strict=True):
        belief.reset()
        for j in range(start, end):
            belief.update(int(viewpoints[j]), one_hot[labels[j]])
        finals.append(belief.belief)
    return np.array(finals)


def episode_diagnostic(held: Held, root: Path, best: dict[str, float],
                       joint: dict[str, tuple[float, float]]
                       ) -> dict[str, dict[str, np.ndarray]]:
    e = load_npz(root / "evaluate" / "episodes.npz")
    arrays = held.recorded.arrays
    out = {}
    print(f"  {'method':<11} {'belief':<34} {'acc':>6} {'conf-acc':>9}")
    for key in METHODS:
        which = np.flatnonzero(e["method"] == key)
        starts, ends = e["offsets"][which], e["offsets"][which + 1]
        steps = np.concatenate([np.arange(s, t) for s, t in zip(starts, ends, strict=True)])
        offsets = np.r_[0, np.cumsum(ends - starts)]
        views, outputs = e["step_viewpoints"][steps], e["step_outputs"][steps]
        labels = outputs.argmax(axis=1)
        truth = e["class_index"][which]
        # (a) the workspace's own belief, checked step by step against the record
        model = arrays[key]
        b = BayesBelief(model)
        worst = 0.0
        for i, (s, t) in enumerate(zip(starts, ends, strict=True)):
            b.reset()
            for j in range(s, t):
                b.update(int(e["step_viewpoints"][j]), e["step_outputs"][j])
                worst = max(worst, float(np.abs(b.belief - e["step_beliefs"][j]).max()))
            if int(np.argmax(b.belief)) != int(e["declared"][which[i]]):
                raise SystemExit(f"{root}: episode {which[i]} does not reproduce")
        own = fuse(model, views, labels, offsets)
        if not np.array_equal(own.argmax(axis=1), e["declared"][which]):
            raise SystemExit(f"{root}: the re-fused declarations differ from the record")
        t_rec = recorded_temperature(held, key)
        refit_same = np.allclose(temper(held.full[key], t_rec), model, atol=1e-9)
        rows = [("(a) workspace's own", own, own.max(axis=1))]
        for alpha, label in ((1.0, "(b) a=1"), (best[key], f"(c) LOO a={best[key]:g}")):
            shrunk = shrink_wrong_labels(held.full[key], alpha)
            t_new, _ = held.temperature(key, alpha)
            for t, how in ((t_rec, f"T rec {t_rec:.3f}"), (t_new, f"T refit {t_new:.3f}")):
                m = temper(shrunk, t)
                f = fuse(m, views, labels, offsets)
                rows.append((f"{label}, {how}", f, f.max(axis=1)))
        a, b_ = joint[key]
        m = shrink_correct(shrink_wrong_labels(held.full[key], a), b_)
        t_joint, _ = held.temperature(key, a, b_)
        m = temper(m, t_joint)
        rows.append((f"(f) LOO (a,b)=({a:g},{b_:g}), T {t_joint:.3f}",
                     fuse(m, views, labels, offsets), None))
        if key == "ra" and "ra_paper" in arrays and held.names["ra"] != "ra_paper":
            # one P(correct) calibration for every class (no per-class intercepts), recorded
            paper = arrays["ra_paper"]
            rows.append(("(d) recorded ra_paper", fuse(paper, views, labels, offsets),
                         None))
            t_paper = recorded_temperature(held, "ra_paper")
            flat = temper(shrink_wrong_labels(temper(paper, 1.0 / t_paper), 1.0), t_paper)
            rows.append(("(e) ra_paper a=1, T rec", fuse(flat, views, labels, offsets),
                         None))
        votes = np.add.reduceat(np.eye(outputs.shape[1])[labels], offsets[:-1], axis=0)
        mean_soft = np.add.reduceat(outputs, offsets[:-1], axis=0)
        static = e["correct"][e["method"] == "static"].mean()
        for label, belief, conf in rows:
            conf = belief.max(axis=1) if conf is None else conf
            acc = (belief.argmax(axis=1) == truth).mean()
            print(f"  {METHODS[key]:<11} {label:<34} {acc:6.3f} {conf.mean() - acc:+9.3f}")
        vote_acc = (votes.argmax(axis=1) == truth).mean()
        soft_acc = (mean_soft.argmax(axis=1) == truth).mean()
        print(f"  {METHODS[key]:<11} {'majority vote / mean softmax':<34} "
              f"{vote_acc:6.3f} / {soft_acc:.3f}   (Static {static:.3f}; {which.size} "
              f"episodes, {np.mean(ends - starts):.1f} views; belief max |diff| to record "
              f"{worst:.1e}; refit = recorded model: {refit_same})")
        step_truth = np.repeat(truth, ends - starts)
        right = labels == step_truth
        first = np.zeros(right.size, dtype=bool)
        first[offsets[:-1]] = True
        per_model = (held.recorded.arrays["test_predictions"]
                     == held.recorded.arrays["test_labels"][:, None]).mean(axis=1)
        files = [m.file for m in load_dataset(root / "dataset").with_role("test")]
        step_model = np.repeat([files.index(f) for f in e["model"][which]], ends - starts)
        adjusted = right - per_model[step_model]
        print(f"  {METHODS[key]:<11} one-view label accuracy on its views: start "
              f"{right[first].mean():.3f}, later {right[~first].mean():.3f}; minus the same "
              f"test model's mean over every X_rho view: start {adjusted[first].mean():+.3f}, "
              f"later {adjusted[~first].mean():+.3f}")
        out[key] = {"truth": truth, "declared": own.argmax(axis=1),
                    "uniform": rows[2][1].argmax(axis=1), "labels": labels,
                    "offsets": offsets}
    return out


def per_class(held: Held, root: Path, fused: dict[str, dict[str, np.ndarray]]) -> None:
    e = load_npz(root / "evaluate" / "episodes.npz")
    arrays = held.recorded.arrays
    classes = held.recorded.classes
    c = len(classes)
    tl, tp = arrays["test_labels"], arrays["test_predictions"]
    test_acc = np.array([(tp[tl == k] == k).mean() for k in range(c)])
    ev = held.evidence
    held_acc = np.array([ev.correct[ev.labels == k].mean() for k in range(c)])
    static = e["method"] == "static"
    s_decl = np.bincount(e["declared"][static], minlength=c)
    s_recall = np.array([e["correct"][static & (e["class_index"] == k)].mean()
                         for k in range(c)])
    print(f"  {'class':<14} {'held-out acc':>12} {'test 1-view':>11} {'P(c|c) ra':>9} "
          f"{'Static decl/rec':>15} {'RA decl/rec':>12} {'RA a=1 decl/rec':>15} "
          f"{'Clf decl/rec':>12} {'test labels ->':>14}")
    p_ra = np.diagonal(held.full["ra"], axis1=1, axis2=2).mean(axis=0)
    for k in range(c):
        cols = []
        for key, which in (("ra", "declared"), ("ra", "uniform"), ("classifier", "declared")):
            d, t = fused[key][which], fused[key]["truth"]
            cols.append(f"{(d == k).sum():4d}/{(d[t == k] == k).mean():.2f}")
        top = np.bincount(tp[tl == k].ravel(), minlength=c)
        top[k] = 0
        print(f"  {classes[k]:<14} {held_acc[k]:12.3f} {test_acc[k]:11.3f} {p_ra[k]:9.3f} "
              f"{s_decl[k]:8d}/{s_recall[k]:.2f} {cols[0]:>12} {cols[1]:>15} {cols[2]:>12} "
              f"{classes[int(top.argmax())]:>14}")
    print(f"  (decl: episodes declaring the class of {len(fused['ra']['truth'])}; rec: recall "
          f"on the class's episodes; 'test labels ->': the test models' most frequent wrong "
          f"label, one view)")
    # where the wrong labels go, held out vs the test models: the share of a class's wrong
    # labels that fall on the held-out objects' most frequent wrong label
    top_held = np.zeros(c, np.int64)
    share_test, share_held = [], []
    for k in range(c):
        hw = ev.predicted[ev.labels == k].ravel()
        hw = hw[hw != k]
        tw = tp[tl == k].ravel()
        tw = tw[tw != k]
        if hw.size == 0 or tw.size == 0:
            continue
        top_held[k] = np.bincount(hw, minlength=c).argmax()
        share_held.append((hw == top_held[k]).mean())
        share_test.append((tw == top_held[k]).mean())
    print(f"  held-out objects' top wrong label per class: takes {np.mean(share_held):.3f} of "
          f"the held-out wrong labels and {np.mean(share_test):.3f} of the test models' "
          f"(mean over classes; uniform would be {1 / (c - 1):.3f})")


def transfer_check(held: Held) -> None:
    """Does leave-one-object-out among the held-out objects predict how the held-out counts
    transfer to the test models? Per class: the share of an object's wrong labels on the top
    wrong label of the *other* objects, and the gap between an object's accuracy and theirs;
    held out (each object against the other held-out objects of its class) and test (each
    test model against every held-out object of its class; a diagnostic)."""
    ev, arrays = held.evidence, held.recorded.arrays
    tl, tp = arrays["test_labels"], arrays["test_predictions"]
    c = len(held.recorded.classes)

    def measures(obj_pred: np.ndarray, k: int, rest_pred: np.ndarray) -> tuple[float, float]:
        rest_wrong = rest_pred[rest_pred != k]
        own_wrong = obj_pred[obj_pred != k]
        share = np.nan
        if rest_wrong.size and own_wrong.size:
            share = float((own_wrong == np.bincount(rest_wrong, minlength=c).argmax()).mean())
        return share, abs(float((obj_pred == k).mean() - (rest_pred == k).mean()))

    loo, test = [], []
    for k in range(c):
        rows = np.flatnonzero(ev.labels == k)
        for r in rows:
            loo.append(measures(ev.predicted[r], k, ev.predicted[rows[rows != r]].ravel()))
        for r in np.flatnonzero(tl == k):
            test.append(measures(tp[r], k, ev.predicted[rows].ravel()))
    loo_a, test_a = np.array(loo), np.array(test)
    print(f"  transfer of the held-out counts to a new object ({len(loo)} held-out objects "
          f"LOO; {len(test)} test models, diagnostic):")
    print(f"    share of its wrong labels on the others' top wrong label: held out "
          f"{np.nanmean(loo_a[:, 0]):.3f}, test {np.nanmean(test_a[:, 0]):.3f} "
          f"(uniform {1 / (c - 1):.3f})")
    print(f"    |its accuracy - the others' accuracy| (class's objects): held out "
          f"{loo_a[:, 1].mean():.3f}, test {test_a[:, 1].mean():.3f}")
    held_acc = ev.correct.mean(axis=1)
    test_acc = (tp == tl[:, None]).mean(axis=1)
    se = np.sqrt(held_acc.var(ddof=1) / held_acc.size + test_acc.var(ddof=1) / test_acc.size)
    print(f"    one-view accuracy over all X_rho: held-out objects {held_acc.mean():.3f}, test "
          f"models {test_acc.mean():.3f} (difference {test_acc.mean() - held_acc.mean():+.3f} "
          f"± {se:.3f}, per-object SE)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=Path("runs/study-learned"))
    parser.add_argument("--workspaces", nargs="*", default=None,
                        help="under --root (default: every <dataset>/seed-<n> with report/)")
    parser.add_argument("--alphas", nargs="*", type=float, default=list(ALPHAS))
    parser.add_argument("--pseudo-counts", nargs="*", type=float, default=list(PSEUDO_COUNTS))
    parser.add_argument("--per-class", nargs="*", default=["real-cad-dev-learned/seed-0"],
                        help="workspaces whose per-class table to print")
    args = parser.parse_args()
    names = args.workspaces or sorted(
        str(p.parent.relative_to(args.root)) for p in args.root.glob("*/seed-*/report"))
    alphas = tuple(args.alphas)
    summary = []
    for name in names:
        root = args.root / name
        if not (root / "report").is_dir():
            print(f"== {name}: no report/ yet, skipped")
            continue
        began = time.process_time()
        held = Held(root)
        print(f"== {name}: {len(held.recorded.classes)} classes, {len(held.masks)} held-out "
              f"groups; RA model {held.names['ra']}")
        print(" 1. held out (leave one volume group out)")
        best = {}
        for key in METHODS:
            rows, best[key] = held_out_table(held, key, alphas)
            r0 = rows[0]
            rb = next(r for r in rows if r["alpha"] == best[key])
            summary.append((name, METHODS[key], best[key], rb["diff"], rb["se"],
                            min(rows, key=lambda r: r["walk_loss"])["alpha"],
                            r0["walk_loss"] - min(r["walk_loss"] for r in rows)))
        joint = {key: joint_table(held, key, alphas) for key in METHODS}
        pseudo_count_table(held, tuple(args.pseudo_counts))
        transfer_check(held)
        print(" 2. test episodes re-fused (UPPER-BOUND DIAGNOSTIC: reads the test models)")
        fused = episode_diagnostic(held, root, best, joint)
        if name in args.per_class:
            print(" 3. per class on the test episodes (diagnostic)")
            per_class(held, root, fused)
        print(f"  ({time.process_time() - began:.1f} s CPU)")
    print("== summary: held-out LOO choice of a (per observation log-likelihood; walks: the "
          "tempered belief's held-out walk log loss)")
    print(f"  {'workspace':<28} {'method':<11} {'a*':>5} {'dLL/obj':>8} {'(se)':>7} "
          f"{'walk a*':>7} {'walk gain':>9}")
    for name, method, a, d, se, wa, wg in summary:
        print(f"  {name:<28} {method:<11} {a:5.2f} {d:+8.4f} {se:7.4f} {wa:7.2f} {wg:9.4f}")


if __name__ == "__main__":
    main()
