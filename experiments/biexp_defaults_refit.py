"""What regenerating the Bi-exponential defaults would change (issue 25, item 11).

    python experiments/biexp_defaults_refit.py                      # 8 episodes of 10 s
    python experiments/biexp_defaults_refit.py --episodes 4 --controllers skyhook-biexp

The shipped :class:`~capsule_env.dampers.BiExponentialDamper` defaults are the reference
damper's fit with the literal branch split (``x >= 0`` / ``x < 0``); today's
``python -m capsule_env.identification.cli --emit-defaults`` leaves out the samples within the model's
0.1 mm branch blend (two per loop) and differs by up to 0.58 %. This script prints both
parameter sets side by side, then runs each controller on evaluate.py's episodes (guideway
bank and seeds) with the shipped defaults and with today's fit rounded as ``--emit-defaults``
prints it: in ``sim`` both the plant damper and the inverted model, in ``hils`` the inverted
model (the plant is the reference damper). It prints the Wk-weighted RMS body acceleration of
each and their relative difference.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import fields

import numpy as np
from capsule_env.agents import classical_controllers, make_controller

from capsule_env.dampers import BiExponentialDamper
from capsule_env.engine.config import EnvConfig
from capsule_env.evaluation.episodes import check_episode_length, episode_metrics, run_episodes
from capsule_env.identification import identify_reference
from capsule_env.identification.results import dataclass_default_lines


def refit_params() -> dict[str, float]:
    """Today's reference fit, rounded to 5 significant digits as ``--emit-defaults`` prints."""
    damper = identify_reference().models["bi_exponential"].damper
    params = {}
    for line in dataclass_default_lines(damper):
        name, value = line.strip().split(": float = ")
        params[name] = float(value)
    params.pop("branch_blend_m", None)
    return params


def check_arguments(args: argparse.Namespace) -> None:
    """``ValueError`` naming the option when ``args`` cannot run."""
    if not (args.episodes >= 1 and 0 <= args.seed <= 2**63 - args.episodes):
        raise ValueError(f"--episodes must be >= 1 and --seed in [0, 2**63 - episodes], got "
                         f"{args.episodes} and {args.seed}")  # fmt: skip
    check_episode_length(args.episode_length, EnvConfig().dt_s, "--episode-length")
    unknown = [n for n in args.controllers.split(",") if n not in classical_controllers()]
    if unknown:
        raise ValueError(f"--controllers: unknown {unknown}; accepted: "
                         f"{', '.join(classical_controllers())}")  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--episode-length", type=float, default=10.0)
    parser.add_argument("--controllers", default="skyhook-biexp,skyhook-cont-biexp")
    args = parser.parse_args(argv)
    try:  # before the refit and the episodes, not a traceback from the first episode
        check_arguments(args)
    except ValueError as exc:
        sys.exit(f"biexp_defaults_refit.py: error: {exc}")
    refit = refit_params()
    shipped = BiExponentialDamper()
    print(f"{'parameter':<10}{'shipped':>12}{'refit':>12}{'rel. diff':>11}")
    for f in fields(shipped):
        if f.name in refit:
            a, b = getattr(shipped, f.name), refit[f.name]
            print(f"{f.name:<10}{a:12.6g}{b:12.6g}{(b - a) / abs(a):11.2e}")
    print()
    print(f"{'setting':<8}{'controller':<22}{'Wk shipped':>12}{'Wk refit':>12}{'rel. diff':>11}")
    for setting in ("sim", "hils"):
        for name in args.controllers.split(","):
            ctrl = make_controller(name)
            wk = []
            for params in ({}, refit):
                env = {**ctrl.env_kwargs, "setting": setting, "inverse_params": params}
                if setting == "sim":
                    env["damper_params"] = params
                roll = run_episodes(ctrl, env, args.episodes, args.seed, args.episode_length)
                wk.append(float(np.mean(episode_metrics(roll, None)["wk_rms_body_acc_m_s2"])))
            diff = (wk[1] - wk[0]) / wk[0]
            print(f"{setting:<8}{name:<22}{wk[0]:12.6f}{wk[1]:12.6f}{diff:11.2e}")


if __name__ == "__main__":
    main()
