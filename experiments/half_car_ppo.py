"""PPO on the half-car task (``CapsuleHalfRide-v0``), several seeds, evaluated beside the
per-bogie clipped LQR on the held-out episodes; checkpoints and resumes.

    python experiments/half_car_ppo.py --out runs/half_car_ppo            # 5 seeds x 1M steps
    python experiments/half_car_ppo.py --out runs/half_car_ppo --evaluate  # the figures only
    python experiments/half_car_ppo.py --out runs/half_car_residual --residual  # on the LQR
    python experiments/half_car_ppo.py --out runs/half_car_residual_mpc --residual \
        --law wheelbase-mpc-biexp-meas                  # on the best law, the wheelbase MPC

Read top to bottom: the arguments, one seed's training (SB3 PPO with ``hyperparams/ppo.yml``'s
ride-task values, the training bank ``guideway_seed`` 0, a checkpoint every
``--checkpoint-every`` steps, resumed from the newest after an interruption; the run folder's
``run.json`` records the options that shape the networks, ``--residual``, ``--law``,
``--learning-rate``, ``--num-envs``, and a resume with others, or ``--evaluate`` with another
law, is refused), one seed's
evaluation (10 s episodes 1000.. of the evaluation bank 2026, the deterministic action), and
the group's IQM over the seeds against the per-bogie LQR (and the law a residual rides on) on the
same episodes with a 95 %
bootstrap interval over seeds and episodes (:func:`capsule_env.evaluation.rl_statistics.paired_ratio_interval`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class Args:
    out: Path  # the run folder: seed<k>/ per seed, results.json
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)  # training seeds (independent streams)
    total_timesteps: int = 1_000_000  # env steps per seed
    num_envs: int = 256  # vehicles per vector step (hyperparams/ppo.yml)
    checkpoint_every: int = 200_000  # env steps between checkpoints
    eval_episodes: int = 10  # held-out episodes 1000.. of the evaluation bank
    evaluate_only: bool = False  # skip training: evaluate what is saved
    residual: bool = False  # learn a residual on the law ``law`` (scale 0.5)
    law: str = "lqr-clipped-biexp-meas"  # the residual's law: a key of LAWS
    learning_rate: float = 1e-3  # the linear schedule's start (hyperparams/ppo.yml: lin_1e-3)


#: The residual's scale: half the action range, as the quarter-car's residual policies.
RESIDUAL_SCALE = 0.5


#: The laws a residual can ride on: the per-bogie clipped LQR (no memory) and the best law
#: without the survey, the wheelbase MPC with its tuned weights (a memory per vehicle: the
#: front's rises, the requests in flight, the plan; reset at each vehicle's episode start).
LAWS = ("lqr-clipped-biexp-meas", "wheelbase-mpc-biexp-meas")


def _law(name: str = LAWS[0]) -> Any:
    if name == "wheelbase-mpc-biexp-meas":
        from capsule_env.evaluation.half_car import tuned_mpc

        return tuned_mpc(name)
    from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR

    return IndependentClippedLQR()


def _law_action(law: Any, obs: Any, starts: np.ndarray) -> np.ndarray:
    """The law's action on ``obs``, the vehicles flagged in ``starts`` starting afresh."""
    return law.predict(np.asarray(obs, dtype=np.float64), episode_start=starts)[0]


def _residual_wrapper(venv: Any, law_name: str) -> Any:
    """``a = clip(a_law(obs) + 0.5 a_policy, -1, 1)`` on an SB3 VecEnv (SB3 resets a finished
    vehicle at once: its next observation starts an episode, and the law's memory of that
    vehicle starts afresh with it)."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class Residual(VecEnvWrapper):
        def __init__(self, venv: Any) -> None:
            super().__init__(venv)
            self.law, self._obs = _law(law_name), None
            self._starts = np.ones(venv.num_envs, dtype=bool)

        def reset(self) -> Any:
            self._obs = self.venv.reset()
            self._starts = np.ones(self.num_envs, dtype=bool)
            return self._obs

        def step_async(self, actions: np.ndarray) -> None:
            base = _law_action(self.law, self._obs, self._starts)
            self.venv.step_async(np.clip(base + RESIDUAL_SCALE * actions, -1.0, 1.0))

        def step_wait(self) -> Any:
            obs, reward, done, infos = self.venv.step_wait()
            self._obs, self._starts = obs, np.asarray(done, dtype=bool).copy()
            return obs, reward, done, infos

    return Residual(venv)


def _env(args: Args, seed: int) -> Any:
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from capsule_env.envs.declared_sb3 import DeclaredSB3VecEnv
    from capsule_env.evaluation.half_car import TASK_KWARGS, TRAINING_GUIDEWAY_SEED

    venv = DeclaredSB3VecEnv(args.num_envs, guideway_seed=TRAINING_GUIDEWAY_SEED, **TASK_KWARGS)
    venv.seed(seed)
    wrapped = _residual_wrapper(venv, args.law) if args.residual else venv
    return VecNormalize(VecMonitor(wrapped), norm_obs=True, norm_reward=True, clip_obs=10.0,
                        gamma=0.99)  # fmt: skip


def _save_atomic(model: Any, env: Any, folder: Path, stem: str) -> None:
    """``stem.vecnormalize.pkl``, then ``stem.zip``, each written whole or not at all: a
    ``stem.zip`` (what :func:`_newest_checkpoint` and the ``final.zip`` test look for) exists
    only beside its normaliser."""
    for suffix, save in ((".vecnormalize.pkl", env.save), (".zip", model.save)):
        with tempfile.NamedTemporaryFile(dir=folder, suffix=suffix, delete=False) as f:
            tmp = f.name
        try:
            save(tmp)
            os.replace(tmp, folder / f"{stem}{suffix}")
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)


def _learning_rate(done: int, chunk: int, total: int, start: float = 1e-3) -> Any:
    """The schedule for ``model.learn(chunk)`` from ``done`` steps: the run's linear decay
    from ``start`` (``hyperparams/ppo.yml``'s ``lin_1e-3``: 1e-3) to 0 over ``total`` steps. SB3's
    progress is ``1 - steps / (done + chunk)`` (from ``done / (done + chunk)`` down to 0, and
    below 0 when the last rollout overshoots the chunk), so the steps done are recovered from
    it; the rate stops at 0."""

    def rate(progress_remaining: float) -> float:
        steps = (1.0 - progress_remaining) * (done + chunk)
        return start * max(0.0, 1.0 - steps / total)

    return rate


def _newest_checkpoint(folder: Path) -> tuple[Path, int] | None:
    steps = sorted(int(p.stem.split("_")[1]) for p in folder.glob("step_*.zip"))
    return (folder / f"step_{steps[-1]}", steps[-1]) if steps else None


def train_seed(args: Args, seed: int) -> Path:
    """Train (or resume) one seed; returns its folder, with ``final.zip`` when done."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    folder = args.out / f"seed{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    if (folder / "final.zip").exists():
        return folder
    env = _env(args, seed)
    latest = _newest_checkpoint(folder)
    if latest is not None:  # resume: the model, its optimiser and the normaliser's statistics
        env = VecNormalize.load(f"{latest[0]}.vecnormalize.pkl", env.venv)
        model = PPO.load(f"{latest[0]}.zip", env=env)
    else:
        model = PPO("MlpPolicy", env, n_steps=64, batch_size=2048, n_epochs=10, gamma=0.99,
                    gae_lambda=0.95, learning_rate=args.learning_rate, clip_range=0.2,
                    ent_coef=0.0, max_grad_norm=0.5, seed=seed, verbose=0,
                    policy_kwargs={"net_arch": [64, 64], "log_std_init": -1.0})  # fmt: skip
        if args.residual:  # start from the law's behaviour exactly
            from capsule_env.agents.learning.residual import zero_last_layer

            zero_last_layer(model)
    while model.num_timesteps < args.total_timesteps:
        chunk = min(args.checkpoint_every, args.total_timesteps - model.num_timesteps)
        model.lr_schedule = _learning_rate(model.num_timesteps, chunk, args.total_timesteps,
                                           args.learning_rate)  # fmt: skip
        model.learn(chunk, reset_num_timesteps=False)
        _save_atomic(model, env, folder, f"step_{model.num_timesteps}")
    _save_atomic(model, env, folder, "final")
    return folder


class _Policy:
    """A saved seed's deterministic action on raw observations (its normaliser inside)."""

    def __init__(self, folder: Path, residual: bool = False, law: str = LAWS[0]) -> None:
        import pickle

        from stable_baselines3 import PPO

        self.model = PPO.load(folder / "final.zip", device="cpu")
        with open(folder / "final.vecnormalize.pkl", "rb") as f:
            self.norm = pickle.load(f)
        from capsule_env.evaluation.half_car import TASK_KWARGS

        self.env_kwargs = dict(TASK_KWARGS)
        self.law = _law(law) if residual else None

    def reset(self) -> None:
        """A new batch of episodes: the law's memory starts afresh (``rollout`` calls it)."""
        if hasattr(self.law, "reset"):
            self.law.reset()

    def predict(self, obs: np.ndarray) -> tuple[np.ndarray, None]:
        action, _ = self.model.predict(self.norm.normalize_obs(obs), deterministic=True)
        if self.law is not None:
            base = self.law.predict(np.asarray(obs, dtype=np.float64))[0]
            action = np.clip(base + RESIDUAL_SCALE * action, -1.0, 1.0)
        return action, None


def evaluate(args: Args) -> dict[str, Any]:
    """Each seed's Wk per held-out episode, the per-bogie LQR's (and the residual's law's), and
    the group's ratio to each."""
    from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR

    from capsule_env.evaluation.half_car import EVALUATION_GUIDEWAY_SEED, episode_metrics, rollout
    from capsule_env.evaluation.rl_statistics import paired_ratio_interval

    episodes = list(range(1000, 1000 + args.eval_episodes))
    law = episode_metrics(rollout(IndependentClippedLQR(), episodes, EVALUATION_GUIDEWAY_SEED))
    per_seed = {}
    for seed in args.seeds:
        folder = args.out / f"seed{seed}"
        if (folder / "final.zip").exists():
            policy = _Policy(folder, args.residual, args.law)
            roll = rollout(policy, episodes, EVALUATION_GUIDEWAY_SEED)
            per_seed[seed] = episode_metrics(roll)["wk_rms_body_acc_m_s2"].tolist()
    law_wk = law["wk_rms_body_acc_m_s2"]
    group = "residual-ppo" if args.residual else "ppo"
    out: dict[str, Any] = {"episodes": episodes, "lqr-clipped-biexp-meas": law_wk.tolist(),
                           f"{group}_per_seed": per_seed}  # fmt: skip
    if len(per_seed) >= 2:
        est = paired_ratio_interval(np.array(list(per_seed.values())), law_wk)
        out[f"{group}_iqm_ratio_to_lqr"] = [est.value, est.low, est.high]
    if args.residual and args.law != LAWS[0]:
        base = episode_metrics(rollout(_law(args.law), episodes, EVALUATION_GUIDEWAY_SEED))
        out[args.law] = base["wk_rms_body_acc_m_s2"].tolist()
        if len(per_seed) >= 2:
            est = paired_ratio_interval(np.array(list(per_seed.values())), np.array(out[args.law]))
            out[f"{group}_iqm_ratio_to_law"] = [est.value, est.low, est.high]
    return out


#: The run folder's record of the options that shape its saved networks (``run.json``).
RUN_RECORD = "run.json"
#: The options ``--evaluate`` must repeat (the law under the networks); training repeats all.
_SCORED = ("residual", "law")


def _run_options(args: Args) -> dict[str, Any]:
    """The options that shape a run's saved networks: the law under them (none without
    ``--residual``), the learning rate, the vehicles per step."""
    return {"residual": args.residual, "law": args.law if args.residual else None,
            "learning_rate": args.learning_rate, "num_envs": args.num_envs}  # fmt: skip


def read_record(folder: Path) -> dict[str, Any] | None:
    """``folder``'s ``run.json`` (None when it has none); ``ValueError`` naming the file when
    it is not a JSON object."""
    path = folder / RUN_RECORD
    if not path.is_file():
        return None
    try:
        recorded = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        recorded = None
    if not isinstance(recorded, dict):
        raise ValueError(f"{path} is not a JSON object")
    return recorded


def _record_problem(args: Args) -> str:
    """Why ``args`` cannot resume (or, with ``--evaluate``, score) the run folder it names: the
    options its ``run.json`` records differ (``""`` when they agree or there is no record)."""
    try:
        recorded = read_record(args.out)
    except ValueError as exc:
        return f"--out: {exc}"
    if recorded is None:
        return ""
    mine = _run_options(args)
    keys = _SCORED if args.evaluate_only else tuple(mine)
    was = ", ".join(f"--{k.replace('_', '-')} {recorded.get(k)!r} (given {mine[k]!r})"
                    for k in keys if recorded.get(k) != mine[k])  # fmt: skip
    return (
        f"--out {args.out} was trained with {was}: pass the same options, or another --out"
        if was
        else ""
    )


def _record_options(args: Args) -> None:
    """Write the run folder's ``run.json`` (atomically) unless it is there already."""
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / RUN_RECORD
    if path.is_file():
        return
    with tempfile.NamedTemporaryFile("w", dir=args.out, suffix=".tmp", delete=False) as f:
        json.dump(_run_options(args), f, indent=1)
    os.replace(f.name, path)


def parse_args(argv: list[str] | None = None) -> Args:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--seeds", default="0,1,2,3,4", help="comma-separated training seeds")
    p.add_argument("--total-timesteps", type=int, default=1_000_000)
    p.add_argument("--num-envs", type=int, default=256)
    p.add_argument("--checkpoint-every", type=int, default=200_000)
    p.add_argument("--eval-episodes", type=int, default=10)
    p.add_argument(
        "--learning-rate",
        type=float,
        default=1e-3,
        help="the linear schedule's start (default 1e-3, hyperparams/ppo.yml)",
    )
    p.add_argument("--evaluate", action="store_true", help="evaluate the saved seeds only")
    p.add_argument("--residual", action="store_true", help="a residual on the law --law")
    p.add_argument("--law", default=LAWS[0], help=f"the residual's law: one of {', '.join(LAWS)}")
    a = p.parse_args(argv)
    try:
        seeds = tuple(int(s) for s in a.seeds.split(","))
    except ValueError:
        seeds = ()
    if not seeds or len(set(seeds)) < len(seeds) or not all(0 <= s < 2**32 for s in seeds):
        p.exit(2, "error: --seeds must be distinct comma-separated integers in [0, 2**32), "
                  f"got {a.seeds!r}\n")  # fmt: skip
    if a.law not in LAWS or (a.law != LAWS[0] and not a.residual):
        p.exit(
            2, f"error: --law must be one of {', '.join(LAWS)}, with --residual, got {a.law!r}\n"
        )
    if a.evaluate and not a.out.is_dir():
        p.exit(2, f"error: --out must be an existing run folder with --evaluate, got {a.out}\n")
    if a.out.exists() and not a.out.is_dir():
        p.exit(2, f"error: --out must be a run folder (or a new one), got the file {a.out}\n")
    if not 0.0 < a.learning_rate <= 1.0:  # NaN fails too
        p.exit(2, f"error: --learning-rate must be in (0, 1], got {a.learning_rate}\n")
    if min(a.total_timesteps, a.num_envs, a.checkpoint_every) < 1 or a.eval_episodes < 2:
        p.exit(2, "error: --total-timesteps, --num-envs, --checkpoint-every >= 1 and "
                  "--eval-episodes >= 2\n")  # fmt: skip
    args = Args(a.out, seeds, a.total_timesteps, a.num_envs, a.checkpoint_every,
                a.eval_episodes, a.evaluate, a.residual, a.law, a.learning_rate)  # fmt: skip
    problem = _record_problem(args)
    if problem:
        p.exit(2, f"error: {problem}\n")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if not args.evaluate_only:
        _record_options(args)
        for seed in args.seeds:
            train_seed(args, seed)
    result = {"command": "python experiments/half_car_ppo.py " + " ".join(argv or sys.argv[1:]),
              **evaluate(args)}  # fmt: skip
    path = args.out / "results.json"
    with tempfile.NamedTemporaryFile("w", dir=args.out, suffix=".tmp", delete=False) as f:
        json.dump(result, f, indent=1)
    os.replace(f.name, path)
    print(json.dumps({k: v for k, v in result.items() if not k.endswith("_per_seed")}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
