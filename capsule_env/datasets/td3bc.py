"""TD3+BC (Fujimoto & Gu, "A minimalist approach to offline reinforcement learning", NeurIPS
2021) on a recorded dataset, TorchRL's loss (:class:`torchrl.objectives.TD3BCLoss`), evaluated
like every other row (one file, CleanRL style: the method's arguments are the dataclass
:class:`Args`; the dataset and evaluation options are
:class:`~capsule_env.datasets.offline_eval.Evaluation`'s).

    python -m capsule_env.datasets.td3bc --dataset-root datasets/mpc --seeds 5 --json out/td3bc.json

TD3 on the dataset's transitions alone (no env interaction): twin critics on ``(observation,
action)`` learn the env's discounted reward (``gamma``; a bump-stop termination ends the
bootstrap, the episode's time limit does not), and the actor maximises the critics' value
scaled by ``lambda = alpha / mean|Q|`` while staying near the dataset's actions (a mean squared
error term): ``alpha`` large is TD3, ``alpha`` 0 is behaviour cloning. Target policy smoothing
(``policy_noise``, ``noise_clip``), delayed actor updates (``policy_delay``) and Polyak targets
(``tau``) as TD3. The observation is standardised with the dataset's mean and spread in both
networks. Reward is the env's (docs/env.md), not the Wk figure the row is judged by. Needs the
``rl`` extra (torch, rliable), TorchRL (in the ``dev`` extra) and minari (the ``datasets``
extra).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from capsule_env.datasets.bc import mlp, standardised
from capsule_env.datasets.offline_eval import Trainer, Transitions, check_ranges, offline_main

__all__ = ["Args", "check_args", "train_td3bc", "main"]

PROG = "python -m capsule_env.datasets.td3bc"


@dataclass
class Args:
    gradient_steps: int = 3000
    """critic steps per network (the actor steps every --policy-delay of them)"""
    batch_size: int = 256
    """transitions per step, drawn with replacement"""
    learning_rate: float = 3e-4
    """Adam's step size, actor and critics"""
    hidden_units: int = 64
    """units per hidden layer (actor and critics)"""
    hidden_layers: int = 2
    """hidden tanh layers (actor and critics)"""
    alpha: float = 2.5
    """weight of the critics' value against the behaviour-cloning term (the paper's 2.5)"""
    gamma: float = 0.99
    """discount per control step (0.99: a horizon of about 100 steps, 0.5 s)"""
    tau: float = 0.005
    """Polyak factor of the target networks"""
    policy_delay: int = 2
    """critic steps per actor step"""
    policy_noise: float = 0.2
    """standard deviation of the target action's smoothing noise (action units)"""
    noise_clip: float = 0.5
    """bound of that noise"""


def check_args(args: Args) -> None:
    """``ValueError`` naming the option for a value out of range."""
    check_ranges(args, ("gradient_steps", "batch_size", "hidden_units", "hidden_layers",
                        "policy_delay"),
                 {"learning_rate": (0.0, np.inf), "gamma": (0.0, 1.0), "tau": (0.0, 1.0)})  # fmt: skip
    if not (args.alpha >= 0 and args.policy_noise >= 0 and args.noise_clip >= 0):
        raise ValueError("--alpha, --policy-noise and --noise-clip must be >= 0")


def _loss(data: Transitions, args: Args) -> tuple[Any, Any]:
    """TorchRL's TD3+BC loss over a fresh actor and twin critics, and the actor network."""
    import torch
    from torchrl.data import Bounded
    from torchrl.modules import Actor, ValueOperator
    from torchrl.objectives import TD3BCLoss

    dim = data.actions.shape[1]
    spec = Bounded(-torch.ones(dim), torch.ones(dim), (dim,))
    obs = data.observations
    net = standardised(obs, mlp(obs.shape[1], dim, args.hidden_units, args.hidden_layers))
    critic = standardised(obs, mlp(obs.shape[1] + dim, 1, args.hidden_units, args.hidden_layers,
                                   output_tanh=False))  # fmt: skip
    actor = Actor(module=net, spec=spec, in_keys=["observation"])
    qvalue = ValueOperator(module=critic, in_keys=["observation", "action"])
    loss = TD3BCLoss(actor, qvalue, action_spec=spec, alpha=args.alpha,
                     policy_noise=args.policy_noise, noise_clip=args.noise_clip,
                     loss_function="l2")  # fmt: skip
    loss.make_value_estimator(gamma=args.gamma)
    return loss, net


def _batch(data: Transitions, rows: np.ndarray) -> Any:
    import torch
    from tensordict import TensorDict

    done = data.terminations[rows] | data.truncations[rows]
    column = lambda a: torch.as_tensor(a[rows]).reshape(len(rows), -1)  # noqa: E731
    return TensorDict({
        "observation": column(data.observations), "action": column(data.actions),
        ("next", "observation"): column(data.next_observations),
        ("next", "reward"): column(data.rewards),
        ("next", "terminated"): column(data.terminations),
        ("next", "done"): torch.as_tensor(done).reshape(len(rows), 1),
    }, batch_size=[len(rows)])  # fmt: skip


def train_td3bc(data: Transitions, args: Args, seed: int) -> tuple[Any, dict[str, float]]:
    """One actor trained from ``seed`` (module docstring); returns it and its last losses."""
    import torch
    from torchrl.objectives import SoftUpdate

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    loss, net = _loss(data, args)
    target = SoftUpdate(loss, tau=args.tau)
    actor_opt = torch.optim.Adam(
        loss.actor_network_params.values(True, True), lr=args.learning_rate
    )
    critic_opt = torch.optim.Adam(loss.qvalue_network_params.values(True, True),
                                  lr=args.learning_rate)  # fmt: skip
    last = {"critic": float("nan"), "actor": float("nan"), "bc": float("nan")}
    for step in range(args.gradient_steps):
        batch = _batch(data, rng.integers(0, len(data.rewards), size=args.batch_size))
        critic_loss, _ = loss.qvalue_loss(batch)
        critic_opt.zero_grad()
        critic_loss.backward()
        critic_opt.step()
        last["critic"] = float(critic_loss.detach())
        if step % args.policy_delay == 0:
            actor_loss, meta = loss.actor_loss(batch)
            actor_opt.zero_grad()
            actor_loss.backward()
            actor_opt.step()
            target.step()
            last.update(actor=float(actor_loss.detach()), bc=float(meta["bc_loss"]))
    net.eval()
    return net, last


def _trainer(args: Args) -> Trainer:
    check_args(args)
    try:
        import torchrl  # noqa: F401
    except ImportError:
        raise ImportError(
            "TD3+BC needs TorchRL, in the dev extra: pip install 'torchrl>=0.14' "
            "(or 'capsule-env[dev]')"
        ) from None
    return lambda data, seed: train_td3bc(data, args, seed)


def main(argv: list[str] | None = None) -> int:
    return offline_main(PROG, __doc__ or "", Args, "td3bc", _trainer, argv)


if __name__ == "__main__":
    sys.exit(main())
