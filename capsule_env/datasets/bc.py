"""Behaviour cloning on a recorded dataset, evaluated like every other row (one file, CleanRL
style: the method's arguments are the dataclass :class:`Args`, each documented under its field;
the dataset and evaluation options are :class:`~capsule_env.datasets.offline_eval.Evaluation`'s).

    python -m capsule_env.datasets.bc --dataset-root datasets/mpc --seeds 5 --json out/bc.json

For each training seed, a small MLP (the observation standardised with the dataset's mean and
spread, ``hidden_layers`` tanh layers of ``hidden_units``, a tanh output: an action in
``[-1, 1]``) is fitted to the dataset's ``(observation, action)`` pairs by mean squared error
(Adam, ``gradient_steps`` minibatches of ``batch_size`` drawn with replacement), on one torch
thread; then evaluated as :mod:`~capsule_env.datasets.offline_eval` says (the evaluation bank,
the demonstrator on the same episodes, the ratio with its interval). Needs the ``rl`` extra
(torch, rliable) and the ``datasets`` extra (minari).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from capsule_env.datasets.offline_eval import Trainer, Transitions, check_ranges, offline_main

__all__ = ["Args", "check_args", "mlp", "standardised", "train_bc", "main"]

PROG = "python -m capsule_env.datasets.bc"


@dataclass
class Args:
    gradient_steps: int = 3000
    """Adam steps per network"""
    batch_size: int = 256
    """transitions per step, drawn with replacement"""
    learning_rate: float = 1e-3
    """Adam's step size"""
    hidden_units: int = 64
    """units per hidden layer"""
    hidden_layers: int = 2
    """hidden tanh layers"""


def check_args(args: Args) -> None:
    """``ValueError`` naming the option for a value out of range."""
    check_ranges(args, ("gradient_steps", "batch_size", "hidden_units", "hidden_layers"),
                 {"learning_rate": (0.0, np.inf)})  # fmt: skip


def mlp(inputs: int, outputs: int, hidden_units: int, hidden_layers: int,
        output_tanh: bool = True) -> Any:  # fmt: skip
    """A plain MLP: ``hidden_layers`` tanh layers of ``hidden_units``, a tanh output when
    ``output_tanh``."""
    from torch import nn

    layers: list[nn.Module] = []
    width = inputs
    for _ in range(hidden_layers):
        layers += [nn.Linear(width, hidden_units), nn.Tanh()]
        width = hidden_units
    layers += [nn.Linear(width, outputs)] + ([nn.Tanh()] if output_tanh else [])
    return nn.Sequential(*layers)


def standardised(observations: np.ndarray, body: Any) -> Any:
    """``body`` on the first argument standardised with the mean and spread of the rows of
    ``observations`` (buffers, saved with it); further arguments (a critic's action) are
    concatenated after it unchanged."""
    import torch
    from torch import nn

    class Standardised(nn.Module):
        mean: torch.Tensor
        std: torch.Tensor

        def __init__(self) -> None:
            super().__init__()
            self.register_buffer("mean", torch.as_tensor(observations.mean(axis=0)))
            self.register_buffer("std", torch.as_tensor(observations.std(axis=0)).clamp_min(1e-6))
            self.body = body

        def forward(self, x: torch.Tensor, *rest: torch.Tensor) -> torch.Tensor:
            return self.body(torch.cat([(x - self.mean) / self.std, *rest], -1))

    return Standardised()


def train_bc(data: Transitions, args: Args, seed: int) -> tuple[Any, dict[str, float]]:
    """One network fitted to the dataset's pairs from ``seed`` (module docstring); returns it
    and its last minibatch's loss."""
    import torch

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    obs, actions = data.observations, data.actions
    net = standardised(obs, mlp(obs.shape[1], actions.shape[1], args.hidden_units,
                                args.hidden_layers))  # fmt: skip
    optimiser = torch.optim.Adam(net.parameters(), lr=args.learning_rate)
    x_all, y_all = torch.as_tensor(obs), torch.as_tensor(actions)
    loss = torch.zeros(())
    for _ in range(args.gradient_steps):
        rows = torch.as_tensor(rng.integers(0, len(obs), size=args.batch_size))
        loss = torch.mean((net(x_all[rows]) - y_all[rows]) ** 2)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    net.eval()
    return net, {"mse": float(loss.detach())}


def _trainer(args: Args) -> Trainer:
    check_args(args)
    return lambda data, seed: train_bc(data, args, seed)


def main(argv: list[str] | None = None) -> int:
    return offline_main(PROG, __doc__ or "", Args, "bc", _trainer, argv)


if __name__ == "__main__":
    sys.exit(main())
