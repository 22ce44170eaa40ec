"""Record a controller on a task as a Minari dataset: the checks, the run, the write.

:func:`record_dataset` checks everything first (the task, the controller, the episode count
and seeds, the episode length, the output folder), then runs the episodes
(:mod:`~capsule_env.datasets.rollouts`, or the oracle's search and replay,
:mod:`~capsule_env.datasets.oracle_replay`) and only then writes
(:mod:`~capsule_env.datasets.minari_store`). Episode ``k`` is the task's env seeded
``seed + k`` on the env's own guideway bank (the training bank, ``guideway_seed=0``, unless
the task names another), named in the dataset's env spec; the dataset's
``recover_environment(eval_env=True)`` gives the same env on the evaluation bank
(:data:`~capsule_env.evaluation.episodes.EVALUATION_GUIDEWAY_SEED`). A recording that would
hold more than 80 % of the memory available until the write (:func:`recording_bytes`) is
refused before it runs.

The recording env is the task's with the controller's own options over it (how it reads and
acts: its observation set, action mode, inverse model, preview), as ``evaluate.py`` runs every
controller; a controller whose options change the task's physics (a trip law on a
constant-speed task) is refused. The dataset's env spec is that env (``gym.make(task,
**options)``), so ``recover_environment()`` gives it back.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import capsule_env
from capsule_env.common.validation import available_memory_bytes, format_bytes
from capsule_env.datasets.demonstrators import Demonstrator, resolve_demonstrator
from capsule_env.datasets.minari_store import check_out, dataset_id, write_dataset
from capsule_env.datasets.rollouts import Episode, record_episodes
from capsule_env.engine.config import EnvConfig
from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, RECORDED

__all__ = ["Plan", "plan_dataset", "record_dataset", "recording_bytes", "action_meaning"]

_MAX_SEED = 2**63
#: Copies of each recorded step held at once (measured: about 400 bytes a step of
#: CapsuleRide-v0, 130 bytes a copy; docs/howto-datasets.md).
_COPIES = 3
#: A dataset's name: Minari's dataset-name characters.
_NAME = re.compile(r"[-\w]+", re.ASCII)


@dataclass(frozen=True)
class Plan:
    """What :func:`record_dataset` will do, every input checked."""

    task: str
    demonstrator: Demonstrator
    spec_kwargs: dict[str, Any]  # gym.make(task, **spec_kwargs) is the recording env
    seeds: tuple[int, ...]
    episode_length_s: float
    ident: str
    options_over_task: dict[str, Any]

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """The recording env's options, the task's registered ones included."""
        from capsule_env.evaluation.condition import task_env_kwargs

        return {**task_env_kwargs(self.task), **self.spec_kwargs}


def _check_count(episodes: Any, seed: Any) -> range:
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"--episodes must be an integer >= 1, got {episodes!r}")
    last = _MAX_SEED - episodes
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= last:
        raise ValueError(f"--seed must be an integer in 0..{last} (2**63 - --episodes: episode "
                         f"k uses seed + k, a 64-bit seed), got {seed!r}")  # fmt: skip
    return range(seed, seed + episodes)  # lazy: checked against the memory first


def _own_options(task: str, task_kwargs: dict[str, Any], own: dict[str, Any],
                 length_s: float) -> dict[str, Any]:  # fmt: skip
    """The controller's options that differ from the task's; ``ValueError`` when one of them
    changes the task's physics."""
    from capsule_env.evaluation.condition import physics_changes

    changes = physics_changes(task_kwargs, own, length_s, base_label=task)
    if changes:
        raise ValueError(f"--controller's own env options change {task}'s physics: "
                         f"{'; '.join(changes)}; record it on a task it is made for")  # fmt: skip
    return {k: v for k, v in own.items() if task_kwargs.get(k, _default(k)) != v}


def _default(key: str) -> Any:
    return getattr(EnvConfig(), key, None)


def recording_bytes(config: EnvConfig, episodes: int) -> int:
    """About the memory (bytes) ``episodes`` episodes of the env ``config`` hold until the
    write: every step's observation (float32), action, reward, ends and the recorded signals
    (float64), :data:`_COPIES` times (the vector env's rows, the episodes cut from them,
    Minari's buffers)."""
    row = 4 * len(config.observation_names) + 4 + 8 + 2 + 8 * len(RECORDED)
    return _COPIES * episodes * (config.max_episode_steps + 1) * row


def _check_memory(config: EnvConfig, episodes: int) -> None:
    """``ValueError`` naming ``--episodes`` when the recording would hold more than 80 % of
    the memory available now (it is all in memory until the write)."""
    need, free = recording_bytes(config, episodes), available_memory_bytes()
    if need > 0.8 * free:
        raise ValueError(f"--episodes {episodes} of {config.episode_length_s:g} s would hold "
                         f"about {format_bytes(need)} in memory until the write, more than 80 % "
                         f"of the {format_bytes(free)} available: record fewer episodes per "
                         f"dataset (each its own --out) or shorter ones")  # fmt: skip


def plan_dataset(task: str, controller: str, episodes: int, seed: int,
                 episode_length_s: float | None = None, name: str | None = None) -> Plan:  # fmt: skip
    """Every input checked, the controller loaded; ``ValueError`` (or ``ImportError`` for a
    missing extra) naming the option and what it accepts."""
    from capsule_env.evaluation.condition import task_env_kwargs

    task_kwargs = task_env_kwargs(task)  # ValueError naming --task and the ids
    seeds = _check_count(episodes, seed)
    demonstrator = resolve_demonstrator(controller)
    length = task_kwargs.get("episode_length_s", EnvConfig().episode_length_s)
    length = length if episode_length_s is None else episode_length_s
    if isinstance(length, bool) or not isinstance(length, (int, float)):
        raise ValueError(f"--episode-length must be a number of seconds, got {length!r}")
    own = {k: v for k, v in demonstrator.env_kwargs.items() if k != "setting"}
    # the guideway bank named in the spec: recover_environment() rebuilds the recorded bank
    # whatever the package's default, and the metadata says which bank the data is on
    bank = task_kwargs.get("guideway_seed", EnvConfig().guideway_seed)
    spec_kwargs = {"guideway_seed": bank, **own, "episode_length_s": float(length)}
    try:
        config = EnvConfig.from_kwargs(**{**task_kwargs, **spec_kwargs})
    except (ValueError, TypeError) as exc:
        raise ValueError(f"--episode-length / --controller on {task}: {exc}") from None
    _check_memory(config, len(seeds))
    over = _own_options(task, task_kwargs, own, float(length))
    label = name if name is not None else demonstrator.name
    if not isinstance(label, str) or not _NAME.fullmatch(label):
        raise ValueError(f"--name must be letters, digits, '-' and '_', got {label!r}")
    return Plan(
        task,
        demonstrator,
        spec_kwargs,
        tuple(seeds),
        float(length),
        dataset_id(task, label),
        over,
    )


def action_meaning(env_kwargs: dict[str, Any], oracle: bool) -> str:
    """What an action ``a`` in ``[-1, 1]`` of the recording env means, in words."""
    config = EnvConfig.from_kwargs(**env_kwargs)
    if config.action_mode == "current":
        text = (f"current mode: a commands the coil current (a + 1) / 2 * {config.max_current_a:g} A"
                f" (i_max), applied {config.effective_control_delay_steps} control step(s) later")  # fmt: skip
        if oracle:
            text += (
                "; the oracle's searched applied-current sequence, replayed without delay "
                "(the coil's lag, where the setting has one, still acts)"
            )
        return text
    return (f"force mode: a * {config.max_force_n:g} N is the damper force requested, turned "
            f"into a current by the {config.inverse_model} inverse model, applied "
            f"{config.effective_control_delay_steps} control step(s) later")  # fmt: skip


def _run(plan: Plan, oracle_search: dict[str, Any] | None) -> tuple[list[Episode], Any]:
    demonstrator = plan.demonstrator
    if demonstrator.controller is None:
        from capsule_env.datasets.oracle_replay import oracle_episodes

        return oracle_episodes({k: v for k, v in plan.env_kwargs.items()
                                if k != "episode_length_s"}, plan.seeds,
                               plan.episode_length_s, oracle_search)  # fmt: skip
    kwargs = {k: v for k, v in plan.env_kwargs.items() if k != "episode_length_s"}
    return record_episodes(demonstrator.controller, kwargs, plan.seeds,
                           plan.episode_length_s), None  # fmt: skip


def _description(plan: Plan, episodes: list[Episode], oracle: Any) -> dict[str, Any]:
    d = plan.demonstrator
    gains = d.controller.gains() if d.controller is not None else {}
    return {
        "summary": (
            f"{d.name} ({d.kind}) on {plan.task}: {len(episodes)} episodes of "
            f"{plan.episode_length_s:g} s, seeds {plan.seeds[0]}..{plan.seeds[-1]}"
        ),
        "capsule_env_version": capsule_env.__version__,
        "task": plan.task,
        "controller": {"name": d.name, "kind": d.kind, "source": d.source, "gains": gains},
        "seeds": list(plan.seeds),
        "episode_length_s": plan.episode_length_s,
        "env_kwargs": plan.env_kwargs,
        "options_over_task": plan.options_over_task,
        "action": action_meaning(plan.env_kwargs, d.kind == "oracle"),
        "observation_names": list(EnvConfig.from_kwargs(**plan.env_kwargs).observation_names),
        "infos": {
            "signals": list(RECORDED),
            "layout": "each the env's info entry of that name "
            "(its unit in the name), one value per step, the reset's first",
        },  # fmt: skip
        "eval_guideway_seed": EVALUATION_GUIDEWAY_SEED,
        "oracle_search": oracle,
    }


def record_dataset(task: str, controller: str, episodes: int, seed: int, out: str | Path,
                   episode_length_s: float | None = None, name: str | None = None,
                   oracle_search: dict[str, Any] | None = None) -> tuple[Path, str]:  # fmt: skip
    """Record ``episodes`` episodes of ``controller`` on ``task`` (module docstring) as a
    Minari dataset under the new root ``out``; returns its folder and its id. ``oracle_search``:
    options of :func:`capsule_env.oracle.clairvoyant_bound` for ``controller="oracle"``."""
    import gymnasium as gym

    from capsule_env.datasets.minari_store import minari_module

    minari_module()  # the extra, before the run
    check_out(out)
    plan = plan_dataset(task, controller, episodes, seed, episode_length_s, name)
    recorded, oracle = _run(plan, oracle_search)
    env = gym.make(plan.task, **plan.spec_kwargs)
    try:
        assert env.spec is not None
        eval_spec = replace(env.spec, kwargs={**env.spec.kwargs,
                                              "guideway_seed": EVALUATION_GUIDEWAY_SEED})  # fmt: skip
        folder = write_dataset(out, plan.ident, recorded, env, eval_spec,
                               _description(plan, recorded, oracle))  # fmt: skip
    finally:
        env.close()
    return folder, plan.ident
