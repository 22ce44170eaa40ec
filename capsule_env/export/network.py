"""A saved policy's deterministic action as data: the observation normaliser, the layers of the
network that gives the action, and what SB3's ``predict`` does to the network's output.

:func:`deterministic_actor` reads them from an
:class:`~capsule_env.agents.learning.sb3_policy.SB3Policy` (its model and its ``VecNormalize``
statistics). The ONNX export (:mod:`capsule_env.export.onnx_export`) runs SB3's own modules
(:attr:`DeterministicActor.modules`); the C export (:mod:`capsule_env.export.c_export`) writes
the layers (:attr:`DeterministicActor.layers`, read from the same modules). What is
reproduced, in order (``SB3Policy.predict`` with ``deterministic=True``):

1. ``clip((obs - mean) / sqrt(var + epsilon), -clip_obs, clip_obs)`` in double precision, then
   float32 (``SB3Policy.normalize``; skipped for a policy saved without observation
   normalisation);
2. the actor network: PPO's ``mlp_extractor.policy_net`` then ``action_net`` (the Gaussian's
   mean, its mode); SAC's, TQC's and CrossQ's ``latent_pi`` then ``mu`` then ``tanh`` (the
   squashed Gaussian's mode); TD3's ``mu`` (ending with its own ``tanh``);
3. SB3's ``predict`` on a ``Box`` action: a policy that squashes (SAC, TQC, CrossQ, TD3)
   rescales ``[-1, 1]`` to ``[low, high]`` (``unscale_action``), the others clip to
   ``[low, high]``;
4. ``SB3Policy.predict``'s clip to ``[-1, 1]`` (the env's action space).

Refused (``ValueError`` naming the reason): RecurrentPPO (its LSTM state would have to cross the
interface), feature extractors other than SB3's ``FlattenExtractor``, and layers other than
``Linear``, ``Tanh``, ``ReLU``, ``Hardtanh``, ``Identity``, ``Flatten`` and CrossQ's
``BatchRenorm1d`` (evaluation mode: its running statistics).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "Dense",
    "Activation",
    "Hardtanh",
    "Renorm",
    "Layer",
    "Normaliser",
    "DeterministicActor",
    "deterministic_actor",
]


@dataclass(frozen=True)
class Dense:
    """``y = weight @ x + bias`` (float32; ``weight`` of shape ``(out, in)``)."""

    weight: np.ndarray
    bias: np.ndarray


@dataclass(frozen=True)
class Activation:
    """An element-wise activation: ``"tanh"`` or ``"relu"``."""

    kind: str


@dataclass(frozen=True)
class Hardtanh:
    """``clip(x, low, high)`` (SB3's ``clip_mean`` of a gSDE actor)."""

    low: float
    high: float


@dataclass(frozen=True)
class Renorm:
    """CrossQ's batch renormalisation in evaluation mode:
    ``(x - mean) / sqrt(var + eps) * scale + bias`` (float32)."""

    mean: np.ndarray
    var: np.ndarray
    eps: float
    scale: np.ndarray
    bias: np.ndarray


Layer = Dense | Activation | Hardtanh | Renorm


@dataclass(frozen=True)
class Normaliser:
    """``clip((obs - mean) / std, -clip, clip)`` in double precision; ``std`` is
    ``sqrt(var + epsilon)`` of the ``VecNormalize`` statistics."""

    mean: np.ndarray
    std: np.ndarray
    var: np.ndarray
    epsilon: float
    clip: float


@dataclass(frozen=True)
class DeterministicActor:
    """What a policy's deterministic action is made of (the module docstring's steps 1-4)."""

    normaliser: Normaliser | None
    layers: tuple[Layer, ...]
    modules: Any  # torch.nn.Sequential of SB3's modules (copies, evaluation mode)
    tanh_output: bool  # a tanh after the layers (the squashed Gaussian's mode)
    rescale: bool  # SB3's unscale_action from [-1, 1] to [low, high]; else a clip to them
    low: np.ndarray  # float32, the model's action space
    high: np.ndarray
    algo: str

    @property
    def obs_size(self) -> int:
        first = next(layer for layer in self.layers if isinstance(layer, Dense))
        return int(first.weight.shape[1])

    @property
    def action_size(self) -> int:
        last = [layer for layer in self.layers if isinstance(layer, Dense)][-1]
        return int(last.weight.shape[0])


def _float32(tensor: Any) -> np.ndarray:
    return np.array(tensor.detach().cpu().numpy(), dtype=np.float32)


def _layer(module: Any) -> list[Layer]:
    """The layers of one torch module (a ``Sequential`` recursively)."""
    import torch

    if isinstance(module, torch.nn.Sequential):
        return [layer for child in module for layer in _layer(child)]
    if isinstance(module, torch.nn.Linear):
        bias = module.bias if module.bias is not None else torch.zeros(module.out_features)
        return [Dense(_float32(module.weight), _float32(bias))]
    if isinstance(module, torch.nn.Tanh):
        return [Activation("tanh")]
    if isinstance(module, torch.nn.ReLU):
        return [Activation("relu")]
    if isinstance(module, torch.nn.Hardtanh):
        return [Hardtanh(float(module.min_val), float(module.max_val))]
    if isinstance(module, (torch.nn.Identity, torch.nn.Flatten)):
        return []
    if type(module).__name__ == "BatchRenorm1d" and hasattr(module, "ra_mean"):
        ones = torch.ones_like(module.ra_mean)
        scale, bias = (module.scale, module.bias) if module.affine else (ones, 0 * ones)
        return [Renorm(_float32(module.ra_mean), _float32(module.ra_var), float(module.eps),
                       _float32(scale), _float32(bias))]  # fmt: skip
    raise ValueError(
        f"the policy's network has a {type(module).__name__} layer, which the export does not "
        "write (accepted: Linear, Tanh, ReLU, Hardtanh, Identity, Flatten, BatchRenorm1d)"
    )


def _check_flatten(extractor: Any) -> None:
    from stable_baselines3.common.torch_layers import FlattenExtractor

    if not isinstance(extractor, FlattenExtractor):
        raise ValueError(
            f"the policy's features extractor is {type(extractor).__name__}; the export writes "
            "policies on flat Box observations (SB3's FlattenExtractor) only"
        )


def _actor_parts(model: Any, algo: str) -> tuple[list[Any], bool]:
    """SB3's modules that give the action's mean, in order, and whether a tanh follows them."""
    policy = model.policy
    if algo == "recurrentppo":
        raise ValueError(
            "a RecurrentPPO policy carries an LSTM state between steps; the export writes "
            "stateless policies only (ppo, sac, td3, tqc, crossq)"
        )
    if hasattr(policy, "mlp_extractor"):  # PPO's ActorCriticPolicy
        _check_flatten(getattr(policy, "pi_features_extractor", policy.features_extractor))
        return [policy.mlp_extractor.policy_net, policy.action_net], bool(policy.squash_output)
    actor = getattr(policy, "actor", None)
    if actor is None:
        raise ValueError(f"cannot find the actor of a {type(policy).__name__}")
    _check_flatten(actor.features_extractor)
    if hasattr(actor, "latent_pi"):  # SAC, TQC, CrossQ: the squashed Gaussian's mode
        return [actor.latent_pi, actor.mu], True
    return [actor.mu], False  # TD3: mu ends with its own Tanh


def _normaliser(policy: Any) -> Normaliser | None:
    rms = policy.obs_rms
    if rms is None:
        return None
    mean, var = np.asarray(rms.mean, np.float64), np.asarray(rms.var, np.float64)
    std = np.sqrt(var + policy.epsilon)
    return Normaliser(mean, std, var, float(policy.epsilon), float(policy.clip_obs))


def deterministic_actor(policy: Any) -> DeterministicActor:
    """The deterministic action of ``policy`` (an ``SB3Policy``) as data (module docstring).
    ``ValueError`` for a policy the export cannot write."""
    import torch

    model, algo = policy.model, str(policy.meta.get("algo", "ppo"))
    parts, tanh_output = _actor_parts(model, algo)
    modules = torch.nn.Sequential(*(copy.deepcopy(p) for p in parts)).eval()
    layers = tuple(layer for part in parts for layer in _layer(part))
    dense = [layer for layer in layers if isinstance(layer, Dense)]
    if not dense:
        raise ValueError("the policy's network has no Linear layer")
    for layer in layers:
        values = [np.asarray(v) for v in vars(layer).values() if isinstance(v, np.ndarray)]
        if not all(np.isfinite(v).all() for v in values):
            raise ValueError("the policy's network has a weight that is NaN or infinite")
    space = model.action_space
    actor = DeterministicActor(
        normaliser=_normaliser(policy), layers=layers, modules=modules, tanh_output=tanh_output,
        rescale=bool(model.policy.squash_output), low=np.asarray(space.low, np.float32),
        high=np.asarray(space.high, np.float32), algo=algo,
    )  # fmt: skip
    norm = actor.normaliser
    if norm is not None and norm.mean.shape != (actor.obs_size,):
        raise ValueError(f"normaliser of shape {norm.mean.shape}, network input {actor.obs_size}")
    return actor
