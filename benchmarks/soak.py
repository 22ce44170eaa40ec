"""Random-action soak: many vehicle-steps in many configurations, counting what went wrong.

    python benchmarks/soak.py                    # about 10 minutes on 2 cores
    python benchmarks/soak.py --minutes 60       # longer
    python benchmarks/soak.py --quick            # a smoke test (seconds)

For every configuration in a grid (plant damper x setting x action mode x observation set x
vehicle randomisation x speed range x control rate), a native vector env of 256 vehicles takes
uniformly random actions (a bang-bang stress for the damper) until its share of the time is
spent, with autoreset. Counted per configuration: vehicle-steps, episodes ended by the bump
stop, NaN or infinite observations, rewards or info signals, and observations outside the
observation space. Prints one line per configuration and a total; exits 1 if anything was
non-finite or out of the space. Not part of the test run (it is long by design).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time

import numpy as np

from capsule_env.common.cli import ArgumentParser, integer, nonempty_path
from capsule_env.common.safe_io import atomic_write_text, check_writable_file
from capsule_env.envs import CapsuleSuspensionVectorEnv


def grid(quick: bool) -> list[dict]:
    dampers = ("reference", "bi_exponential", "tanh", "bouc_wen", "passive")
    rows = []
    for damper, setting, mode, obs in itertools.product(
        dampers, ("sim", "hils"), ("force", "current"), ("sensors", "full_state")
    ):
        rows.append({"damper": damper, "setting": setting, "action_mode": mode, "observation": obs})
    extremes = [
        {"vehicle_randomization": 0.9, "setting": "hils"},
        {"vehicle_randomization": 0.9, "damper": "bi_exponential"},
        {"speed_range_kmh": (50.0, 1200.0), "setting": "hils"},
        {"control_rate_hz": 50.0, "setting": "hils"},
        {"control_rate_hz": 1000.0, "setting": "hils", "inverse_model": "csdc"},
        {"guideway": "bump", "setting": "hils"},
        {"guideway": "step", "guideway_params": {"peak_m": 0.05}},
        {"guideway_params": {"peak_m": 0.03}, "setting": "hils", "inverse_model": "tanh"},
    ]
    rows += extremes
    return rows[:4] + extremes[:2] if quick else rows


def soak(kwargs: dict, seconds: float, num_envs: int, seed: int) -> dict:
    env = CapsuleSuspensionVectorEnv(num_envs=num_envs, **kwargs)
    low, high = env.single_observation_space.low, env.single_observation_space.high
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    counts = {"vehicle_steps": 0, "bump_stop_episodes": 0, "non_finite": 0, "out_of_space": 0}
    t_end = time.perf_counter() + seconds
    while time.perf_counter() < t_end:
        for _ in range(50):
            actions = rng.uniform(-1.0, 1.0, (num_envs, 1)).astype(np.float32)
            obs, reward, terminated, _, info = env.step(actions)
            counts["vehicle_steps"] += num_envs
            counts["bump_stop_episodes"] += int(terminated.sum())
            bad = ~np.isfinite(obs).all(axis=1) | ~np.isfinite(reward)
            for key, value in info.items():
                if not key.startswith("_"):
                    bad |= ~np.isfinite(value)
            counts["non_finite"] += int(bad.sum())
            counts["out_of_space"] += int(np.any((obs < low) | (obs > high), axis=1).sum())
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(  # errors: one line, exit status 2
        prog="soak.py", description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--minutes", type=float, default=10.0, help="total wall time (> 0)")
    parser.add_argument("--num-envs", type=integer, default=256,
                        help="vehicles per configuration (>= 1)")  # fmt: skip
    parser.add_argument("--quick", action="store_true", help="a few seconds: a smoke test")
    parser.add_argument("--json", type=nonempty_path,
                        help="also write the counts to this JSON file")  # fmt: skip
    args = parser.parse_args(argv)
    if not (math.isfinite(args.minutes) and args.minutes > 0):
        parser.error(f"--minutes must be a finite number > 0, got {args.minutes}")
    if args.num_envs < 1:
        parser.error(f"--num-envs must be >= 1, got {args.num_envs}")
    if args.json is not None:  # before the minutes of the soak, not after them
        try:
            check_writable_file(args.json, "--json")
        except ValueError as exc:
            parser.error(str(exc))
    configs = grid(args.quick)
    seconds = 0.5 if args.quick else 60.0 * args.minutes / len(configs)
    total = {"vehicle_steps": 0, "bump_stop_episodes": 0, "non_finite": 0, "out_of_space": 0}
    rows = []
    t0 = time.perf_counter()
    for k, kwargs in enumerate(configs):
        counts = soak(kwargs, seconds, 16 if args.quick else args.num_envs, seed=k)
        rows.append({"config": kwargs, **counts})
        for key in total:
            total[key] += counts[key]
        print(f"{counts['vehicle_steps']:>12,} vehicle-steps  non-finite {counts['non_finite']}  "
              f"out of space {counts['out_of_space']}  bump stops {counts['bump_stop_episodes']:>5}"
              f"  {kwargs}", flush=True)  # fmt: skip
    print(f"\ntotal: {total['vehicle_steps']:,} vehicle-steps in {len(configs)} configurations, "
          f"{time.perf_counter() - t0:.0f} s; non-finite {total['non_finite']}, out of the "
          f"observation space {total['out_of_space']}, bump-stop episodes "
          f"{total['bump_stop_episodes']}")  # fmt: skip
    if args.json is not None:  # atomic: a Ctrl-C here leaves no cut-off file
        counts = {"total": total, "configurations": rows}
        atomic_write_text(args.json, json.dumps(counts, indent=2, default=str))
    return 1 if total["non_finite"] or total["out_of_space"] else 0


if __name__ == "__main__":
    sys.exit(main())
