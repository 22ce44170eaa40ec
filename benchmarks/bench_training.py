"""Training speed per algorithm: env-steps/s and the time to reach the clipped LQR's Wk.

    python benchmarks/bench_training.py                        # every algorithm, 120 s each
    python benchmarks/bench_training.py --algos ppo sac --budget-s 60 --json out.json
    python benchmarks/bench_training.py --algos ppo --hp n_epochs=2 --hp batch_size=8192
    python benchmarks/bench_training.py --algos ppo --compile both   # eager, then compiled

For each algorithm of ``--algos`` (``capsule_env.agents.learning.algorithms``), in one process: the
run ``train.py --algo ALGO`` would make (``hyperparams/<algo>.yml``, its env arguments: the
ride task ``CapsuleRide-v0``; ``--hp KEY=VALUE`` and ``--num-envs`` override the file), whose
policy is evaluated every ``--eval-every-s`` seconds of training on the validation guideway
bank (bank 7, seeds 5000..5009, 10 s episodes: train.py's evaluation). The bar is the clipped
LQR on measured signals (``lqr-clipped-biexp-meas``), measured once in the same run on the same
episodes. An algorithm stops at the first evaluation at or below the bar (unless
``--no-stop-at-bar``), at ``--budget-s`` seconds of training, or at the file's ``n_timesteps``
(``--timesteps``), whichever comes first.

Clocks: ``train_s`` is the wall time of ``learn`` minus the evaluations (the time a training
run spends learning); ``time_to_bar_s`` is ``train_s`` at the first evaluation that reaches
the bar (evaluation cadence ``--eval-every-s``: the figure is at most that late). Each
algorithm's env takes one step before the clock starts, so that the kernel's one-time load
from numba's cache (or compilation) is reported on its own. Where the time goes: ``env_s``
(inside the env's ``step_wait``), ``rollout_other_s`` (the rest of collecting: policy forward
passes, buffers, normalisation, callbacks), ``update_s`` (the algorithm's ``train``: the
gradient steps). The machine, its load average (start and end) and the command are in the JSON.

``--compile on`` runs PPO's update under ``torch.compile`` as ``train.py --compile`` does
(``capsule_env.agents.learning.compiled``); ``--compile both`` runs each algorithm eager, then compiled
(reported as ``ppo+compile``), in the same process. The compilation happens in the first update,
inside ``train_s`` (``first_update_s`` says how long that update took).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any

import numba
import numpy as np
import torch
from capsule_env.agents import classical_controllers
from capsule_env.agents.learning.algorithms import ALGORITHMS, ON_POLICY, algorithm_class
from capsule_env.agents.learning.compiled import check_compile, compile_update
from capsule_env.agents.learning.hyperparams import (
    algo_kwargs_from,
    load_hyperparams,
    normalize_kwargs_from,
    resolve_env_kwargs,
)
from capsule_env.agents.learning.sb3_policy import SB3Policy
from capsule_env.agents.learning.training import HYPERPARAMS_DIR, policy_env_kwargs
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnvWrapper, VecMonitor, VecNormalize

from capsule_env.common.cli import ArgumentParser, parse_literal
from capsule_env.common.safe_io import atomic_write_text, check_writable_file
from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv
from capsule_env.evaluation.episodes import VALIDATION_GUIDEWAY_SEED, episode_metrics, run_episodes

#: The classical law whose Wk is the bar: the best one on the ride task's measured signals.
BAR_LAW = "lqr-clipped-biexp-meas"
METRIC = "wk_rms_body_acc_m_s2"


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


@dataclass
class Validation:
    """The validation episodes every policy and the bar are measured on."""

    env_kwargs: dict
    episodes: int = 10
    seed: int = 5000
    length_s: float = 10.0

    def wk(self, policy: Any, extra_kwargs: dict | None = None) -> float:
        """Mean Wk-weighted RMS car-body acceleration of ``policy`` on the episodes, m/s^2."""
        kwargs = {**self.env_kwargs, **(extra_kwargs or {}),
                  "guideway_seed": VALIDATION_GUIDEWAY_SEED}  # fmt: skip
        rollout = run_episodes(policy, kwargs, self.episodes, self.seed, self.length_s)
        return float(episode_metrics(rollout, None)[METRIC])


def bar_wk(validation: Validation) -> float:
    """The clipped LQR's Wk on the validation episodes (its own env options over the task's)."""
    law = classical_controllers()[BAR_LAW]
    return validation.wk(law, law.env_kwargs)


@dataclass
class Clock:
    """Training time (wall time of ``learn`` minus the evaluations) and the phases' times."""

    t0: float = field(default_factory=time.perf_counter)
    eval_s: float = 0.0
    collect_s: float = 0.0
    update_s: float = 0.0
    first_update_s: float | None = None

    def train_s(self) -> float:
        return time.perf_counter() - self.t0 - self.eval_s


class BarCallback(BaseCallback):
    """Evaluates the policy every ``every_s`` seconds of training; stops training at the
    first evaluation at or below ``bar`` or when ``budget_s`` seconds of training are spent."""

    def __init__(self, clock: Clock, validation: Validation, bar: float, every_s: float,
                 budget_s: float, stop_at_bar: bool = True) -> None:  # fmt: skip
        super().__init__()
        self.clock, self.validation, self.bar = clock, validation, bar
        self.stop_at_bar = stop_at_bar
        self.every_s, self.budget_s = every_s, budget_s
        self.next_eval_s = every_s
        self.evaluations: list[dict] = []
        self.reached: dict | None = None

    def _on_step(self) -> bool:
        train_s = self.clock.train_s()
        if train_s >= self.next_eval_s or train_s >= self.budget_s:
            self.next_eval_s = train_s + self.every_s
            self.evaluate(train_s)
        return (self.reached is None or not self.stop_at_bar) and train_s < self.budget_s

    def evaluate(self, train_s: float) -> dict:
        """Evaluate the current policy (frozen normalisation statistics), record it."""
        t0 = time.perf_counter()
        policy = SB3Policy.from_model(self.model, self.model.get_vec_normalize_env())
        wk = self.validation.wk(policy)
        self.clock.eval_s += time.perf_counter() - t0
        row = {"train_s": round(train_s, 3), "num_timesteps": int(self.num_timesteps),
               METRIC: wk}  # fmt: skip
        self.evaluations.append(row)
        if wk <= self.bar and self.reached is None:
            self.reached = row
        return row


def timed_phases(model: Any, clock: Clock) -> None:
    """Time the model's ``collect_rollouts`` and ``train`` (instance attributes over the
    class's methods; SB3's ``learn`` calls them through ``self``)."""
    collect, update = model.collect_rollouts, model.train

    def timed_collect(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return collect(*args, **kwargs)
        finally:
            clock.collect_s += time.perf_counter() - t0

    def timed_update(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return update(*args, **kwargs)
        finally:
            seconds = time.perf_counter() - t0
            clock.update_s += seconds
            if clock.first_update_s is None:
                clock.first_update_s = seconds

    model.collect_rollouts, model.train = timed_collect, timed_update


@dataclass
class Setup:
    """One algorithm's run as train.py would make it, with the overrides applied."""

    algo: str
    hp: dict
    env_kwargs: dict
    num_envs: int
    total: int
    compiled: bool = False


def runs_of(args: argparse.Namespace) -> dict[str, Setup]:
    """The runs, by the name they are reported under: each algorithm, eager (``ALGO``) and/or
    compiled (``ALGO+compile``) as ``--compile`` says."""
    modes = {"off": (False,), "on": (True,), "both": (False, True)}[args.compile]
    runs = {}
    for algo in args.algos:
        for compiled in modes:
            setup = setup_for(algo, args.hp, args.num_envs, args.timesteps)
            setup.compiled = compiled
            runs[algo + ("+compile" if compiled else "")] = setup
    return runs


def setup_for(algo: str, overrides: dict, num_envs: int | None, timesteps: int | None) -> Setup:
    """``hyperparams/<algo>.yml`` with ``overrides``; its env arguments over train.py's."""
    hp = {**load_hyperparams(HYPERPARAMS_DIR / f"{algo}.yml"), **overrides}
    env_kwargs = resolve_env_kwargs(hp.get("env_kwargs", {}), {})
    n = int(num_envs or hp.get("n_envs", 1))
    total = int(timesteps or float(hp["n_timesteps"]))
    return Setup(algo, hp, env_kwargs, n, total)


def make_model(setup: Setup, seed: int) -> tuple[Any, TimedVecEnv, float]:
    """The model on its env (SB3 VecEnv, timed, + VecMonitor + VecNormalize), the timed
    layer, and the seconds of the env's first step (kernel load), taken before training."""
    vehicles = CapsuleSuspensionSB3VecEnv(setup.num_envs, **setup.env_kwargs)
    t0 = time.perf_counter()
    vehicles.reset()
    vehicles.step(np.zeros((setup.num_envs, 1), dtype=np.float32))
    first_step_s = time.perf_counter() - t0
    vehicles.seed(seed)
    timed = TimedVecEnv(vehicles)
    env = VecNormalize(VecMonitor(timed), **normalize_kwargs_from(setup.hp))
    model = algorithm_class(setup.algo)(env=env, seed=seed, device="cpu", verbose=0,
                                        **algo_kwargs_from(setup.hp))  # fmt: skip
    if setup.compiled:
        compile_update(model)
    return model, timed, first_step_s


def bench_algo(setup: Setup, validation: Validation, bar: float, args: Any) -> dict:
    """Train ``setup`` until the bar, the budget or the timesteps; the figures as a dict."""
    model, timed, first_step_s = make_model(setup, args.seed)
    clock = Clock()
    callback = BarCallback(clock, validation, bar, args.eval_every_s, args.budget_s,
                           args.stop_at_bar)  # fmt: skip
    timed_phases(model, clock)
    clock.t0 = time.perf_counter()
    model.learn(setup.total, callback=callback)
    train_s = clock.train_s()
    if not callback.evaluations or callback.evaluations[-1]["num_timesteps"] != model.num_timesteps:
        callback.evaluate(train_s)  # the final policy
    model.get_env().close()
    steps = int(model.num_timesteps)
    best = min(callback.evaluations, key=lambda row: row[METRIC])
    reached = callback.reached
    return {
        "num_envs": setup.num_envs,
        "compiled_update": setup.compiled,
        "hyperparams": {k: v for k, v in setup.hp.items() if k != "env_kwargs"},
        "num_timesteps": steps,
        "train_s": train_s,
        "env_steps_per_s": steps / train_s,
        "env_s": timed.env_seconds,
        "rollout_other_s": clock.collect_s - clock.eval_s - timed.env_seconds,
        "update_s": clock.update_s,
        "first_update_s": clock.first_update_s,
        "eval_s": clock.eval_s,
        "first_step_s": first_step_s,
        "stopped_by": _stopped_by(reached is not None and args.stop_at_bar, train_s, args.budget_s),
        "time_to_bar_s": reached["train_s"] if reached else None,
        "steps_to_bar": reached["num_timesteps"] if reached else None,
        "best": best,
        "final": callback.evaluations[-1],
        "evaluations": callback.evaluations,
    }


def _stopped_by(at_bar: bool, train_s: float, budget_s: float) -> str:
    return "bar" if at_bar else ("budget" if train_s >= budget_s else "timesteps")


def print_result(algo: str, r: dict, bar: float) -> None:
    reach = (f"reached the bar at {r['time_to_bar_s']:.1f} s ({r['steps_to_bar']:,} steps)"
             if r["time_to_bar_s"] is not None else f"bar not reached ({r['stopped_by']})")  # fmt: skip
    phases = ", ".join(f"{k[:-2]} {100 * r[k] / r['train_s']:.0f} %"
                       for k in ("env_s", "rollout_other_s", "update_s"))  # fmt: skip
    print(f"{algo:>13}: {r['env_steps_per_s']:>9,.0f} env-steps/s ({r['num_timesteps']:,} "
          f"steps, {r['train_s']:.1f} s; {phases}); best Wk {r['best'][METRIC]:.4f} "
          f"({r['best'][METRIC] / bar:.3f} x bar); {reach}", flush=True)  # fmt: skip


def machine() -> dict:
    """The CPU's model name, its core count and the load averages (1, 5, 15 min)."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            names = [ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")]
        model = names[0] if names else model
    except OSError:
        pass
    load = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    return {"cpu": model, "cores": os.cpu_count(), "load_avg": load}


def parse_hp(items: list[str]) -> dict:
    """``KEY=VALUE`` items (VALUE JSON or a Python literal, a bare word a string)."""
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ValueError(f"--hp must be KEY=VALUE, got {item!r}")
        try:
            out[key] = parse_literal(text)
        except ValueError:
            out[key] = text
    return out


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = ArgumentParser(
        prog="bench_training.py", description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    p.add_argument(
        "--algos",
        nargs="+",
        default=list(ALGORITHMS),
        metavar="ALGO",
        help=f"algorithms, among {', '.join(ALGORITHMS)} (default: all)",
    )
    p.add_argument(
        "--budget-s",
        type=float,
        default=120.0,
        help="seconds of training per algorithm at most (default 120)",
    )
    p.add_argument(
        "--eval-every-s",
        type=float,
        default=5.0,
        help="seconds of training between evaluations (default 5)",
    )
    p.add_argument(
        "--stop-at-bar",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="stop an algorithm at the first evaluation that reaches the bar "
        "(--no-stop-at-bar: train on to the budget or the timesteps)",
    )
    p.add_argument("--timesteps", type=int, help="env steps at most (default: the file's)")
    p.add_argument("--num-envs", type=int, help="vehicles (default: the file's n_envs)")
    p.add_argument(
        "--hp",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a hyperparameter over the file's, repeatable: --hp n_epochs=2",
    )
    p.add_argument("--eval-episodes", type=int, default=10)
    p.add_argument("--eval-episode-length", type=float, default=10.0, help="s")
    p.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    p.add_argument(
        "--env-threads",
        type=int,
        default=1,
        help="numba threads of the env kernel (default 1, train.py's default)",
    )
    p.add_argument(
        "--compile",
        choices=("off", "on", "both"),
        default="off",
        help="PPO's update under torch.compile: off, on, or both (eager, then compiled)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", help="write the results here (atomically)")
    args = p.parse_args(argv)
    try:
        check_args(args)
    except ValueError as exc:
        p.error(str(exc))
    return args


def check_args(args: argparse.Namespace) -> None:
    """Ranges and names; ``ValueError`` naming the option."""
    for algo in args.algos:
        if algo not in ALGORITHMS:
            raise ValueError(f"--algos: {algo!r} is not one of {', '.join(ALGORITHMS)}")
    for name in ("budget_s", "eval_every_s", "eval_episode_length"):
        value = getattr(args, name)
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"--{name.replace('_', '-')} must be a number > 0, got {value}")
    for name in ("timesteps", "num_envs", "eval_episodes", "threads", "env_threads"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise ValueError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    if args.compile != "off":
        for algo in args.algos:
            check_compile(algo, True)
    args.hp = parse_hp(args.hp)
    if args.json:
        check_writable_file(args.json, "--json")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    numba.set_num_threads(min(args.env_threads, numba.config.NUMBA_NUM_THREADS))
    started = {"date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
               "machine": machine(), "python": platform.python_version(),
               "torch": torch.__version__,
               "command": shlex.join(["python", "benchmarks/bench_training.py",
                                      *(sys.argv[1:] if argv is None else argv)])}  # fmt: skip
    setups = runs_of(args)
    first = next(iter(setups.values())).env_kwargs
    for algo, setup in setups.items():
        if setup.env_kwargs != first:
            raise SystemExit(f"bench_training.py: error: {algo}.yml trains on {setup.env_kwargs}, "
                             f"not on {first} (one bar per run)")  # fmt: skip
    task = policy_env_kwargs(first)
    validation = Validation(task, args.eval_episodes, 5000, args.eval_episode_length)
    bar = bar_wk(validation)
    print(f"bar: {BAR_LAW} Wk {bar:.4f} m/s^2 on the validation bank {VALIDATION_GUIDEWAY_SEED} "
          f"(seeds 5000..{5000 + args.eval_episodes - 1}, {task}); budget {args.budget_s:g} s "
          f"per algorithm, evaluation every {args.eval_every_s:g} s", flush=True)  # fmt: skip
    results = {}
    for algo, setup in setups.items():
        results[algo] = bench_algo(setup, validation, bar, args)
        print_result(algo, results[algo], bar)
    out = {**started, "load_avg_end": machine()["load_avg"], "bar": {"law": BAR_LAW, METRIC: bar},
           "config": {k: v for k, v in vars(args).items()}, "on_policy": list(ON_POLICY),
           "results": results}  # fmt: skip
    if args.json:
        atomic_write_text(args.json, json.dumps(out, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
