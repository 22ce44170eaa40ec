"""PPO training throughput with the SB3 VecEnv over the batched kernel, and the env's share.

    python benchmarks/bench_training.py [--timesteps 100000] [--num-envs 64] [--json out.json]

Trains PPO (SB3 defaults except the rollout size) on ``CapsuleSuspension-v0`` and reports
env-steps per second of the whole training loop and the share of wall time spent inside the
environment's ``step`` (timed around ``step_wait``). The env takes one step before training
starts, so that the kernel's one-time load from numba's cache (or compilation) is reported on
its own rather than counted as training time.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnvWrapper, VecMonitor, VecNormalize

from capsule_env.sb3 import CapsuleSuspensionSB3VecEnv


class TimedVecEnv(VecEnvWrapper):
    """Accumulates the wall time spent in the wrapped env's ``step_wait``."""

    def __init__(self, venv):
        super().__init__(venv)
        self.env_seconds = 0.0

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        t0 = time.perf_counter()
        out = self.venv.step_wait()
        self.env_seconds += time.perf_counter() - t0
        return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--timesteps", type=int, default=200_000)
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--n-steps", type=int, default=64, help="PPO rollout length per env")
    p.add_argument("--batch-size", type=int, default=1024)
    p.add_argument("--n-epochs", type=int, default=4)
    p.add_argument("--setting", default="hils")
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument("--json")
    args = p.parse_args(argv)
    torch.set_num_threads(args.threads)
    venv = CapsuleSuspensionSB3VecEnv(args.num_envs, setting=args.setting)
    # One step first: the kernel's first call loads it from numba's cache (or compiles it),
    # ~0.4 s once per process, which would otherwise be counted as env time of the training.
    t_first = time.perf_counter()
    venv.reset()
    venv.step(np.zeros((args.num_envs, 1), dtype=np.float32))
    first_step_s = time.perf_counter() - t_first
    venv.seed(0)
    timed = TimedVecEnv(venv)
    env = VecNormalize(VecMonitor(timed))
    model = PPO("MlpPolicy", env, n_steps=args.n_steps, batch_size=args.batch_size,
                n_epochs=args.n_epochs, seed=0, device="cpu", verbose=0)  # fmt: skip
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.timesteps)
    wall = time.perf_counter() - t0
    steps = model.num_timesteps
    result = {
        "timesteps": steps,
        "wall_s": wall,
        "env_steps_per_s": steps / wall,
        "env_share_of_wall": timed.env_seconds / wall,
        "env_only_steps_per_s": steps / timed.env_seconds,
        "first_step_s": first_step_s,
        "config": vars(args),
    }
    print(f"PPO on CapsuleSuspension-v0 ({args.setting}), {args.num_envs} envs, "
          f"n_steps={args.n_steps}, batch={args.batch_size}, epochs={args.n_epochs}, "
          f"torch threads={args.threads}")  # fmt: skip
    print(f"  {steps:,} steps in {wall:.1f} s: {steps / wall:,.0f} env-steps/s of training")
    print(f"  env share of wall time: {100 * result['env_share_of_wall']:.1f} % "
          f"({result['env_only_steps_per_s']:,.0f} env-steps/s inside step)")  # fmt: skip
    print(f"  (not counted: first env step, kernel load or compile, {first_step_s:.2f} s)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
