"""Train a stable-baselines3 / sb3-contrib agent on the ride task (``CapsuleRide-v0``).

    python train.py                                   # PPO, defaults from hyperparams/ppo.yml
    python train.py --algo sac --total-timesteps 300000
    python train.py --env setting=sim --env reward_stroke_weight=0.2
    python train.py --task CapsuleTrip-v0             # a registered task's env arguments
    python train.py --resume auto                     # continue runs/ppo-seed0 after a Ctrl-C
    python evaluate.py --policy runs/ppo-seed0/best_model.zip --setting hils

Hyperparameters: ``hyperparams/<algo>.yml`` (RL-Zoo format). Env: the realistic ride task
``CapsuleRide-v0`` (``hils``, the ``measured`` signals; force mode), unless the file's
``env_kwargs`` (the shipped files: the same options), ``--env-kwargs`` or ``--env`` say
otherwise; training on guideway bank 0, evaluation every ``--eval-freq`` steps on the
validation bank 7 (the evaluation bank 2026 that evaluate.py reports on is never used to
choose a model). Output (``--output-dir``, default ``runs/<algo>-seed<seed>``):
``best_model.*`` (the best evaluation by the Wk-weighted RMS car-body acceleration;
``evaluate.py --policy`` loads it), ``final_model.*``, ``checkpoints/`` (every
``--checkpoint-freq`` steps and ``--checkpoint-minutes``, on Ctrl-C or SIGTERM and at the end;
``--resume``) and ``evaluations.jsonl``. Each save is one atomic step (agents/learning/policy_files.py);
``--resume`` restores the run's own arguments from the checkpoint and refuses one given again
with another value (agents/learning/run_args.py); Ctrl-C prints the command that continues the run. Bad
arguments stop the script before training, and a full disk during it, with one line on stderr.
Details: agents/learning/training.py, agents/learning/checkpoints.py, agents/learning/run_args.py, agents/learning/hyperparams.py.
"""

from __future__ import annotations

import signal
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numba
import torch
from capsule_env.agents.learning.algorithms import ON_POLICY
from capsule_env.agents.learning.checkpoints import (
    RunFolderLock,
    check_fresh_run_dir,
    logged_timesteps,
    resume_model,
    save_policy,
    saved_at,
)
from capsule_env.agents.learning.compiled import check_compile, compile_update
from capsule_env.agents.learning.residual import zero_last_layer
from capsule_env.agents.learning.run_args import continue_command
from capsule_env.agents.learning.run_args import parse_args as parse_dataclass_args
from capsule_env.agents.learning.training import (
    HYPERPARAMS_DIR,
    Run,
    TrainingMonitor,
    continues_own_run,
    make_env,
    make_run_folders,
    output_dir_for,
    prepare,
    residual_of,
    run_seed_for,
)
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.utils import set_random_seed


@dataclass
class Args:
    algo: Literal["ppo", "sac", "td3", "tqc", "crossq", "recurrentppo"] = "ppo"
    """the algorithm (capsule_env.agents.learning.algorithms; tqc, crossq, recurrentppo from sb3-contrib)"""
    total_timesteps: int | None = None
    """env steps, all vehicles together (default: the file's n_timesteps, or the resumed run's),
    rounded up to whole PPO rollouts (n_steps * num_envs) or vector steps"""
    num_envs: int | None = None
    """vehicles simulated in parallel (default: the file's n_envs, or the resumed run's)"""
    seed: int = 0
    """random seed of torch, numpy and the vehicles (runs with different seeds share no stream)"""
    task: str | None = None
    """a registered task id (capsule_env.tasks, e.g. CapsuleTrip-v0): its env arguments, read
    from Gymnasium's registry, over the hyperparameter file's env_kwargs (--env-kwargs and
    --env over them)"""
    env_kwargs: dict = field(default_factory=dict)
    """env arguments, a JSON object or Python dict literal such as '{"speed_kmh": 600}', over
    the file's env_kwargs and the defaults (the ride task CapsuleRide-v0: setting hils,
    observation measured; action_mode force)"""
    env: list[str] = field(default_factory=list)
    """one env argument KEY=VALUE (VALUE JSON or a Python literal, a bare word a string),
    repeatable, merged over --env-kwargs: --env setting=sim --env speed_kmh=600"""
    residual: str | None = None
    """train a residual policy: its action is a correction added to this classical law's
    request (a name of evaluate.py's controllers that reads the env's signals, e.g.
    lqr-clipped-biexp-meas), its last layer zeroed so that training starts from the law;
    the saved policy evaluates as that sum (agents/learning/residual.py)"""
    residual_scale: float = 0.5
    """--residual: the correction's scale, in (0, 2] of the action range (0.5: 4 kN in force
    mode)"""
    output_dir: str | None = None
    """output folder (default: runs/<algo>-seed<seed>)"""
    name: str | None = None
    """the policy's name in evaluate.py's tables (default: <algo>-seed<seed>)"""
    eval_freq: int = 200_000
    """evaluate on the validation guideway bank every this many env steps (0: only at the end)"""
    eval_episodes: int = 10
    """episodes per evaluation"""
    eval_seed: int = 5000
    """first evaluation episode seed (evaluate.py reports on 1000..)"""
    eval_episode_length: float = 10.0
    """seconds per evaluation episode"""
    checkpoint_freq: int = 500_000
    """save a checkpoint every this many env steps (0: off)"""
    checkpoint_minutes: float = 5.0
    """also save one when this many minutes of wall time have passed since the last (0: off)"""
    keep_replay_buffers: int = 2
    """SAC/TD3: keep the replay buffers of only the newest this many checkpoints"""
    resume: str | None = None
    """continue a run: 'auto' (the newest intact checkpoint in output_dir), a run folder, or a
    checkpoint .zip; the run's own arguments (env, budget, algorithm, hyperparameters, seed,
    evaluation) come from the checkpoint, and one given again with another value is refused"""
    tensorboard: str | None = None
    """tensorboard log folder (needs the tensorboard package)"""
    threads: int = 1
    """torch CPU threads (1 is fastest here)"""
    env_threads: int = 1
    """numba threads of the env kernel (1: the env and the learner take turns on one core; on
    a 2-core machine that other jobs share, 2 made PPO's training 2.2 x slower: the kernel's
    threads wait for a core at every step; benchmarks/bench_training.py --env-threads)"""
    compile: bool = False
    """PPO: run the update's forward and backward passes under torch.compile (the first
    update compiles, for seconds; then each gradient step is faster: agents/learning/compiled.py,
    docs/benchmarks.md); the saved policy is the same as without"""
    progress: bool = True
    """show a progress bar"""
    hyperparams: str | None = None
    """RL-Zoo yml file (default: hyperparams/<algo>.yml)"""
    device: str = "cpu"
    """torch device"""
    verbose: int = 0
    """SB3 verbosity (1: SB3's log tables)"""
    explicit: frozenset[str] | None = field(default=None, metadata={"cli": False})
    """the fields the command line gave (set by parse_args; None: every field that is not None
    counts as given): what --resume checks against the run's own arguments"""


def train(args: Args, extra_callbacks: list | None = None) -> dict:
    """Train as ``args`` says; returns a summary (paths, timesteps, best evaluation, model).
    Bad arguments or files raise ``SystemExit`` with one line before training starts, and so
    does a run folder another ``train.py`` is working in; a failed write (a full disk) raises
    ``SystemExit`` with one line too, the files as the last complete save left them."""
    with RunFolderLock() as lock:  # one process per run folder (agents/learning/checkpoints.py)
        try:  # hyperparameters, env arguments, checkpoint, writable folders: checked first
            if not args.resume:  # before any folder is made
                check_compile(args.algo, args.compile)
            lock.acquire(output_dir_for(args))  # an existing folder: before prepare cleans it
            plan = prepare(args)
            if args.resume:  # the algorithm the checkpoint restored
                check_compile(plan.args.algo, plan.args.compile)
        except (ValueError, OSError, TypeError) as exc:
            raise SystemExit(f"train.py: error: {exc}") from None
        return _train(plan, lock, extra_callbacks)


def _train(plan: Any, lock: RunFolderLock, extra_callbacks: list | None) -> dict:
    args = plan.args  # a resumed run's own arguments restored (agents/learning/run_args.py)
    torch.set_num_threads(args.threads)
    numba.set_num_threads(min(args.env_threads, numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]

    # Seeds, in one place: torch, numpy, random and the vehicles' streams. A resumed run gets
    # a seed derived from the seed and the timesteps done, so it does not replay the start.
    run_seed = run_seed_for(args.seed, plan.start_timesteps)
    set_random_seed(run_seed)
    try:  # a configuration too large for this machine's memory: refused in one line
        env = make_env(plan.num_envs, run_seed, plan.env_kwargs, plan.norm_kwargs,
                       plan.statistics, residual_of(args))  # fmt: skip
    except ValueError as exc:
        raise SystemExit(f"train.py: error: {exc}") from None
    try:
        model = _model(args, plan, env, run_seed)
        _make_folders(plan, lock)  # only now: a run refused before training leaves nothing
        run = Run(args, plan, model)  # evaluation, best model, checkpoints, clock
        interrupted = _learn(run, model, extra_callbacks)
        if not interrupted:
            _finish(run, model)
        if model.num_timesteps != run.last_checkpoint_timesteps:  # always resumable at the end
            run.checkpoint(model)
        run.report(model)  # throughput and the best evaluation
    except OSError as exc:  # a full disk, a folder gone: the saves left the files consistent
        raise SystemExit(_write_failed(exc, args, plan.output_dir)) from None
    finally:
        env.close()
    return {"output_dir": str(plan.output_dir), "num_timesteps": int(model.num_timesteps),
            "interrupted": interrupted, "best": run.best, "wall_time_s": run.wall_time(),
            "model": model}  # fmt: skip


def _write_failed(exc: OSError, args: Args, output_dir: Path) -> str:
    """The one line for a failed write: the command that continues the run when a checkpoint
    was saved, else that nothing can be continued (issue 40: it offered ``--resume auto``
    when no checkpoint existed, which could not work)."""
    where = f" ({exc.filename})" if exc.filename else ""
    head = f"train.py: error: {exc.strerror or exc}{where}; "
    if any((output_dir / "checkpoints").glob("ckpt_*.zip")):
        return (f"{head}the run's files are as its last complete save left them; once fixed, "
                f"continue with: {continue_command(args, output_dir)}")  # fmt: skip
    return (f"{head}no checkpoint was saved, so there is nothing to continue: once fixed, "
            f"remove {output_dir} and start the run again")  # fmt: skip


def _make_folders(plan: Any, lock: RunFolderLock) -> None:
    """The run's folders made; a folder made just now locked, and looked at again: another run
    may have started in it since :func:`prepare` looked (a one-line ``SystemExit`` then)."""
    try:
        make_run_folders(plan)
        if lock.fd is None:
            lock.acquire(plan.output_dir)
            if not continues_own_run(plan.args, plan.output_dir):
                check_fresh_run_dir(plan.output_dir)
    except ValueError as exc:
        raise SystemExit(f"train.py: error: {exc}") from None


def _model(args: Args, plan: Any, env: Any, run_seed: int) -> Any:
    """A new model on ``env``, or the checkpoint's when resuming; hyperparameters the
    algorithm refuses (an unknown key, a value its checks reject) stop the run with one line."""
    if plan.ckpt is None:
        try:
            model = plan.algo_cls(env=env, seed=run_seed, device=args.device,
                                  verbose=args.verbose, tensorboard_log=plan.tensorboard_log,
                                  **plan.algo_kwargs)  # fmt: skip
        except (TypeError, ValueError, AssertionError) as exc:  # SB3 checks some by assert
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            source = args.hyperparams or HYPERPARAMS_DIR / f"{args.algo}.yml"
            raise SystemExit(f"train.py: error: the hyperparameters ({source}) do not make a "
                             f"{args.algo.upper()}: {reason}") from None  # fmt: skip
        if args.residual:  # start from the law's behaviour exactly (the residual's mean is 0)
            zero_last_layer(model)
    else:
        # Algo.load(env=env): learn() first resets the env, which adds that one batch of
        # observations to the checkpoint's VecNormalize statistics (agents/learning/checkpoints.py)
        model = resume_model(plan.algo_cls, plan.ckpt, env, device=args.device,
                             verbose=args.verbose, tensorboard_log=plan.tensorboard_log)  # fmt: skip
    if args.compile:
        compile_update(model)
    return model


def _learn(run: Run, model: Any, extra_callbacks: list | None) -> bool:
    """Train up to the budget; on Ctrl-C (or SIGTERM) save a checkpoint and print the command
    that continues the run. Returns whether it was interrupted."""
    args, plan = run.args, run.plan
    callbacks = CallbackList([TrainingMonitor(run), *(extra_callbacks or [])])
    env_id = args.task or "CapsuleSuspension-v0"
    print(f"{args.algo.upper()} on {env_id} {plan.env_kwargs}: {plan.num_envs} vehicles, "
          f"{plan.total} timesteps, torch threads {args.threads}; output "
          f"{plan.output_dir}", flush=True)  # fmt: skip
    try:
        if plan.total > model.num_timesteps:
            model.learn(plan.total - model.num_timesteps, callback=callbacks,
                        reset_num_timesteps=plan.ckpt is None, progress_bar=args.progress,
                        tb_log_name=run.name)  # fmt: skip
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (see main): a checkpoint to resume from
        if args.algo in ON_POLICY:  # a rollout cut short was not learned from: count it out
            model.num_timesteps = run.rollout_end_timesteps
        path = run.checkpoint(model)
        print(f"\ninterrupted at {model.num_timesteps} timesteps: checkpoint {path}\n"
              f"continue with: {continue_command(args, plan.output_dir)}")  # fmt: skip
        return True
    return False


def _finish(run: Run, model: Any) -> None:
    """The final evaluation (the final policy is a candidate for the best one too) and
    ``final_model``. A resumed run that learned nothing here (it had finished, or was cut off
    during these last steps) does only what is missing: an evaluation already in
    ``evaluations.jsonl`` is not repeated, a ``final_model`` already saved is kept."""
    steps, output_dir = int(model.num_timesteps), run.output_dir
    nothing_learned = run.plan.ckpt is not None and steps == run.start_timesteps
    if nothing_learned and steps in logged_timesteps(output_dir / "evaluations.jsonl"):
        print(f"the run had finished at {steps} timesteps: its final evaluation is in "
              f"{output_dir / 'evaluations.jsonl'}")  # fmt: skip
    else:
        run.evaluate(model)
    if not (nothing_learned and saved_at(output_dir / "final_model", steps)):
        final_meta = run.meta(model, name=f"{run.name}-final")  # its own row in evaluate.py
        save_policy(model, output_dir / "final_model", final_meta)


def parse_args(argv: list[str] | None = None) -> Args:
    """The command line as :class:`Args`; a bad value exits with one line on stderr."""
    return parse_dataclass_args(Args, argv, __doc__)


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    signal.signal(signal.SIGTERM, _interrupt)  # a job scheduler's SIGTERM checkpoints too
    return 130 if train(args)["interrupted"] else 0


if __name__ == "__main__":
    sys.exit(main())
