"""The ``learn`` pipeline stage: the learned baseline, trained on held-out evidence only.

When ``evaluate.methods`` lists ``learned``, the stage

1. records the evidence (:class:`~rapomdp.experiment.recorded_env.RecordedEvidence`): the
   trained classifier's output at every test viewpoint of every *volume* model (the
   classifier_eval stage's, on the xrho stage's images: the outputs the observation models
   were fitted on; its test models' arrays are not read). No test model is read (checked by
   key);
2. trains one policy per wrong-declaration cost λ (Table 1's ``solve.wrong_declaration_cost_m``
   and every ``evaluate.lambdas``) with sb3-contrib's MaskablePPO on
   :class:`~rapomdp.experiment.recorded_env.RecordedRecognitionEnv`, the belief that of
   ``learn.observation_model``; one task per λ over the worker processes, each seeded on its
   own;
3. scores each policy, and Random at each of its stop beliefs, on every (held-out model,
   reachable start) pair of the recorded evidence through the closed loop's own
   :func:`~rapomdp.experiment.episode.run_episode` (the recorded outputs as its memo, so
   nothing is rendered): in-sample figures for the learned policy, which trained on these
   models, labelled so.

Writes ``W/learn/``: the recorded evidence, ``learned_lambda_<λ>.pt|json`` (state dict and
architecture; no pickle), ``training_curves.csv|png`` (per update: mean return, accuracy,
energy) and ``learn.json``. Without ``learned`` in ``evaluate.methods`` it writes only
``learn.json`` (``"trained": false``) and takes no time.
"""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.config import Config, EvaluateConfig, LearnConfig
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.experiment.episode import Motion, Policy, run_episode
from rapomdp.experiment.learned import (
    CURVES_CSV,
    CURVES_FIGURE,
    LEARN_SUMMARY,
    LearnedPolicy,
    PolicyNetwork,
    PolicySpec,
    load_learned_policy,
    save_learned_policy,
)
from rapomdp.experiment.methods import RandomWalkPolicy
from rapomdp.experiment.recorded_env import (
    RECORDED_FILE,
    MapDeclaration,
    RecordedEvidence,
    RecordedRecognitionEnv,
)
from rapomdp.experiment.sections import LEARNED, learned_lambdas
from rapomdp.io import read_json, write_json_atomic, write_text_atomic
from rapomdp.parallel import run_tasks
from rapomdp.planning.stage import (
    offered_observation_models,
)
from rapomdp.progress import progress_bar, track
from rapomdp.recognition.artefacts import XrhoProbabilities, load_volume_probabilities
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, StageInputs

#: The columns of :data:`~rapomdp.experiment.learned.CURVES_CSV`.
CURVE_COLUMNS = ("lambda", "update", "timesteps", "episodes", "mean_return", "accuracy",
                 "mean_energy", "mean_moves")


# -- 1. the recorded evidence ------------------------------------------------------------------

def record_evidence(dataset: Dataset, volume: XrhoProbabilities) -> RecordedEvidence:
    """The classifier's outputs at X_rho of every volume model (``volume``: the classifier_eval
    stage's, on the xrho stage's images, the ones the observation models were fitted on). No
    test model is read; evidence naming one is refused."""
    models = dataset.with_role("volume")
    classes = len(dataset.classes)
    outputs = [np.asarray(volume.of(m), dtype=np.float32) for m in models]
    views = outputs[0].shape[0] if outputs else 0
    parts = [RecordedEvidence(np.array([f"{m.class_name}/{m.id}" for m in models], dtype=str),
                              np.array([dataset.label(m) for m in models], dtype=np.int64),
                              np.stack(outputs) if outputs else
                              np.zeros((0, views, classes), np.float32),
                              np.full(len(models), "volume"))]
    evidence = RecordedEvidence.concatenate(parts)
    test = {f"{m.class_name}/{m.id}" for m in dataset.with_role("test")}
    leaked = sorted(set(evidence.keys.tolist()) & test)
    if leaked:
        raise StageError(f"learn: the recorded evidence holds test models {leaked[:5]}; the "
                         "learned policy trains on held-out models only")
    return evidence


# -- 2. training -------------------------------------------------------------------------------

def belief_arguments(observe_dir: Path, names: Sequence[str]) -> dict[str, dict[str, Any]]:
    """For each named observation model, the arguments of its closed-loop belief
    (:class:`~rapomdp.belief.BayesBelief`) as the evaluation builds them: the
    model."""
    models, _ = offered_observation_models(observe_dir)
    return {name: {"observation_model": models[name]} for name in names if name in models}


def belief_models(observe_dir: Path, name: str = "ra") -> dict[str, Any]:
    """The belief arguments (:func:`belief_arguments`) of one observation model, the belief
    the learned policy sees.

    Args:
        observe_dir: The observe stage's folder.
        name: The observation model (``learn.observation_model``).

    Returns:
        The keyword arguments of its belief: ``observation_model`` (V, C, C).

    Raises:
        StageError: The observe stage did not make ``name`` (the models it made are named).
    """
    found = belief_arguments(observe_dir, [name])
    if name not in found:
        models, _ = offered_observation_models(observe_dir)
        raise StageError(f"learn.observation_model is '{name}'; the observe stage made "
                         f"{', '.join(models)}")
    return found[name]


def recorded_environment(evidence: RecordedEvidence, belief: dict[str, Any], motion: Motion,
                         lambda_: float, evaluate: EvaluateConfig | None = None,
                         seed: int | None = None) -> RecordedRecognitionEnv:
    """The training environment at ``lambda_`` over recorded evidence.

    Args:
        evidence: The recorded classifier outputs of the models.
        belief: The belief's arguments (:func:`belief_models`).
        motion: The robot's movement energy and reachable viewpoints.
        lambda_: λ, the cost of a wrong declaration in metres.
        evaluate: The ``evaluate`` section: the closed loop's step budget and revisit rule
            (``max_moves``, ``revisit``; None: the defaults).
        seed: The environment's seed (None: unseeded).

    Returns:
        The :class:`~rapomdp.experiment.recorded_env.RecordedRecognitionEnv`.
    """
    evaluate = EvaluateConfig() if evaluate is None else evaluate
    return RecordedRecognitionEnv(evidence, motion=motion, lambda_=lambda_,
                                  max_moves=evaluate.max_moves,
                                  revisit=evaluate.revisit, seed=seed, **belief)


def network_of(policy: Any, spec: PolicySpec) -> PolicyNetwork:
    """The actor of an sb3 ``MaskableActorCriticPolicy`` (``MlpPolicy``) as a
    :class:`PolicyNetwork`: its ``mlp_extractor.policy_net`` and ``action_net`` weights."""
    network = PolicyNetwork.of(spec)
    state = {f"body.{k}": v for k, v in policy.mlp_extractor.policy_net.state_dict().items()}
    state.update({f"head.{k}": v for k, v in policy.action_net.state_dict().items()})
    network.load_state_dict(state)
    return network.eval()


def train_policy(evidence: RecordedEvidence, observe_dir: Path, motion: Motion, lambda_: float,
                 seed: int, cfg: LearnConfig | None = None,
                 evaluate: EvaluateConfig | None = None, progress: bool = False
                 ) -> tuple[PolicyNetwork, PolicySpec, list[dict[str, float]]]:
    """MaskablePPO on ``learn.envs`` recorded-evidence environments at ``lambda_``.

    Args:
        evidence: The recorded classifier outputs of the training models.
        observe_dir: The observe stage's folder (the belief's observation model).
        motion: The robot's movement energy and reachable viewpoints.
        lambda_: λ, the cost of a wrong declaration in metres.
        seed: PPO's seed.
        cfg: The ``learn`` section: the network, PPO's settings, the belief's model (None:
            the defaults).
        evaluate: The ``evaluate`` section: the step budget and revisit rule (None: the
            defaults).
        progress: Show a progress bar.

    Returns:
        The policy network, its spec and one training-curve row per update (the episodes
        that ended in it).
    """
    import torch
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv

    cfg = LearnConfig() if cfg is None else cfg
    evaluate = EvaluateConfig() if evaluate is None else evaluate
    rows: list[dict[str, float]] = []

    class Curves(BaseCallback):  # type: ignore[misc]
        """Per update: the episodes that ended during its rollout (return, right, energy)."""

        def __init__(self, bar: Any, task: Any) -> None:
            super().__init__()
            self.ended: list[tuple[float, bool, float, int]] = []
            self.bar, self.task = bar, task

        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"], strict=True):
                if done and "correct" in info:
                    right = bool(info["correct"])
                    self.ended.append((-info["energy"] - (0.0 if right else lambda_), right,
                                       info["energy"], info["moves"]))
            return True

        def _on_rollout_end(self) -> None:
            ended = np.array(self.ended, dtype=np.float64).reshape(-1, 4)
            rows.append({"lambda": lambda_, "update": len(rows) + 1,
                         "timesteps": float(self.num_timesteps), "episodes": len(ended),
                         **dict(zip(CURVE_COLUMNS[4:], (ended.mean(axis=0) if len(ended)
                                                        else np.full(4, np.nan)).tolist(),
                                    strict=True))})
            self.ended = []
            last = rows[-1]
            self.bar.update(self.task, completed=self.num_timesteps,
                            status=f"return {last['mean_return']:.2f}, accuracy "
                                   f"{last['accuracy']:.2f}")

    spec = PolicySpec(evidence.classes, evidence.viewpoints, tuple(cfg.hidden),
                      cfg.observation_model, lambda_, evaluate.max_moves, evaluate.revisit)
    models = belief_models(observe_dir, cfg.observation_model)

    def environment() -> Any:
        return MapDeclaration(recorded_environment(evidence, models, motion, lambda_, evaluate))

    envs = DummyVecEnv([environment for _ in range(cfg.envs)])
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # a small MLP: one thread is fastest, and workers have one core
    try:
        model = MaskablePPO(
            "MlpPolicy", envs, learning_rate=cfg.learning_rate, n_steps=cfg.rollout_steps,
            batch_size=cfg.batch_size, n_epochs=cfg.epochs, gamma=cfg.gamma,
            gae_lambda=cfg.gae_lambda, ent_coef=cfg.entropy_coefficient, seed=seed,
            device="cpu", verbose=0,
            policy_kwargs={"net_arch": {"pi": list(cfg.hidden), "vf": list(cfg.hidden)},
                           "activation_fn": torch.nn.Tanh})
        with progress_bar(progress, status=True) as bars:
            task = bars.add_task(f"learn: PPO at λ = {lambda_:g}", total=cfg.timesteps,
                                 unit="steps", status="")
            model.learn(cfg.timesteps, callback=Curves(bars, task))
        network = network_of(model.policy, spec)
    finally:
        torch.set_num_threads(threads)
    return network, spec, rows


def _train_task(config_json: str, out: str, observe_dir: str, robot_dir: str, lambda_: float,
                progress: bool) -> tuple[list[dict[str, float]], float]:
    """A worker's task: train the policy of one λ, save it into ``out``; its curves and CPU
    seconds."""
    config = Config.model_validate_json(config_json)
    evidence = RecordedEvidence.load(Path(out) / RECORDED_FILE)
    motion = Motion.from_robot(load_robot(Path(robot_dir)))
    seed = int(class_seed(config.seed, f"learn/lambda_{lambda_:g}").integers(2**31))
    began = time.process_time()
    network, spec, rows = train_policy(evidence, Path(observe_dir), motion, lambda_, seed,
                                       config.learn, config.evaluate, progress)
    seconds = time.process_time() - began
    save_learned_policy(out, network, spec, {"timesteps": config.learn.timesteps,
                                             "seed": seed, "cpu_seconds": seconds})
    return rows, seconds


# -- 3. held-out scores ----------------------------------------------------------------------

class _NoScene:
    """The scene of an episode over recorded evidence: every output is in the memo, so a look
    would be a bug."""

    def look(self, viewpoint: int, rng: np.random.Generator) -> np.ndarray:
        raise RuntimeError(f"recorded evidence: viewpoint {viewpoint} was not recorded")


class _NoRecogniser:
    def predict(self, depth_images: np.ndarray) -> np.ndarray:
        raise RuntimeError("recorded evidence: nothing is classified")


def recorded_starts(evidence: RecordedEvidence, reachable: np.ndarray, seed: int,
                    per_model: int | None = None) -> list[np.ndarray]:
    """Each recorded model's start viewpoints: every reachable one, or ``per_model`` distinct
    reachable ones drawn from a generator seeded by the seed and the model's key."""
    candidates = np.flatnonzero(reachable)
    if per_model is None:
        return [candidates for _ in range(evidence.models)]
    count = min(int(per_model), candidates.size)
    return [np.sort(class_seed(seed, f"learn/start/{key}").choice(candidates, count,
                                                                  replace=False))
            for key in evidence.keys]


def recorded_scores(evidence: RecordedEvidence, method: Policy, motion: Motion,
                    max_moves: int, seed: int, key: str,
                    starts: Sequence[np.ndarray] | None = None) -> dict[str, float]:
    """Accuracy, mean energy and moves of ``method`` over every (recorded model, start) pair
    (``starts``: :func:`recorded_starts`, default every reachable start), through
    :func:`run_episode` with the recorded outputs as its memo: nothing is rendered."""
    right, energy, moves = [], [], []
    if starts is None:
        starts = recorded_starts(evidence, motion.reachable, seed)
    for m in range(evidence.models):
        memo = {v: evidence.outputs[m, v] for v in range(evidence.viewpoints)}
        for start in starts[m]:
            rng = class_seed(seed, f"learn/held_out/{evidence.keys[m]}/{start}/{key}")
            episode = run_episode(_NoScene(), _NoRecogniser(), method, motion, int(start),
                                  max_moves, rng, memo)
            right.append(episode.declared == evidence.labels[m])
            energy.append(float(episode.move_energy.sum()))
            moves.append(episode.moves)
    return {"episodes": len(right), "accuracy": float(np.mean(right)),
            "mean_energy": float(np.mean(energy)), "mean_moves": float(np.mean(moves))}


def held_out_comparison(evidence: RecordedEvidence, out: Path, observe_dir: Path,
                        motion: Motion, lambda_: float, ev: EvaluateConfig | None = None,
                        observation_model: str = "ra", seed: int = 0, progress: bool = True
                        ) -> list[dict[str, Any]]:
    """Every trained policy and Random (at each stop belief) scored on the held-out recorded
    evidence (:func:`recorded_scores`), one row each; their beliefs as the evaluation builds
    them.

    Args:
        evidence: The recorded classifier outputs of the held-out models.
        out: The learn stage's folder (the trained policies, one per λ).
        observe_dir: The observe stage's folder (the beliefs' observation models).
        motion: The robot's movement energy and reachable viewpoints.
        lambda_: Table 1's λ in metres (``solve.wrong_declaration_cost_m``).
        ev: The ``evaluate`` section: the sweep's λ, Random's settings, the step budget
            (None: the defaults).
        observation_model: The learned policy's belief (``learn.observation_model``).
        seed: The configuration's ``seed`` (the episodes' generators).
        progress: Show a progress bar.

    Returns:
        One row per (method, setting): ``method``, ``parameter``, ``value`` and
        :func:`recorded_scores`' accuracy, mean energy (metres) and moves.
    """
    ev = EvaluateConfig() if ev is None else ev
    walk = ev.random.observation_model
    beliefs = belief_arguments(observe_dir, [observation_model, walk])
    if walk not in beliefs:
        raise StageError(f"evaluate.random.observation_model is '{walk}'; the workspace "
                         "lacks it")
    settings: list[tuple[str, float, Policy]] = []
    for lam in learned_lambdas(lambda_, ev.lambdas):
        network, spec = load_learned_policy(out, lam)
        settings.append((LEARNED, lam, LearnedPolicy(network, spec, reachable=motion.reachable,
                                                     **beliefs[spec.observation_model])))
    for threshold in dict.fromkeys([ev.random.belief_threshold, *ev.random_thresholds]):
        random_belief = dict(beliefs[walk])
        settings.append(("random", float(threshold), RandomWalkPolicy(
            random_belief.pop("observation_model"), motion.distance_m, motion.reachable,
            ev.random.neighbours, threshold, ev.random.max_moves, **random_belief)))
    rows = []
    for method, value, policy in track(settings, "learn: held-out episodes", progress,
                                       unit="settings"):
        scores = recorded_scores(evidence, policy, motion, ev.max_moves, seed, method)
        rows.append({"method": method, "parameter": "lambda" if method == LEARNED
                     else "threshold", "value": value, **scores})
    return rows


# -- the figure and the stage ------------------------------------------------------------------

def plateau_timesteps(rows: Sequence[dict[str, float]], window: int = 5,
                      tolerance_m: float = 0.1) -> float | None:
    """The first timestep from which the mean return, smoothed over ``window`` updates, stays
    within ``tolerance_m`` (metres of energy-equivalent cost: about half a move) of its final
    smoothed value (None: no rows)."""
    values = np.array([r["mean_return"] for r in rows], dtype=np.float64)
    good = np.isfinite(values)
    if not good.any():
        return None
    values = np.where(good, values, np.nanmean(values))
    width = min(window, values.size)
    smooth = np.convolve(values, np.ones(width) / width, mode="valid")
    outside = np.flatnonzero(np.abs(smooth - smooth[-1]) > tolerance_m)
    first = 0 if outside.size == 0 else int(outside[-1]) + 1
    return float(rows[first + width - 1]["timesteps"])


def curves_csv(rows: Sequence[dict[str, float]]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, CURVE_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def curves_figure(rows: Sequence[dict[str, float]], path: Path) -> Path:
    """Mean return, accuracy and mean energy of the training episodes per update, one line
    per λ (line style and marker per λ, so they differ without colour)."""
    from rapomdp.plots import OKABE_ITO, new_figure, save_png, style

    lambdas = list(dict.fromkeys(r["lambda"] for r in rows))
    styles = (("-", "o"), ("--", "s"), ("-.", "^"), (":", "D"), ("-", "v"))
    with style():
        fig = new_figure(10.0, 3.4)
        axes = fig.subplots(1, 3, sharex=True)
        for k, lam in enumerate(lambdas):
            mine = [r for r in rows if r["lambda"] == lam]
            x = np.array([r["timesteps"] for r in mine])
            line, marker = styles[k % len(styles)]
            every = max(1, len(mine) // 8)
            for ax, column in zip(axes, ("mean_return", "accuracy", "mean_energy"),
                                  strict=True):
                ax.plot(x, [r[column] for r in mine], linestyle=line, marker=marker,
                        markevery=every, markersize=4, color=OKABE_ITO[(k + 4) % 8],
                        label=f"λ = {lam:g} m" if ax is axes[0] else None)
        for ax, label in zip(axes, ("mean return (−m of energy, −λ if wrong)",
                                    "accuracy of the training episodes",
                                    "mean energy of an episode (m)"), strict=True):
            ax.set(xlabel="environment steps", ylabel=label)
            ax.grid(alpha=0.3)
        axes[1].set_ylim(0, 1.02)
        axes[0].legend(loc="lower right")
        fig.suptitle("Learned baseline (MaskablePPO): training on held-out recorded evidence")
        return save_png(fig, path)


def require_sb3() -> None:
    """A named error, before any work, when sb3-contrib (MaskablePPO) is not installed."""
    try:
        import sb3_contrib  # noqa: F401
    except ImportError:
        raise StageError("the learned baseline ('learned' in evaluate.methods) trains with "
                         "sb3-contrib's MaskablePPO, which is not installed: pip install "
                         "'rapomdp[learned]'") from None


def run_learn_stage(config: Config, inputs: StageInputs, out: Path,
                    context: RunContext) -> None:
    """Record the held-out evidence, train a policy per λ, score it on held-out episodes.

    Args:
        config: the run's configuration; the stage reads ``seed`` and ``learn`` (its key),
            and ``evaluate`` and ``solve`` (the methods and λ).
        inputs: the folders of the stages it reads (dataset, classifier_eval, observe and robot).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: one MaskablePPO policy per λ (when ``evaluate.methods`` lists
            ``learned``) with its held-out scores, and ``learn.json``.
    """
    began = time.perf_counter()
    if LEARNED not in config.evaluate.methods:
        write_json_atomic(out / LEARN_SUMMARY, {
            "trained": False, "reason": "evaluate.methods does not list 'learned' "
            "(configs/learned.yaml does)"})
        return
    require_sb3()
    dataset = load_dataset(inputs.dataset)
    evidence = record_evidence(dataset, load_volume_probabilities(inputs.classifier_eval))
    evidence.save(out / RECORDED_FILE)
    recorded_s = time.perf_counter() - began
    motion = Motion.from_robot(load_robot(inputs.robot))
    # a wrong observation model is named before work
    belief_models(inputs.observe, config.learn.observation_model)
    lambdas = learned_lambdas(config.solve.wrong_declaration_cost_m, config.evaluate.lambdas)
    workers = min(context.worker_count, len(lambdas))
    in_process = workers == 1 and not context.uses_cluster
    tasks = [(config.model_dump_json(), str(out), str(inputs.observe), str(inputs.robot), lam,
              context.progress and in_process) for lam in lambdas]
    trained = run_tasks(_train_task, tasks, workers, "learn: PPO policies (one per λ)",
                        context.progress and not in_process, context.scheduler,
                        unit="policies", pool=context.pool)
    trained_s = time.perf_counter() - began - recorded_s
    rows = [row for curve, _ in trained for row in curve]
    write_text_atomic(out / CURVES_CSV, curves_csv(rows))
    curves_figure(rows, out / CURVES_FIGURE)
    held_out = held_out_comparison(evidence, out, inputs.observe, motion,
                                   config.solve.wrong_declaration_cost_m, config.evaluate,
                                   config.learn.observation_model, config.seed,
                                   context.progress)
    write_json_atomic(out / LEARN_SUMMARY, {
        "trained": True,
        "observation_model": config.learn.observation_model,
        "lambdas": lambdas,
        "timesteps": config.learn.timesteps,
        "evidence": {"models": evidence.models,
                     "volume": int((evidence.sources == "volume").sum()),
                     "keys": evidence.keys.tolist()},
        "policies": {f"{lam:g}": {
            "cpu_seconds": seconds,
            "plateau_timesteps": plateau_timesteps([r for r in curve]),
            "final": curve[-1] if curve else None}
            for lam, (curve, seconds) in zip(lambdas, trained, strict=True)},
        "held_out": held_out,
        "held_out_note": "in-sample for the learned policies: they trained on these models",
        "workers": workers,
        "seconds": {"record": recorded_s, "train_wall": trained_s,
                    "train_cpu": float(sum(s for _, s in trained)),
                    "total": time.perf_counter() - began},
    })


def load_learn_summary(folder: str | Path) -> dict[str, Any]:
    """The learn stage's ``learn.json``."""
    data = read_json(Path(folder) / LEARN_SUMMARY)
    if not isinstance(data, dict):
        raise StageError(f"{Path(folder) / LEARN_SUMMARY}: not a JSON object")
    return data
