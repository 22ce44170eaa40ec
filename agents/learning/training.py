"""What ``train.py``'s run is made of: its command line, the checks made before training, the
env, and the state shared by the callbacks and the main loop (evaluation, checkpoints, clock).

- the command line and its values: :mod:`capsule_env.agents.learning.run_args` (``parse_args``,
  ``check_args``).
- :func:`prepare`: everything checked before any training time is spent (the hyperparameter
  file, the env arguments, the evaluation episode length, the checkpoint to resume from, a
  new run's folder free of another run's files), as a :class:`Plan`; it makes no folder.
  :func:`make_run_folders` makes them (and ``--tensorboard``'s), checked writable, once the
  model is built: a run refused before training leaves nothing on disk.
- :func:`make_env`: the batched numba kernel as an SB3 ``VecEnv`` + ``VecMonitor`` +
  ``VecNormalize`` (new, or with a checkpoint's statistics).
- :class:`Run` and :class:`TrainingMonitor`: held-out evaluation through
  ``capsule_env.agents.learning.sb3_policy.SB3Policy`` (the class ``evaluate.py`` loads saved policies with) on the
  validation guideway bank ``VALIDATION_GUIDEWAY_SEED`` (7; training uses bank 0, the
  reported evaluation bank 2026 is never used to choose a model), keeping
  ``best_model.*`` by the ISO 2631 Wk-weighted RMS car-body acceleration (an evaluation with a
  bump-stop hit ranks below every one without); checkpoints every ``checkpoint_freq`` env
  steps and every ``checkpoint_minutes`` of wall time (:mod:`capsule_env.agents.learning.checkpoints`);
  throughput. The passive damper and the task's best law on the same signals
  (:func:`reference_law`) run on the same evaluation seeds once, as references (printed, and
  kept in ``best_model.json``).

Output folder: ``best_model.{zip,vecnormalize.pkl,json}`` (the json: ``name``, ``algo``,
``env_kwargs`` (what ``evaluate.py`` merges into its env), ``train_env_kwargs``,
``num_timesteps``, ``wall_time_s``, ``seed``, ``num_envs``, ``hyperparams``, ``best`` and
``eval``: the seeds, ``metrics`` (``capsule_env.evaluation.episodes.episode_metrics``) and
``references``), ``final_model.*``, ``checkpoints/ckpt_<steps>.*`` and ``evaluations.jsonl``
(one line per evaluation: ``num_timesteps``, ``wall_time_s``, ``steps_per_s``,
``wk_rms_body_acc_m_s2``, ``rms_body_acc_m_s2``, ``vre_body_mode1_pct``, ``max_stroke_m``,
``terminated_episodes``).
"""

from __future__ import annotations

import json
import math
import sys
import time
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from capsule_env.agents import PassiveController, classical_controllers
from capsule_env.agents.learning.algorithms import ON_POLICY, algorithm_class
from capsule_env.agents.learning.checkpoints import (
    best_so_far,
    check_fresh_run_dir,
    find_checkpoint,
    save_checkpoint,
    save_policy,
    statistics_path,
)
from capsule_env.agents.learning.compiled import is_compiled
from capsule_env.agents.learning.hyperparams import (
    algo_kwargs_from,
    load_hyperparams,
    normalize_kwargs_from,
    resolve_env_kwargs,
)
from capsule_env.agents.learning.policy_files import clean_leftovers
from capsule_env.agents.learning.run_args import (
    restore_arguments,
    restore_env_kwargs,
    restore_hyperparams,
    run_arguments,
)
from capsule_env.agents.learning.sb3_policy import SB3Policy
from stable_baselines3.common.callbacks import BaseCallback

from capsule_env.common.safe_io import append_line, check_creatable_dir, check_writable_dir
from capsule_env.engine.config import EnvConfig
from capsule_env.evaluation.episodes import (
    VALIDATION_GUIDEWAY_SEED,
    Rollout,
    check_episode_length,
    episode_metrics,
    run_episodes,
)
from capsule_env.tasks import reference_law_for

if typing.TYPE_CHECKING:
    from stable_baselines3.common.vec_env import VecNormalize

#: ``hyperparams/`` beside ``agents/`` (a checkout), or ``capsule_env/hyperparams`` beside
#: ``capsule_env/agents`` (an installed package): the same relative place.
HYPERPARAMS_DIR = Path(__file__).resolve().parents[2] / "hyperparams"
#: Env arguments chosen by the evaluation, not by the policy (kept out of the saved metadata
#: that ``evaluate.py`` merges into its env; ``episode_length_s`` is its ``--episode-length``).
EVALUATION_CHOSEN = ("guideway_seed", "episode_length_s")


def reference_law(env_kwargs: dict) -> str:
    """The law a run on ``env_kwargs`` is compared with: its task's best on the same signals,
    else the best law on them (:func:`capsule_env.tasks.reference_law_for`); its LQ counterpart
    when the MPC's solver (the ``mpc`` extra) is missing."""
    from capsule_env.agents.controllers.mpc_solver import solver_available

    name = reference_law_for(env_kwargs)
    if "mpc" in name.split("-") and not solver_available():
        name = name.replace("preview-mpc", "preview-lq").replace("mpc", "lqr-clipped")
    return name


#: The metric ``best_model`` is chosen by (lower is better), after the bump-stop hits.
BEST_METRIC = "wk_rms_body_acc_m_s2"


def residual_of(args: Any) -> tuple[Any, float] | None:
    """``(law, scale)`` of a residual run (a fresh instance of the law), else None."""
    if not getattr(args, "residual", None):
        return None
    from capsule_env.agents.controllers.classical import make_controller

    return make_controller(args.residual), float(args.residual_scale)


# ----------------------------------------------------------------------------- before training
@dataclass
class Plan:
    """What :func:`prepare` checked and loaded before anything is trained."""

    args: Any  # the arguments, with a resumed run's own restored
    output_dir: Path
    hp: dict
    env_kwargs: dict
    norm_kwargs: dict
    algo_kwargs: dict
    algo_cls: type
    num_envs: int
    total: int  # timesteps to reach, rounded up to whole rollouts
    ckpt: Path | None = None  # the checkpoint to resume from
    ckpt_meta: dict = field(default_factory=dict)
    tensorboard_log: str | None = None

    @property
    def start_timesteps(self) -> int:
        """The timesteps done before this run: 0, or the checkpoint's."""
        return int(self.ckpt_meta.get("num_timesteps", 0))

    @property
    def statistics(self) -> Path | None:
        """The checkpoint's ``VecNormalize`` statistics, when resuming."""
        return None if self.ckpt is None else statistics_path(self.ckpt)


def output_dir_for(args: Any) -> Path:
    """The run folder: ``--resume DIR``; else ``--output-dir``; else, for ``--resume`` of a
    checkpoint ``RUN/checkpoints/ckpt_*.zip``, ``RUN``; else ``runs/<algo>-seed<seed>``.
    ``ValueError`` when ``--resume DIR`` and ``--output-dir`` name different folders."""
    resume = args.resume
    if resume and resume != "auto" and Path(resume).is_dir():
        if args.output_dir and Path(args.output_dir).resolve() != Path(resume).resolve():
            raise ValueError(f"--resume {resume} and --output-dir {args.output_dir} name "
                             "different run folders: give one")  # fmt: skip
        return Path(resume)
    if args.output_dir:
        return Path(args.output_dir)
    if resume and resume != "auto" and Path(resume).parent.name == "checkpoints":
        return Path(resume).parent.parent
    return Path(f"runs/{args.algo}-seed{args.seed}")


def _resumed(args: Any, output_dir: Path) -> tuple[Any, Path, dict, dict, dict]:
    """``(args, checkpoint, its metadata, hyperparameters, env arguments)`` of ``--resume``:
    the run's own arguments restored from the checkpoint, and those given again checked
    against them (:mod:`capsule_env.agents.learning.run_args`)."""
    ckpt, meta = find_checkpoint(args.resume, output_dir)
    args = restore_arguments(args, meta, ckpt)
    if args.hyperparams or not isinstance(meta.get("hyperparams"), dict):
        path = args.hyperparams or HYPERPARAMS_DIR / f"{args.algo}.yml"
        loaded = load_hyperparams(path)
    else:
        path, loaded = None, None
    hp = restore_hyperparams(str(path), loaded, meta, ckpt)
    env_kwargs = resolve_env_kwargs({}, restore_env_kwargs(args, meta, ckpt))
    return args, ckpt, meta, hp, env_kwargs


def prepare(args: Any) -> Plan:
    """Check everything the run needs before it starts, making no folder: the run folder (a
    new run's, or one a checkpoint of another folder continues in, holds no run's files; it is
    writable or can be made; what killed saves left there is finished or removed), the
    checkpoint to resume from (``auto``: the newest intact one) with the run's own arguments,
    the hyperparameters, the env arguments, the evaluation episode length and the TensorBoard
    folder (writable or can be made). Raises
    ``ValueError``/``OSError``/``TypeError`` with a one-line message."""
    if not 0 <= args.seed < 2**32:  # numpy's and SB3's global seeding take 32 bits
        raise ValueError(f"--seed must be in 0..{2**32 - 1}, got {args.seed}")
    output_dir = output_dir_for(args)
    if not continues_own_run(args, output_dir):  # never over another run's files (issue 40)
        check_fresh_run_dir(output_dir)
    for folder, what in RUN_FOLDERS:  # writable, or can be made; what killed saves left
        if check_creatable_dir(output_dir / folder, what).is_dir():
            clean_leftovers(output_dir / folder)
    if args.tensorboard:
        check_creatable_dir(args.tensorboard, "--tensorboard")

    ckpt: Path | None = None
    ckpt_meta: dict[str, Any] = {}
    if args.resume:  # the checkpoint's run: its arguments, statistics and model
        args, ckpt, ckpt_meta, hp, env_kwargs = _resumed(args, output_dir)
    else:
        hp = load_hyperparams(args.hyperparams or HYPERPARAMS_DIR / f"{args.algo}.yml")
        file_kwargs = {**hp.get("env_kwargs", {}), **task_env_kwargs(getattr(args, "task", None))}
        env_kwargs = resolve_env_kwargs(file_kwargs, args.env_kwargs)
    norm_kwargs, algo_kwargs = normalize_kwargs_from(hp), algo_kwargs_from(hp)
    config = EnvConfig.from_kwargs(**policy_env_kwargs(env_kwargs))
    dt_s = config.dt_s
    residual = residual_of(args)
    if residual is not None:  # the law must read this env's signals and act in its mode
        from capsule_env.agents.learning.residual import check_law_fits

        check_law_fits(residual[0], config)
    check_episode_length(args.eval_episode_length, dt_s, "--eval-episode-length")

    num_envs = args.num_envs or int(hp.get("n_envs", 1))
    total = int(args.total_timesteps or float(hp["n_timesteps"]))
    chunk = num_envs * (algo_kwargs.get("n_steps", 2048) if args.algo in ON_POLICY else 1)
    if total % chunk:
        total = (total // chunk + 1) * chunk
        print(f"total timesteps rounded up to {total} (a multiple of {chunk})")
    algo_cls = algorithm_class(args.algo)
    return Plan(args, output_dir, hp, env_kwargs, norm_kwargs, algo_kwargs, algo_cls, num_envs,
                total, ckpt, ckpt_meta, _tensorboard_log(args.tensorboard))  # fmt: skip


#: A run's folders (under ``--output-dir``) and their names in the messages.
RUN_FOLDERS = (("", "--output-dir"), ("checkpoints", "checkpoint folder"))


def continues_own_run(args: Any, output_dir: Path) -> bool:
    """Whether ``--resume`` continues the run whose folder ``output_dir`` is (``auto``, the
    folder, or a checkpoint under its ``checkpoints/``), not a checkpoint of another folder
    continued in ``output_dir``, which must then hold no run's files, as for a new run."""
    if not args.resume:
        return False
    if args.resume == "auto" or Path(args.resume).is_dir():
        return True  # output_dir_for: the folder itself
    homes = [p.parent for p in Path(args.resume).resolve().parents if p.name == "checkpoints"]
    return bool(homes) and homes[0] == output_dir.resolve()


def make_run_folders(plan: Plan) -> None:
    """Make the run's folders and ``--tensorboard``'s (:func:`prepare` checked that they can
    be), each checked writable (``ValueError`` naming it otherwise): the last step before
    training, after the model's construction, so that a run refused before training leaves
    nothing on disk."""
    for folder, what in RUN_FOLDERS:
        check_writable_dir(plan.output_dir / folder, what)
    if plan.args.tensorboard:
        check_writable_dir(plan.args.tensorboard, "--tensorboard")


def task_env_kwargs(task: str | None) -> dict[str, Any]:
    """The env arguments the task ``task`` is registered with (Gymnasium's registry; ``{}``
    for None); ``ValueError`` listing the registered tasks for another id."""
    if task is None:
        return {}
    from capsule_env.evaluation.condition import task_env_kwargs as registered_kwargs

    return registered_kwargs(task)


def _tensorboard_log(folder: str | None) -> str | None:
    """``folder`` when TensorBoard logging can run (the package installed), else None."""
    if not folder:
        return None
    try:
        import tensorboard  # noqa: F401
    except ImportError:
        print("tensorboard logging disabled: the tensorboard package is not installed "
              "(pip install tensorboard)", file=sys.stderr)  # fmt: skip
        return None
    return folder


# ----------------------------------------------------------------------------- env
def run_seed_for(seed: int, timesteps_done: int) -> int:
    """The seed of a run that starts after ``timesteps_done`` steps: ``seed`` itself for a new
    run, else an integer derived from both by ``numpy.random.SeedSequence`` (not ``seed +
    timesteps``, which could be another run's seed)."""
    if timesteps_done == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(timesteps_done)]).generate_state(1)[0])


def make_env(
    num_envs: int,
    seed: int,
    env_kwargs: dict,
    norm_kwargs: dict,
    vecnormalize: str | Path | None = None,
    residual: tuple[Any, float] | None = None,
) -> VecNormalize:
    """The batched kernel as an SB3 VecEnv, + VecMonitor + VecNormalize (new, or a saved one).
    ``residual``: ``(law, scale)``, the vehicles wrapped in
    :class:`~capsule_env.agents.learning.residual.ResidualVecEnv` (the action a correction of the law's
    request; the observation and reward unchanged).

    Vehicle ``n`` gets stream ``n`` of ``numpy.random.SeedSequence(seed)`` (guideway window,
    noise, ...) at the first reset, so that runs with different seeds share no stream."""
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

    vehicles = CapsuleSuspensionSB3VecEnv(num_envs, **env_kwargs)
    vehicles.seed(seed)
    if residual is not None:
        from capsule_env.agents.learning.residual import ResidualVecEnv

        venv = VecMonitor(ResidualVecEnv(vehicles, *residual))
    else:
        venv = VecMonitor(vehicles)
    if vecnormalize is not None:  # resume: the checkpoint's running statistics
        return VecNormalize.load(str(vecnormalize), venv)
    return VecNormalize(venv, **norm_kwargs)


def policy_env_kwargs(env_kwargs: dict) -> dict:
    """The env arguments a saved policy carries (those the evaluation chooses left out)."""
    return {k: v for k, v in env_kwargs.items() if k not in EVALUATION_CHOSEN}


# ----------------------------------------------------------------------------- the run
class Run:
    """State shared by the callbacks and the main loop: where to save, the clock, the best
    evaluation so far and the metadata that goes with every saved policy."""

    def __init__(self, args: Any, plan: Plan, model: Any) -> None:
        self.args = args
        self.plan = plan
        self.output_dir = plan.output_dir
        self.name = args.name or f"{args.algo}-seed{args.seed}"
        self.start_timesteps = int(model.num_timesteps)
        self.rollout_end_timesteps = self.start_timesteps  # PPO: the last complete rollout
        self.wall_before = float(plan.ckpt_meta.get("wall_time_s", 0.0))  # earlier runs
        self.t0 = time.perf_counter()
        self.eval_seconds = 0.0
        self.best: dict | None = None  # an evaluations.jsonl line
        if plan.ckpt is not None:  # best_model may be newer than the checkpoint
            self.best = best_so_far(self.output_dir, BEST_METRIC)
        self.last_eval_timesteps = -1
        self.eval_kwargs = {**policy_env_kwargs(plan.env_kwargs),
                            "guideway_seed": VALIDATION_GUIDEWAY_SEED}  # fmt: skip
        self.passive: Rollout | None = None
        self.references: dict = {}
        self.last_checkpoint_clock = time.monotonic()  # for --checkpoint-minutes
        self.last_checkpoint_timesteps = self.start_timesteps

    # -- clock
    def wall_time(self) -> float:
        """Wall time of this run and the runs it resumes, s."""
        return self.wall_before + time.perf_counter() - self.t0

    def steps_per_s(self, num_timesteps: int) -> float:
        """Training throughput of this process: env steps / (wall time minus evaluations)."""
        elapsed = time.perf_counter() - self.t0 - self.eval_seconds
        return (num_timesteps - self.start_timesteps) / max(elapsed, 1e-9)

    def meta(self, model: Any, **extra: Any) -> dict:
        """The metadata saved with ``model`` (``.json`` next to its ``.zip``)."""
        return {
            "name": self.name,
            "algo": self.args.algo,
            "env_kwargs": policy_env_kwargs(self.plan.env_kwargs),
            "train_env_kwargs": self.plan.env_kwargs,
            "num_timesteps": int(model.num_timesteps),
            "wall_time_s": round(self.wall_time(), 2),
            "seed": self.args.seed,
            "num_envs": model.n_envs,
            "hyperparams": self.plan.hp,
            "compiled_update": is_compiled(
                model
            ),  # this process's update (agents/learning/compiled.py)
            "args": run_arguments(self.args, self.plan.total, self.plan.num_envs, self.name),
            "best": self.best,
            **self.residual_block(),
            **extra,
        }

    def residual_block(self) -> dict:
        """``{"residual": {"law", "scale"}}`` of a residual run (what
        :func:`capsule_env.agents.learning.sb3_policy.load_policy` wraps the saved policy with), else {}."""
        if not getattr(self.args, "residual", None):
            return {}
        return {"residual": {"law": self.args.residual, "scale": float(self.args.residual_scale)}}

    def policy_of(self, model: Any) -> Any:
        """``model`` as the controller it is evaluated as: an :class:`SB3Policy` of the frozen
        statistics, plus a fresh instance of the law for a residual run."""
        policy = SB3Policy.from_model(model, model.get_vec_normalize_env(), {"name": self.name})
        residual = residual_of(self.args)
        if residual is None:
            return policy
        from capsule_env.agents.learning.residual import ResidualPolicy

        return ResidualPolicy(residual[0], policy, residual[1], name=self.name)

    # -- evaluation on the held-out guideway bank
    def _episodes(self, policy: Any, env_kwargs: dict) -> Any:
        a = self.args
        return run_episodes(policy, env_kwargs, a.eval_episodes, a.eval_seed, a.eval_episode_length)

    def evaluate(self, model: Any, logger: Any = None) -> dict:
        """Evaluate ``model`` (through :meth:`SB3Policy.from_model`, frozen statistics) on the
        held-out seeds; save it as ``best_model`` when it is the best so far; log the result
        (``evaluations.jsonl``, stdout, SB3's ``logger``). Returns the result."""
        if model.num_timesteps == self.last_eval_timesteps:
            return self.best or {}
        t_start = time.perf_counter()
        if self.passive is None:  # the VRE reference: passive damper on the same seeds
            passive_kwargs = {**self.eval_kwargs, **PassiveController.env_kwargs}
            self.passive = self._episodes(PassiveController(), passive_kwargs)
            self.references = self._references(self.passive)
        policy = self.policy_of(model)
        m = episode_metrics(self._episodes(policy, self.eval_kwargs), self.passive)
        self.eval_seconds += time.perf_counter() - t_start
        self.last_eval_timesteps = model.num_timesteps
        result = {
            "num_timesteps": int(model.num_timesteps),
            "wall_time_s": round(self.wall_time(), 2),
            "steps_per_s": round(self.steps_per_s(model.num_timesteps), 1),
            "wk_rms_body_acc_m_s2": m["wk_rms_body_acc_m_s2"],
            "rms_body_acc_m_s2": m["rms_body_acc_m_s2"],
            "vre_body_mode1_pct": m["vre_pct"]["body_mode1"],
            "max_stroke_m": m["max_stroke_m"],
            "terminated_episodes": m["terminated_episodes"],
        }
        # Best: no bump-stop hit first, then the lowest Wk-weighted RMS body acceleration.
        rank = (result["terminated_episodes"], result[BEST_METRIC])
        best = self.best
        improved = best is None or rank < (best["terminated_episodes"], best[BEST_METRIC])
        if improved:
            self.best = result
            save_policy(model, self.output_dir / "best_model",
                        self.meta(model, eval=self._eval_block(m)))  # fmt: skip
        append_line(self.output_dir / "evaluations.jsonl", json.dumps(result))
        print(
            f"[{result['num_timesteps']:>10d}] eval Wk acc {result[BEST_METRIC]:.4f} m/s^2"
            f"  VRE body m1 {result['vre_body_mode1_pct']:6.2f} %  stroke "
            f"{1000 * result['max_stroke_m']:5.1f} mm  hits {result['terminated_episodes']}"
            f"  | {result['steps_per_s']:8.0f} steps/s, {result['wall_time_s']:7.1f} s"
            + ("  *best*" if improved else ""),
            flush=True,
        )
        if logger is not None:
            for key in (BEST_METRIC, "vre_body_mode1_pct", "max_stroke_m"):
                logger.record(f"eval/{key}", result[key])
            logger.record("time/env_steps_per_s", result["steps_per_s"])
        return result

    def _references(self, passive: Rollout) -> dict:
        """Passive (its rollout ``passive``) and :func:`reference_law` on the evaluation seeds
        (numbers to compare with: the seeds differ from evaluate.py's, so do the absolute
        values)."""
        a = self.args
        refs = {"passive": {BEST_METRIC: episode_metrics(passive, None)[BEST_METRIC]}}
        name = reference_law(self.plan.env_kwargs)
        law = classical_controllers().get(name)
        if law is not None:
            m = episode_metrics(self._episodes(law, {**self.eval_kwargs, **law.env_kwargs}),
                                passive)  # fmt: skip
            refs[name] = {
                BEST_METRIC: m[BEST_METRIC],
                "vre_body_mode1_pct": m["vre_pct"]["body_mode1"],
            }
        described = [
            f"{name} Wk {r[BEST_METRIC]:.4f} m/s^2"
            + (
                f", VRE body m1 {r['vre_body_mode1_pct']:.2f} %"
                if "vre_body_mode1_pct" in r
                else ""
            )
            for name, r in refs.items()
        ]
        print(f"evaluation: seeds {a.eval_seed}..{a.eval_seed + a.eval_episodes - 1} of the "
              f"validation guideway bank {VALIDATION_GUIDEWAY_SEED}; references: "
              + "; ".join(described), flush=True)  # fmt: skip
        return refs

    def _eval_block(self, m: dict) -> dict:
        a = self.args
        return {
            "guideway_seed": VALIDATION_GUIDEWAY_SEED,
            "seeds": [a.eval_seed, a.eval_seed + a.eval_episodes - 1],
            "episode_length_s": a.eval_episode_length,
            "metrics": m,
            "references": self.references,
        }

    # -- checkpoints
    def checkpoint(self, model: Any) -> Path:
        """Save a checkpoint of ``model`` now (:func:`capsule_env.agents.learning.checkpoints.save_checkpoint`)."""
        path = save_checkpoint(
            model, self.output_dir / "checkpoints", self.meta(model), self.args.keep_replay_buffers
        )
        self.last_checkpoint_clock = time.monotonic()
        self.last_checkpoint_timesteps = int(model.num_timesteps)
        return path

    def report(self, model: Any) -> None:
        """Print the throughput of this process and the best evaluation."""
        steps = model.num_timesteps - self.start_timesteps
        elapsed = time.perf_counter() - self.t0
        print(
            f"done: {model.num_timesteps} timesteps; this process {steps} steps in {elapsed:.1f}"
            f" s wall ({steps / max(elapsed, 1e-9):.0f} steps/s overall, "
            f"{self.steps_per_s(model.num_timesteps):.0f} steps/s training without evaluations;"
            f" total wall time {self.wall_time():.1f} s)",
            flush=True,
        )
        if self.best:
            print(f"best: Wk acc {self.best[BEST_METRIC]:.4f} m/s^2, VRE body m1 "
                  f"{self.best['vre_body_mode1_pct']:.2f} % at {self.best['num_timesteps']} "
                  f"timesteps -> {self.output_dir / 'best_model.zip'}")  # fmt: skip


def _next_multiple(steps: int, every: int) -> float:
    return math.inf if every <= 0 else (steps // every + 1) * every


class TrainingMonitor(BaseCallback):
    """Held-out evaluation (:meth:`Run.evaluate`) every ``eval_freq`` env steps, a checkpoint
    every ``checkpoint_freq`` env steps and, between rollouts, when ``checkpoint_minutes`` of
    wall time have passed since the last one."""

    def __init__(self, run: Run) -> None:
        super().__init__()
        self.run = run
        self.next_eval = _next_multiple(run.start_timesteps, run.args.eval_freq)
        self.next_ckpt = _next_multiple(run.start_timesteps, run.args.checkpoint_freq)

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_eval:
            self.next_eval = _next_multiple(self.num_timesteps, self.run.args.eval_freq)
            self.run.evaluate(self.model, logger=self.logger)
        if self.num_timesteps >= self.next_ckpt:
            self.next_ckpt = _next_multiple(self.num_timesteps, self.run.args.checkpoint_freq)
            self._checkpoint("checkpoint")
        return True

    def _on_rollout_start(self) -> None:
        # Between rollouts the model has learned from every step it counts (PPO: the
        # previous rollout; SAC/TD3: the gradient steps after the last env step).
        minutes = self.run.args.checkpoint_minutes
        due = time.monotonic() - self.run.last_checkpoint_clock >= 60.0 * minutes
        if minutes > 0 and due and self.num_timesteps > self.run.last_checkpoint_timesteps:
            self._checkpoint(f"checkpoint ({minutes:g} min)")

    def _on_rollout_end(self) -> None:
        self.run.rollout_end_timesteps = self.num_timesteps

    def _checkpoint(self, label: str) -> None:
        path = self.run.checkpoint(self.model)
        print(f"[{self.num_timesteps:>10d}] {label} {path}", flush=True)
