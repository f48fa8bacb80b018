"""The learned baseline's policy: its network, its artefact, and the closed-loop method.

The learn stage trains the policy with sb3-contrib's MaskablePPO
(:mod:`rapomdp.experiment.learn_stage`); what it keeps is the policy network's weights as a
PyTorch state dict (read back with ``torch.load(..., weights_only=True)``, checked against the
SHA-256 its JSON records) and a JSON of its architecture and setting (:class:`PolicySpec`),
never sb3's ``.zip`` (which pickles). :class:`PolicyNetwork` rebuilds the network from them:
the same layers as sb3's ``MlpPolicy`` actor (tanh MLP, then a linear layer to one logit per
action). :class:`LearnedPolicy` runs it in the closed loop like every method: its belief is
:class:`~rapomdp.belief.BayesBelief` with its observation model, its input
:func:`~rapomdp.experiment.recorded_env.policy_input`, and it takes the most likely action among
:func:`~rapomdp.experiment.recorded_env.valid_actions` (PPO's deterministic action).

``W/learn/``: ``learned_lambda_<λ>.pt|json`` (one policy per wrong-declaration cost,
:func:`policy_stem`), :data:`RECORDED_FILE`, :data:`CURVES_CSV`, :data:`CURVES_FIGURE`,
:data:`LEARN_SUMMARY`.
"""

from __future__ import annotations

import hashlib
import io
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from rapomdp.belief import BayesBelief
from rapomdp.experiment.recorded_env import (
    RECORDED_FILE,
    closed_loop_action,
    map_mask,
    policy_input,
    valid_actions,
)
from rapomdp.experiment.sections import LEARNED
from rapomdp.io import ArtefactError, read_json, write_bytes_atomic, write_json_atomic
from rapomdp.planning.policy import ARAction

FORMAT = "rapomdp.learned-policy.v1"
#: The learn stage's summary: what was trained, for how long, its held-out scores.
LEARN_SUMMARY = "learn.json"
#: Per λ and update: timesteps, episodes, mean return, accuracy, energy, moves.
CURVES_CSV = "training_curves.csv"
CURVES_FIGURE = "training_curves.png"

__all__ = ["CURVES_CSV", "CURVES_FIGURE", "LEARNED", "LEARN_SUMMARY", "RECORDED_FILE",
           "LearnedPolicy", "PolicyNetwork", "PolicySpec", "load_learned_policy",
           "policy_stem", "save_learned_policy"]


def policy_stem(lambda_: float) -> str:
    """The file stem of the policy trained at wrong-declaration cost ``lambda_``."""
    return f"learned_lambda_{lambda_:g}"


@dataclass(frozen=True)
class PolicySpec:
    """What a learned policy is: its input (``classes`` + 2 x ``viewpoints``), hidden widths,
    actions (``viewpoints`` moves, then one stop that declares the belief's most likely class,
    :class:`~rapomdp.experiment.recorded_env.MapDeclaration`), and the setting it was trained
    for: the belief's ``observation_model``, ``lambda_``, ``max_moves`` and ``revisit``
    (evaluate's)."""

    classes: int
    viewpoints: int
    hidden: tuple[int, ...]
    observation_model: str
    lambda_: float
    max_moves: int
    revisit: bool

    @property
    def inputs(self) -> int:
        return self.classes + 2 * self.viewpoints

    @property
    def actions(self) -> int:
        return self.viewpoints + 1

    def to_dict(self) -> dict[str, Any]:
        """The artefact's record: the fields and ``declare`` "map" (what its stop declares),
        as every policy file records it."""
        return {**asdict(self), "hidden": list(self.hidden), "declare": "map"}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PolicySpec:
        """The spec of a policy file's record (:meth:`to_dict`).

        Args:
            data: the ``spec`` entry of a ``learned_lambda_<λ>.json``.

        Returns:
            The spec.

        Raises:
            ValueError: the policy chose the declared class itself (``declare`` "any"), an
                action space this version no longer runs.
        """
        if data.get("declare", "map") != "map":
            raise ValueError(f"a learned policy of declare {data['declare']!r} is no longer "
                             "run (docs/decisions/0018-learned-declaration.md); retrain it")
        return cls(int(data["classes"]), int(data["viewpoints"]),
                   tuple(int(h) for h in data["hidden"]), str(data["observation_model"]),
                   float(data["lambda_"]), int(data["max_moves"]), bool(data["revisit"]))


class PolicyNetwork(nn.Module):
    """The actor of sb3's ``MlpPolicy``: ``body`` (Linear + tanh per hidden width, as sb3's
    ``mlp_extractor.policy_net``) then ``head`` (its ``action_net``): one logit per action."""

    def __init__(self, inputs: int, hidden: Sequence[int], actions: int) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        size = inputs
        for width in hidden:
            layers += [nn.Linear(size, int(width)), nn.Tanh()]
            size = int(width)
        self.body = nn.Sequential(*layers)
        self.head = nn.Linear(size, actions)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(x))

    @classmethod
    def of(cls, spec: PolicySpec) -> PolicyNetwork:
        return cls(spec.inputs, spec.hidden, spec.actions)

    def best_action(self, observation: np.ndarray, mask: np.ndarray) -> int:
        """The most likely valid action (masked argmax of the logits)."""
        with torch.no_grad():
            logits = self(torch.from_numpy(np.asarray(observation, dtype=np.float32)[None]))
        scores = logits[0].numpy().astype(np.float64)
        return int(np.argmax(np.where(mask, scores, -np.inf)))


def save_learned_policy(folder: str | Path, network: PolicyNetwork, spec: PolicySpec,
                        extra: dict[str, Any] | None = None) -> Path:
    """Write ``<stem>.pt`` (the state dict) and ``<stem>.json`` (format, spec, SHA-256)
    atomically into ``folder``; returns the ``.pt`` path."""
    stem = Path(folder) / policy_stem(spec.lambda_)
    buffer = io.BytesIO()
    torch.save({k: v.detach().cpu() for k, v in network.state_dict().items()}, buffer)
    data = buffer.getvalue()
    write_bytes_atomic(stem.with_suffix(".pt"), data)
    write_json_atomic(stem.with_suffix(".json"), {
        "format": FORMAT, "spec": spec.to_dict(),
        "weights_sha256": hashlib.sha256(data).hexdigest(), **(extra or {})})
    return stem.with_suffix(".pt")


def load_learned_policy(folder: str | Path, lambda_: float) -> tuple[PolicyNetwork, PolicySpec]:
    """The policy the learn stage trained at ``lambda_`` (folder ``W/learn``), rebuilt from
    its JSON and loaded with ``weights_only=True``; a missing, altered or foreign file is a
    named :class:`ArtefactError`."""
    stem = Path(folder) / policy_stem(lambda_)
    meta_path, weights_path = stem.with_suffix(".json"), stem.with_suffix(".pt")
    if not meta_path.is_file():
        raise ArtefactError(f"{meta_path}: no learned policy for λ = {lambda_:g} (the learn "
                            "stage trains one per λ when evaluate.methods lists 'learned')")
    meta = read_json(meta_path)
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ArtefactError(f"{meta_path}: not a learned policy (format "
                            f"{meta.get('format') if isinstance(meta, dict) else None!r})")
    try:
        spec = PolicySpec.from_dict(meta["spec"])
        data = weights_path.read_bytes()
    except (KeyError, TypeError, ValueError) as exc:
        raise ArtefactError(f"{meta_path}: malformed spec ({exc})") from None
    except OSError as exc:
        raise ArtefactError(f"{weights_path}: cannot read ({exc.strerror})") from None
    if hashlib.sha256(data).hexdigest() != meta.get("weights_sha256"):
        raise ArtefactError(f"{weights_path}: the weights do not match the SHA-256 recorded in "
                            f"{meta_path.name} (a partial copy, or another run's)")
    network = PolicyNetwork.of(spec)
    try:
        network.load_state_dict(torch.load(io.BytesIO(data), map_location="cpu",
                                           weights_only=True))
    except Exception as exc:  # any unpickling or shape error is a bad artefact
        raise ArtefactError(f"{weights_path}: cannot load the weights ({exc})") from None
    network.eval()
    return network, spec


class LearnedPolicy:
    """A learned policy in the closed loop: Eq. 5 with its observation model, then the
    network's most likely valid action on (belief, viewpoint, visited); its stop declares the
    belief's most likely class. It reports its belief raised to ``declared_temperature`` (1: as
    it is; the evaluate stage fits it on the held-out closed loop), acting on the belief."""

    def __init__(self, network: PolicyNetwork, spec: PolicySpec, observation_model: np.ndarray,
                 reachable: np.ndarray, name: str = "Learned (PPO)", recogniser: str = "cnn",
                 declared_temperature: float = 1.0) -> None:
        shape = np.shape(observation_model)
        if len(shape) != 3 or (shape[0], shape[2]) != (spec.viewpoints, spec.classes):
            raise ValueError(f"{name}: the policy was trained on {spec.viewpoints} viewpoints "
                             f"and {spec.classes} classes, the observation model is "
                             f"{np.shape(observation_model)}")
        if np.shape(reachable) != (spec.viewpoints,):
            raise ValueError(f"{name}: reachability {np.shape(reachable)}, the policy has "
                             f"{spec.viewpoints} viewpoints")
        self.name, self.recogniser = name, recogniser
        self.network, self.spec = network, spec
        self.reachable = np.asarray(reachable, dtype=bool)
        self._bayes = BayesBelief(observation_model, declared_temperature)
        self._visited = np.zeros(spec.viewpoints, dtype=bool)
        self._looks = 0

    def reset(self, start_viewpoint: int, rng: np.random.Generator) -> None:
        self._bayes.reset()
        self._visited[:] = False
        self._looks = 0

    def observe(self, viewpoint: int, output: np.ndarray) -> None:
        self._visited[viewpoint] = True
        self._looks += 1
        self._bayes.update(viewpoint, output)

    @property
    def belief(self) -> np.ndarray:
        return self._bayes.declared

    def act(self, viewpoint: int) -> ARAction:
        spec = self.spec
        belief = self._bayes.belief
        mask = valid_actions(self.reachable, viewpoint, self._visited, self._looks - 1,
                             spec.max_moves, spec.revisit, spec.classes)
        mask = map_mask(mask, spec.viewpoints)
        action = self.network.best_action(policy_input(belief, viewpoint, self._visited), mask)
        action = closed_loop_action(action, belief, spec.viewpoints)
        if action >= spec.viewpoints:
            return ARAction("declare", action - spec.viewpoints)
        return ARAction("move", action)
