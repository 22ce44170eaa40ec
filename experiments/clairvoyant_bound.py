"""How low could any controller push the Wk-weighted body acceleration? The clairvoyant bound
(:mod:`capsule_env.oracle`) beside a controller, episode by episode.

    python experiments/clairvoyant_bound.py                          # hils, 10 episodes of 10 s
    python experiments/clairvoyant_bound.py --controller preview-lq-biexp-meas --episodes 3
    python experiments/clairvoyant_bound.py --setting sim --json out.json

For each held-out evaluation episode (the seeds ``evaluate.py`` uses, 1000, 1001, ...) it runs
the controller through the env, then searches the applied-current sequence that minimises the
Wk-weighted RMS body acceleration knowing the whole guideway (no noise, no delay, no inverse
model), from the default starts and from the controller's own applied currents (so the
search's answer is never worse than the controller). It prints both per episode, their ratio,
and how much the local search's answer depends on its start (what the numbers mean:
:mod:`capsule_env.oracle`). ``evaluate.py --oracle`` puts the same row in the paper's tables.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from capsule_env.agents import classical_controllers

from capsule_env.common.safe_io import atomic_write_text, check_writable_file
from capsule_env.engine.config import EnvConfig
from capsule_env.evaluation.episodes import episode_metrics, run_episodes
from capsule_env.oracle import DEFAULT_STARTS, applied_currents, clairvoyant_bound


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--controller", default="lqr-clipped-biexp-meas",
                   help="the causal controller to compare (a classical name)")  # fmt: skip
    p.add_argument("--setting", choices=["sim", "hils"], default="hils")
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=1000, help="first episode seed")
    p.add_argument("--duration", type=float, default=10.0, help="seconds per episode")
    p.add_argument("--max-iter", type=int, default=150, help="L-BFGS-B iterations per search")
    p.add_argument("--restarts", type=int, default=1)
    p.add_argument("--json", type=Path, help="write the results to this JSON file")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    controllers = classical_controllers()
    try:
        if args.controller not in controllers:
            raise ValueError(f"--controller: unknown {args.controller!r}; accepted: "
                             + ", ".join(controllers))  # fmt: skip
        if args.episodes < 1 or args.seed < 0:
            raise ValueError("--episodes must be >= 1 and --seed >= 0")
        if args.json is not None:
            check_writable_file(args.json, "--json")
        ctrl = controllers[args.controller]
        env = {**ctrl.env_kwargs, "setting": args.setting}
        delay = EnvConfig.from_kwargs(**env).effective_control_delay_steps
        seeds = list(range(args.seed, args.seed + args.episodes))
        roll = run_episodes(ctrl, env, seeds=seeds, episode_length_s=args.duration)
        result = clairvoyant_bound(  # the controller's episodes: its own options (e.g. a
            env, seeds, args.duration,  # law for trips), what it reads changing nothing here
            starts=[*DEFAULT_STARTS, applied_currents(roll, delay)],
            max_iter=args.max_iter, restarts=args.restarts,
        )  # fmt: skip
    except ValueError as exc:
        sys.exit(f"clairvoyant_bound.py: error: {exc}")
    wk_ctrl = np.array([
        episode_metrics(roll.select([k]), None)["wk_rms_body_acc_m_s2"] for k in range(len(seeds))
    ])  # fmt: skip
    wk_oracle = result.wk_rms_body_acc_m_s2
    print(
        f"{args.setting}: {args.controller} vs the clairvoyant bound, {args.duration:g} s episodes"
    )
    print(f"{'seed':>6} {'controller':>11} {'oracle':>9} {'ratio':>7} {'spread':>8}  best start")
    summary = result.summary()
    for k, seed in enumerate(seeds):
        row = summary["episodes_detail"][k]
        print(f"{seed:>6} {wk_ctrl[k]:>11.4f} {wk_oracle[k]:>9.4f} "
              f"{wk_oracle[k] / wk_ctrl[k]:>7.3f} {row['spread_over_starts_m_s2']:>8.4f}  "
              f"{row['best_start']}")  # fmt: skip
    ratio = float(np.mean(wk_oracle) / np.mean(wk_ctrl))
    print(f"means: controller {np.mean(wk_ctrl):.4f}, oracle {np.mean(wk_oracle):.4f} m/s^2 "
          f"(ratio {ratio:.3f}); search {result.total_time_s:.0f} s")  # fmt: skip
    if args.json is not None:
        summary.update({"controller": args.controller, "wk_controller_m_s2": wk_ctrl.tolist(),
                        "ratio_of_means": ratio})  # fmt: skip
        atomic_write_text(args.json, json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
