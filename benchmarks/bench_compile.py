"""Does ``torch.compile`` speed up PPO's gradient step here? Eager against compiled, one process.

    python benchmarks/bench_compile.py                          # batch 4096, 200 steps
    python benchmarks/bench_compile.py --batch 2048 --steps 500 --json out.json

PPO's update sets the pace of training (docs/benchmarks.md: 81-93 % of the wall time), and
each gradient step is dozens of small torch operations on a ``[64, 64]`` network. This script
times that step as stable-baselines3's PPO makes it: the ride task's (``CapsuleRide-v0``)
observation and action spaces, SB3's ``ActorCriticPolicy`` with the file's
``net_arch=[64, 64], log_std_init=-1`` (``hyperparams/ppo.yml``), ``evaluate_actions`` on a
minibatch, the clipped surrogate, the value loss and the entropy term, ``backward``, the
gradient clip and Adam's step. Once eager, once with the loss function under
``torch.compile`` (default mode; the first call compiles). Reported: the first call (the
compilation), the mean of ``--steps`` steps after 20 untimed ones, the speed-up and the steps
after which the compilation has paid for itself. One torch thread (train.py's setting) unless
``--threads``. Random data: the cost of a step does not depend on the values.

This measures the gradient step alone, with the whole loss compiled. In training, ``train.py
--compile`` and ``bench_training.py --compile`` compile ``policy.evaluate_actions``, what SB3's
``PPO.train`` calls on every minibatch (``capsule_env/agents/learning/compiled.py``); the rollouts'
forward passes (one row per vehicle) stay eager.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

from capsule_env.common.cli import ArgumentParser

#: The largest minibatch (rows): 64 times the 100k setting's 8192, well inside memory.
MAX_BATCH = 2**19
#: Untimed steps after the first call, before the timed ones (eager and compiled alike).
WARM_UP_STEPS = 20


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = ArgumentParser(
        prog="bench_compile.py",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    parser.add_argument("--batch", type=int, default=4096, help="minibatch rows (1..2**19)")
    parser.add_argument("--steps", type=int, default=200, help="timed steps each (>= 1)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (>= 1)")
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    args = parser.parse_args(argv)
    for name, most in (("batch", MAX_BATCH), ("steps", 10**6), ("threads", 1024)):
        if not 1 <= getattr(args, name) <= most:
            parser.error(f"--{name} must be in [1, {most}] (got {getattr(args, name)})")
    if args.json is not None:
        from capsule_env.common.safe_io import check_writable_file

        try:
            check_writable_file(args.json, "--json")
        except ValueError as exc:
            parser.error(str(exc))
    return args


def make_step(policy, compiled: bool):
    """One PPO gradient step on ``(obs, actions, advantages, returns, old_log_prob)``."""
    import torch

    def loss_fn(obs, actions, advantages, returns, old_log_prob):
        values, log_prob, entropy = policy.evaluate_actions(obs, actions)
        ratio = torch.exp(log_prob - old_log_prob)
        surrogate = torch.min(advantages * ratio, advantages * torch.clamp(ratio, 0.8, 1.2))
        value_loss = ((returns - values.flatten()) ** 2).mean()
        return -surrogate.mean() + 0.5 * value_loss - 0.0 * entropy.mean()

    loss = torch.compile(loss_fn) if compiled else loss_fn

    def step(*batch):
        policy.optimizer.zero_grad()
        loss(*batch).backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
        policy.optimizer.step()

    return step


def time_one(compiled: bool, args: argparse.Namespace) -> dict:
    """First-call and mean step times (s, ms) of a fresh policy, eager or compiled."""
    import gymnasium as gym
    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    import capsule_env  # noqa: F401  (registers the tasks)

    env = gym.make("CapsuleRide-v0")
    torch.manual_seed(0)
    policy = ActorCriticPolicy(env.observation_space, env.action_space, lambda _: 1e-3,
                               net_arch=[64, 64], log_std_init=-1.0)  # fmt: skip
    n_obs, n_act = env.observation_space.shape[0], env.action_space.shape[0]
    batch = (torch.randn(args.batch, n_obs), torch.randn(args.batch, n_act),
             torch.randn(args.batch), torch.randn(args.batch), torch.randn(args.batch))  # fmt: skip
    step = make_step(policy, compiled)
    t0 = time.perf_counter()
    step(*batch)
    first_s = time.perf_counter() - t0
    for _ in range(WARM_UP_STEPS):  # untimed: the allocator and the caches settle
        step(*batch)
    t0 = time.perf_counter()
    for _ in range(args.steps):
        step(*batch)
    return {"first_call_s": first_s, "ms_per_step": 1e3 * (time.perf_counter() - t0) / args.steps}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    import torch

    torch.set_num_threads(args.threads)
    eager, compiled = time_one(False, args), time_one(True, args)
    saved_ms = eager["ms_per_step"] - compiled["ms_per_step"]
    compile_s = compiled["first_call_s"] - eager["first_call_s"]
    result = {
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "machine": platform.processor() or platform.machine(),
        "torch": torch.__version__,
        "command": "python benchmarks/bench_compile.py "
        + " ".join(sys.argv[1:] if argv is None else argv),
        "config": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "eager": eager,
        "compiled": compiled,
        "speed_up": eager["ms_per_step"] / compiled["ms_per_step"],
        "break_even_steps": compile_s / (saved_ms / 1e3) if saved_ms > 0 else None,
    }
    print(f"batch {args.batch}, {args.threads} torch thread(s): eager {eager['ms_per_step']:.3f} ms "
          f"per gradient step, compiled {compiled['ms_per_step']:.3f} ms (x{result['speed_up']:.2f}) "
          f"after a first call of {compiled['first_call_s']:.1f} s")  # fmt: skip
    if result["break_even_steps"] is not None:
        print(f"the compilation pays for itself after {result['break_even_steps']:,.0f} steps")
    if args.json:
        from capsule_env.common.safe_io import atomic_write_text

        atomic_write_text(args.json, json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
