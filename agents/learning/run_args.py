"""A training run's arguments: ``train.py``'s command line (:func:`parse_args`, the values
checked by :func:`check_args`), the run's own arguments saved with every policy it writes and
restored by ``--resume``, and the command that continues a run.

Every save's ``.json`` holds ``args`` (:func:`run_arguments`): the arguments that make the run
what it is. ``--resume auto`` (or ``--resume DIR``, or a checkpoint's ``.zip``) restores them
from the checkpoint (:func:`restore_arguments`), so that the bare ``train.py --resume auto``
continues a run made with, say, ``--env observation=measured --total-timesteps 2e6`` with that
observation and that budget. Three kinds of arguments:

- :data:`FIXED` (and the env arguments and the hyperparameters): they define the run. Restored;
  one given again with another value is refused in one line naming the argument, both values
  and the checkpoint.
- :data:`ADJUSTABLE`: restored unless given again; a value given holds from then on (a longer
  ``--total-timesteps`` trains on; the learning-rate schedule follows the new budget).
- the others (``output_dir``, ``resume``, ``tensorboard``, ``threads``, ``env_threads``,
  ``compile``, ``progress``, ``device``, ``verbose``): chosen by each process, not stored.

"Given" is what the command line named (``Args.explicit``, set by the parser); for arguments
built in code (``explicit`` None) every field that is not None counts as given. Checkpoints of
earlier versions (no ``args``) restore what they hold: algorithm, seed, vehicles, name, the env
arguments and the hyperparameters.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shlex
import sys
from pathlib import Path
from typing import Any

from capsule_env.common.cli import (
    ArgumentParser,
    add_dataclass_options,
    dataclass_values,
    parse_env_item,
    parse_env_kwargs,
)
from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, VALIDATION_GUIDEWAY_SEED

#: Define the run: restored by ``--resume``; given again with another value, refused.
FIXED = ("algo", "seed", "num_envs", "name", "eval_episodes", "eval_seed", "eval_episode_length",
         "residual", "residual_scale", "task")  # fmt: skip
#: Restored by ``--resume`` unless given again (then the given value holds).
ADJUSTABLE = ("total_timesteps", "eval_freq", "checkpoint_freq", "checkpoint_minutes",
              "keep_replay_buffers")  # fmt: skip
#: Chosen by each process: written into the command that continues a run when given.
PROCESS = ("tensorboard", "threads", "env_threads", "compile", "device", "verbose", "progress")


# ----------------------------------------------------------------------------- command line
def parse_args(cls: type, argv: list[str] | None, description: str | None) -> Any:
    """The command line as an instance of the argument dataclass ``cls`` (``train.Args``).

    Each field is an option ``--field-name``; its help is the string literal under the field.
    ``env_kwargs`` (a JSON object or Python dict literal) and the ``env`` items (``KEY=VALUE``,
    VALUE JSON or a Python literal, a bare word a string) are merged into ``env_kwargs``, the
    items last. A field ``explicit`` (when ``cls`` has one) gets the names of the options the
    command line gave. A bad value exits with one line on stderr and status 2.
    """
    parser = ArgumentParser(prog="train.py", description=description,
                            formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    add_dataclass_options(parser, cls)
    values = dataclass_values(parser.parse_args(argv), cls)
    if "explicit" in {f.name for f in dataclasses.fields(cls)}:  # what --resume checks
        given = ArgumentParser(prog="train.py")
        add_dataclass_options(given, cls, suppress=True)
        values["explicit"] = frozenset(vars(given.parse_args(argv)))
    try:
        env_kwargs = parse_env_kwargs(values["env_kwargs"])
        env_kwargs.update(parse_env_item(item) for item in values["env"])
        values["env_kwargs"] = env_kwargs
        args = cls(**values)
        check_args(args)
    except ValueError as exc:
        parser.error(str(exc))
    return args


def check_args(args: Any) -> None:
    """The values' ranges; ``ValueError`` naming the option."""
    for name in ("num_envs", "total_timesteps", "eval_episodes", "threads", "env_threads"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise ValueError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    for name in ("eval_freq", "checkpoint_freq", "keep_replay_buffers"):
        if getattr(args, name) < 0:
            raise ValueError(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    last_seed = 2**63 - max(args.eval_episodes, 1)  # episode seeds: numpy's, below 2**63
    if not 0 <= args.eval_seed <= last_seed:
        raise ValueError(f"--eval-seed must be in 0..{last_seed} (--eval-episodes "
                         f"{args.eval_episodes} seeds from it, each below 2**63), got "
                         f"{args.eval_seed}")  # fmt: skip
    check_residual_args(args)
    check_device(args.device)
    if not (math.isfinite(args.checkpoint_minutes) and args.checkpoint_minutes >= 0):
        raise ValueError(f"--checkpoint-minutes must be >= 0, got {args.checkpoint_minutes}")
    if args.env_kwargs.get("guideway_seed", None) in (
        EVALUATION_GUIDEWAY_SEED,
        VALIDATION_GUIDEWAY_SEED,
    ):
        raise ValueError(
            f"guideway_seed={args.env_kwargs['guideway_seed']} is a held-out bank (evaluation "
            f"{EVALUATION_GUIDEWAY_SEED}, validation {VALIDATION_GUIDEWAY_SEED})"
        )


def check_residual_args(args: Any) -> None:
    """``--residual`` names a classical law and ``--residual-scale`` is in (0, 2];
    ``ValueError`` naming the option and what it accepts."""
    from capsule_env.agents.controllers.classical import FACTORIES

    law = getattr(args, "residual", None)
    if law is not None and law not in FACTORIES:
        raise ValueError(f"--residual must name a classical controller ({', '.join(FACTORIES)}), "
                         f"got {law!r}")  # fmt: skip
    scale = getattr(args, "residual_scale", 0.5)
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and 0.0 < scale <= 2.0):
        raise ValueError(f"--residual-scale must be in (0, 2], got {scale}")
    given = getattr(args, "explicit", None) or ()
    if "residual_scale" in given and law is None and not getattr(args, "resume", None):
        raise ValueError("--residual-scale scales a residual policy's correction: give "
                         "--residual LAW with it")  # fmt: skip


def check_device(device: str) -> None:
    """``--device`` is ``auto`` or a torch device (``cpu``, ``cuda``, ``cuda:1``, ``mps``);
    ``ValueError`` otherwise (torch's own error is a multi-line ``RuntimeError``)."""
    if device == "auto":
        return
    import torch

    try:
        torch.device(device)
    except (RuntimeError, TypeError):
        raise ValueError(f"--device must be auto or a torch device (cpu, cuda, cuda:0, mps), "
                         f"got {device!r}") from None  # fmt: skip


# ----------------------------------------------------------------------------- --resume
def given_arguments(args: Any) -> set[str]:
    """The fields of ``args`` the user gave: ``args.explicit`` (the command line's options),
    or, for arguments built in code, every field that is not None."""
    explicit = getattr(args, "explicit", None)
    names = {f.name for f in dataclasses.fields(args) if f.name != "explicit"}
    chosen = names if explicit is None else set(explicit) & names
    return {n for n in chosen if getattr(args, n) is not None}


def run_arguments(args: Any, total_timesteps: int, num_envs: int, name: str) -> dict:
    """The ``args`` block saved with every policy of the run: the effective values of
    :data:`FIXED` and :data:`ADJUSTABLE` (budget rounded to whole rollouts, vehicles, name),
    the env arguments the user gave and the hyperparameter file."""
    stored = {key: getattr(args, key) for key in (*FIXED, *ADJUSTABLE)}
    stored.update(total_timesteps=int(total_timesteps), num_envs=int(num_envs), name=name,
                  env_kwargs=dict(args.env_kwargs), hyperparams=args.hyperparams)  # fmt: skip
    return stored


def _option(key: str) -> str:
    return "--" + key.replace("_", "-")


def restore_arguments(args: Any, meta: dict, ckpt: Path) -> Any:
    """``args`` with the run's own arguments from the checkpoint metadata ``meta`` (see the
    module docstring). Raises ``ValueError`` (one line) for a :data:`FIXED` argument given
    with another value than the run's; prints a note for an :data:`ADJUSTABLE` one."""
    stored = meta.get("args")
    if not isinstance(stored, dict):  # a checkpoint from before the args block
        stored = {k: meta[k] for k in ("algo", "seed", "num_envs", "name") if k in meta}
    given = given_arguments(args)
    changes = {}
    if isinstance(meta.get("args"), dict) and not stored.get("residual") and "residual" in given:
        raise ValueError(f"--resume: --residual {args.residual!r}: the run ({ckpt}) is not a "
                         "residual run; start one in another --output-dir")  # fmt: skip
    for key in FIXED:
        if stored.get(key) is None:
            continue
        if key in given and getattr(args, key) != stored[key]:
            raise ValueError(
                f"--resume: {_option(key)} {getattr(args, key)!r} differs from the run's "
                f"{stored[key]!r} ({ckpt}): leave {_option(key)} out to continue the run, or "
                "start a new one in another --output-dir"
            )
        changes[key] = stored[key]
    for key in ADJUSTABLE:
        if stored.get(key) is None:
            continue
        if key not in given:
            changes[key] = stored[key]
        elif getattr(args, key) != stored[key]:
            print(f"note: {_option(key)} {getattr(args, key)} replaces the run's {stored[key]}")
    return dataclasses.replace(args, **changes)


def _first_difference(given: Any, stored: Any, key: str = "") -> str:
    """``key: given value / stored value`` of the first difference of two JSON-like values."""
    if isinstance(given, dict) and isinstance(stored, dict):
        for k in sorted(set(given) | set(stored), key=str):
            if given.get(k, "(absent)") != stored.get(k, "(absent)"):
                return _first_difference(given.get(k, "(absent)"), stored.get(k, "(absent)"),
                                         f"{key}.{k}" if key else str(k))  # fmt: skip
    return f"{key or 'the file'}: {given!r} there, {stored!r} in the run"


def restore_hyperparams(
    given_file: str | None, loaded: dict | None, meta: dict, ckpt: Path
) -> dict:
    """The run's hyperparameters (``meta["hyperparams"]``, as the run read them), checked
    against the file given again (``given_file``, read as ``loaded``): another content is
    refused (``ValueError`` naming the first differing key and both values)."""
    stored = meta.get("hyperparams")
    if not isinstance(stored, dict):  # not recorded: the file decides, as before
        if loaded is None:
            raise ValueError(f"--resume: {ckpt} records no hyperparameters: give --hyperparams")
        return loaded
    if loaded is not None:
        as_stored = json.loads(json.dumps(loaded, default=str))
        if as_stored != stored:
            raise ValueError(
                f"--resume: --hyperparams {given_file} differs from the run's hyperparameters "
                f"({ckpt}): {_first_difference(as_stored, stored)}; leave --hyperparams out to "
                "continue the run"
            )
    return dict(stored)


def _same_env_value(stored: dict, key: str, value: Any) -> bool:
    """Whether ``key=value`` leaves the run's env arguments ``stored`` as they are (equal, or
    the same :class:`capsule_env.engine.config.EnvConfig`: e.g. a key set to its default)."""
    if key in stored:
        return stored[key] == value
    from capsule_env.engine.config import EnvConfig

    try:
        return EnvConfig.from_kwargs(**stored) == EnvConfig.from_kwargs(**{**stored, key: value})
    except (ValueError, TypeError):
        return False


def restore_env_kwargs(args: Any, meta: dict, ckpt: Path) -> dict:
    """The run's env arguments (``meta["train_env_kwargs"]``); each one given again
    (``--env``, ``--env-kwargs``) must leave them as they are, else ``ValueError`` naming
    the key and both values."""
    stored = dict(meta["train_env_kwargs"])
    given = given_arguments(args) & {"env", "env_kwargs"}
    for key, value in args.env_kwargs.items() if given else ():
        if not _same_env_value(stored, key, value):
            run_value = f"={stored[key]!r}" if key in stored else " (not set: the env's default)"
            raise ValueError(
                f"--resume: --env {key}={value!r} differs from the run's {key}{run_value} "
                f"({ckpt}): leave it out to continue the run, or start a new one in another "
                "--output-dir"
            )
    return stored


def continue_command(args: Any, output_dir: Path) -> str:
    """The shell command that continues the run in ``output_dir`` (``--resume auto`` restores
    the rest), with the :data:`PROCESS` options this process was given; quoted for a POSIX
    shell, runnable from the current folder."""
    program = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    if program == "train.py":
        words = ["python", sys.argv[0]]
    elif program == "capsule-train":
        words = ["capsule-train"]
    else:
        words = ["python", "-m", "capsule_env.agents.learning.train"]
    words += ["--output-dir", str(output_dir), "--resume", "auto"]
    given = given_arguments(args)
    defaults = {f.name: f.default for f in dataclasses.fields(args)}
    for key in PROCESS:
        value = getattr(args, key)
        if key not in given or value == defaults.get(key):
            continue
        if isinstance(value, bool):
            words.append(_option(key) if value else f"--no-{key.replace('_', '-')}")
        else:
            words += [_option(key), str(value)]
    return shlex.join(words)
