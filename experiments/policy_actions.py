"""What a controller asks for: the statistics of its actions on the validation bank.

    python experiments/policy_actions.py --task CapsuleTrip-v0 --law mpc-biexp-meas \
        --policy runs/sweep/tasks-crossq-search/trials/trip-crossq-000/run/final_model.zip
    python experiments/policy_actions.py --policy runs/ppo-seed0/best_model.zip --json a.json

Why: a learned policy that ends at the passive damper's Wk may ask for nothing, or it may ask
for the wrong thing. Both look the same in the metric. This script runs each controller
deterministically on the validation bank (guideway seed 7, episodes ``--first-seed``
(5000) .. + ``--episodes`` (10), 10 s; what train.py evaluates on), in the task's setting
(``hils`` for the registered ride, preview and trip tasks). It uses the task's options with the
controller's own over them (what it reads, how it acts). Then it reports:

- the mean and standard deviation of its actions, and the share with ``|a| >= 0.95``, with the
  action mode they are in (``action_mode``). In force mode the action is the force request as
  a fraction of the damper's ``max_force_n``; in current mode, of the coil's current range, so
  the rows of two modes do not compare.
- its Wk-weighted RMS body acceleration (m/s^2) on those episodes;
- for SAC, TQC and CrossQ policies, the entropy coefficient ``alpha`` the run ended with.

A residual policy's action is its law's plus its correction (``load_policy``). The statistics
cover every control step of every episode that did not hit the bump stop. Bad arguments: one
line on stderr, exit status 2.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env.common.cli import ArgumentParser, integer  # noqa: E402

#: |action| at or above this counts as at the bound.
AT_BOUND = 0.95


class _Recorder:
    """Wraps a controller; keeps every action its ``predict`` returns (one row per vehicle)."""

    def __init__(self, controller: Any) -> None:
        self.controller = controller
        self.actions: list[np.ndarray] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self.controller, name)

    def predict(self, obs: np.ndarray, *args: Any, **kwargs: Any) -> Any:
        out = self.controller.predict(obs, *args, **kwargs)
        self.actions.append(np.array(out[0], dtype=float).reshape(len(obs), -1))
        return out


def action_statistics(controller: Any, env_kwargs: dict, seeds: list[int],
                      episode_length_s: float = 10.0) -> dict:  # fmt: skip
    """Mean, standard deviation and share at the bound of ``controller``'s actions, and its
    Wk, over the episodes ``seeds`` of the env ``env_kwargs``. An episode that hit the bump
    stop is left out of the action statistics (its actions after the stop are not the
    controller's choice) and counted in ``terminated_episodes``."""
    from capsule_env.evaluation.episodes import episode_metrics, run_episodes

    recorder = _Recorder(controller)
    rollout = run_episodes(recorder, env_kwargs, seeds=seeds, episode_length_s=episode_length_s)
    actions = np.stack(recorder.actions, axis=1)  # (episodes, steps, action dims)
    values = actions[~rollout.terminated].ravel()
    if values.size == 0:
        raise ValueError("every episode hit the bump stop: no actions to describe")
    return {"action_mode": rollout.action_mode, "mean": float(values.mean()),
            "std": float(values.std()),
            "share_at_bound": float(np.mean(np.abs(values) >= AT_BOUND)),
            "samples": int(values.size), "terminated_episodes": int(rollout.terminated.sum()),
            "wk_rms_body_acc_m_s2": float(episode_metrics(rollout, None)["wk_rms_body_acc_m_s2"])}  # fmt: skip


def check_observation(name: str, controller: Any, env_kwargs: dict) -> None:
    """``ValueError`` when the saved policy inside ``controller`` reads observations of another
    shape than the env ``env_kwargs`` gives (a policy made for another task)."""
    from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv

    model = getattr(getattr(controller, "policy", controller), "model", None)
    space = getattr(model, "observation_space", None)
    if space is None:
        return
    env = CapsuleSuspensionVectorEnv(num_envs=1, **env_kwargs)
    shape = env.single_observation_space.shape
    env.close()
    if tuple(space.shape) != tuple(shape):
        raise ValueError(f"the policy reads observations of shape {tuple(space.shape)}, the task's "
                         f"env gives {tuple(shape)}: a policy made for another task?")  # fmt: skip


def entropy_coefficient(controller: Any) -> float | None:
    """``exp(log_ent_coef)`` of an SB3 SAC-family model inside ``controller`` (a residual
    policy's network too), else None."""
    model = getattr(getattr(controller, "policy", controller), "model", None)
    log_alpha = getattr(model, "log_ent_coef", None)
    return None if log_alpha is None else float(math.exp(float(log_alpha.detach())))


def _parser() -> ArgumentParser:
    p = ArgumentParser(prog="policy_actions.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--policy", action="append", default=[], metavar="ZIP",
                   help="a saved policy (train.py's .zip), repeatable")  # fmt: skip
    p.add_argument("--law", action="append", default=[], metavar="NAME",
                   help="a classical controller of evaluate.py, repeatable")  # fmt: skip
    p.add_argument("--task", default="CapsuleRide-v0", help="a registered task id")
    p.add_argument("--episodes", type=integer, default=10, help="episodes (1..100)")
    p.add_argument("--first-seed", type=integer, default=5000, help="first episode seed")
    p.add_argument("--json", type=Path, help="write the results here (atomically)")
    return p


def _controllers(args: Any) -> dict[str, Any]:
    """The controllers to run, by name; ``ValueError`` naming a bad one."""
    from capsule_env.agents import classical_controllers
    from capsule_env.agents.learning.sb3_policy import load_policy

    laws = classical_controllers()
    out: dict[str, Any] = {}
    for name in args.law:
        if name not in laws:
            raise ValueError(f"--law {name!r} is not one of evaluate.py's controllers")
        out[name] = laws[name]
    for path in args.policy:
        try:
            out[path] = load_policy(path)
        except (OSError, ValueError) as exc:
            raise ValueError(f"--policy {path}: {exc}") from None
    if not out:
        raise ValueError("give at least one --policy or --law")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    from capsule_env.agents.learning.training import task_env_kwargs

    from capsule_env.common.safe_io import atomic_write_text, check_writable_file
    from capsule_env.evaluation.episodes import VALIDATION_GUIDEWAY_SEED

    try:
        if not 1 <= args.episodes <= 100:
            raise ValueError(f"--episodes must be in [1, 100], got {args.episodes}")
        if not 0 <= args.first_seed <= 2**63 - 1 - args.episodes:
            raise ValueError(f"--first-seed must be in [0, 2**63 - 1 - episodes], got "
                             f"{args.first_seed}")  # fmt: skip
        task = task_env_kwargs(args.task)
        if args.json is not None:
            check_writable_file(args.json, "--json")
        controllers = _controllers(args)
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    seeds = list(range(args.first_seed, args.first_seed + args.episodes))
    results = {}
    for name, controller in controllers.items():
        own = {k: v for k, v in controller.env_kwargs.items() if k != "guideway_seed"}
        kwargs = {**task, **own, "guideway_seed": VALIDATION_GUIDEWAY_SEED}
        try:
            check_observation(name, controller, kwargs)
            row = {**action_statistics(controller, kwargs, seeds),
                   "alpha": entropy_coefficient(controller)}  # fmt: skip
        except (ValueError, TypeError) as exc:
            parser.error(f"{name}: {exc}")
        results[name] = row
        alpha = f", alpha {row['alpha']:.3g}" if row["alpha"] is not None else ""
        print(f"{name}: {row['action_mode']} mode, action mean {row['mean']:+.3f}, std "
              f"{row['std']:.3f}, at the bound {100 * row['share_at_bound']:.1f} %; Wk "
              f"{row['wk_rms_body_acc_m_s2']:.4f}{alpha}")  # fmt: skip
    if args.json is not None:
        out = {"command": "python experiments/policy_actions.py " + " ".join(sys.argv[1:] if argv is None else argv),
               "task": args.task, "guideway_seed": VALIDATION_GUIDEWAY_SEED, "seeds": seeds,
               "results": results}  # fmt: skip
        atomic_write_text(args.json, json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
