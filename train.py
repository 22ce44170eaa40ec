"""Train a stable-baselines3 agent (PPO, SAC or TD3) on ``CapsuleSuspension-v0``.

    python train.py                                   # PPO, defaults from hyperparams/ppo.yml
    python train.py --algo sac --total-timesteps 300000
    python train.py --env setting='"sim"' --env reward_stroke_weight=0.2
    python train.py --resume auto                     # continue runs/ppo-seed0 after a Ctrl-C
    python evaluate.py --policy runs/ppo-seed0/best_model.zip --setting hils

Read top to bottom (CleanRL style): arguments; hyperparameters (RL-Zoo yml); the env (the
batched numba kernel as an SB3 ``VecEnv`` + ``VecMonitor`` + ``VecNormalize``); the model (new
or resumed from a checkpoint); callbacks (held-out evaluation keeping the best model by the
ISO 2631 Wk-weighted RMS car-body acceleration, checkpoints every ``--checkpoint-freq`` steps
and every ``--checkpoint-minutes`` of wall time, throughput); training (Ctrl-C or SIGTERM saves
a checkpoint); the final model and a last checkpoint.

Environment: training uses ``setting="hils"`` (reference damper, coil lag, sensor noise,
control delay), ``action_mode="force"`` and ``observation="sensors"`` unless the hyperparameter
file's ``env_kwargs``, then ``--env-kwargs`` and ``--env``, override them (the shipped
``hyperparams/*.yml`` choose ``observation="full_state"``, which the Skyhook/LQR controllers
read too: with sensors alone PPO does not beat Skyhook), and always the *training* guideway
bank ``guideway_seed=0``. Evaluation during training uses the held-out bank
``capsule_env.evaluation.EVALUATION_GUIDEWAY_SEED`` (2026), with episode seeds ``--eval-seed``
.. (default 5000..5009; ``evaluate.py`` reports on 1000..1009 of the same bank), and prints
the passive and Skyhook figures on the same seeds beside it.

Output folder (``--output-dir``, default ``runs/<algo>-seed<seed>``):

- ``best_model.zip`` / ``.vecnormalize.pkl`` / ``.json``: the best policy so far on the
  held-out evaluation (``evaluate.py --policy .../best_model.zip`` loads it, through
  ``agents.sb3_policy.SB3Policy``); the json holds ``name``, ``algo``, ``env_kwargs``, the
  evaluation metrics, the timesteps and the wall time.
- ``final_model.*``: the same files for the policy at the end of training.
- ``checkpoints/ckpt_<steps>.{zip,vecnormalize.pkl,json}`` (+ ``.replay_buffer.pkl`` for SAC and
  TD3, kept for the newest ``--keep-replay-buffers`` checkpoints only): what ``--resume`` needs;
  ``--resume auto`` takes the newest intact one, saying which newer ones it skipped and why.
  ``evaluations.jsonl``: one line per evaluation.

Every save writes its files under temporary names and then renames them into place, the json
last: a full disk or a kill during a save leaves the previous files intact, and the json's
sizes and SHA-256 of the ``.zip`` and ``.pkl`` let the loaders refuse a mixed or truncated set.
Bad arguments, and output folders that cannot be written, stop the script before training with
one line on stderr (exit status 2 for the command line's own checks, 1 for the later ones).

Hyperparameters: ``hyperparams/<algo>.yml`` is in RL-Zoo format keyed by the env id, so
``python -m rl_zoo3.train --algo ppo --env CapsuleSuspension-v0 --gym-packages capsule_env
--conf-file hyperparams/ppo.yml`` also reads it (rl_zoo3 >= 2.x, which accepts ``env_kwargs``
in the file). rl_zoo3 is *not* a dependency of this project and is not needed: this script
reads the file itself (with PyYAML if installed, else with a small built-in reader for this
format), understanding ``n_envs``, ``n_timesteps``, ``policy``, ``normalize``,
``policy_kwargs``, ``env_kwargs``, ``lin_<x>`` schedules and ``noise_type``/``noise_std``, and
passing every other key to the SB3 algorithm. rl_zoo3 would build its env with
``gymnasium.make`` (one Python env per vehicle, much slower than the batched ``VecEnv`` here)
and evaluate on the training guideway bank.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import time
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from capsule_env.core import EnvConfig
from capsule_env.evaluation import (
    EVALUATION_GUIDEWAY_SEED,
    check_episode_length,
    episode_metrics,
    run_episodes,
)
from capsule_env.safe_io import StagedFiles, check_writable_dir, digest_mismatch, file_digest

ENV_ID = "CapsuleSuspension-v0"
ALGORITHMS = ("ppo", "sac", "td3")
#: Env arguments used for training unless the hyperparameter file or the command line says
#: otherwise: the emulated HILS test, force requests through the inverse model, sensors only.
TRAIN_ENV_DEFAULTS = {"setting": "hils", "action_mode": "force", "observation": "sensors"}
#: Env arguments chosen by the evaluation, not by the policy (kept out of the saved metadata
#: that ``evaluate.py`` merges into its env; ``episode_length_s`` is its ``--episode-length``).
EVALUATION_CHOSEN = ("guideway_seed", "episode_length_s")
#: Printed beside the evaluations: the best classical controller in ``hils``.
REFERENCE_CONTROLLER = "skyhook-cont-biexp"


# ----------------------------------------------------------------------------- arguments
@dataclass
class Args:
    """Command-line arguments (``python train.py --help``)."""

    algo: str = field(default="ppo", metadata={"help": "algorithm: ppo, sac or td3"})
    total_timesteps: int | None = field(
        default=None,
        metadata={"help": "env steps (all vehicles together) to train for; default: the "
                  "hyperparameter file's n_timesteps; rounded up to a whole number of PPO "
                  "rollouts (n_steps * num_envs) or of vector steps (num_envs)"},
    )  # fmt: skip
    num_envs: int | None = field(
        default=None,
        metadata={"help": "vehicles simulated in parallel; default: the file's n_envs"},
    )
    seed: int = field(
        default=0,
        metadata={
            "help": "random seed (torch, numpy; vehicle n gets stream n of "
            "numpy.random.SeedSequence(seed), so different seeds share no stream)"
        },
    )
    env_kwargs: dict = field(
        default_factory=dict,
        metadata={"help": "env arguments as a JSON object, e.g. '{\"speed_kmh\": 600}'; merged "
                  "over the file's env_kwargs and the training defaults "
                  f"{TRAIN_ENV_DEFAULTS}; --env KEY=VALUE items are merged over this"},
    )  # fmt: skip
    output_dir: str | None = field(
        default=None, metadata={"help": "output folder; default runs/<algo>-seed<seed>"}
    )
    name: str | None = field(
        default=None,
        metadata={"help": "policy name in evaluate.py's tables; default <algo>-seed<seed>"},
    )
    eval_freq: int = field(
        default=200_000,
        metadata={"help": "evaluate every this many env steps (0: only at the end)"},
    )
    eval_episodes: int = field(
        default=10, metadata={"help": "episodes per evaluation (held-out guideway bank)"}
    )
    eval_seed: int = field(
        default=5000,
        metadata={"help": "first evaluation episode seed (evaluate.py's default is 1000)"},
    )
    eval_episode_length: float = field(
        default=10.0, metadata={"help": "seconds per evaluation episode"}
    )
    checkpoint_freq: int = field(
        default=500_000,
        metadata={"help": "save a checkpoint every this many env steps (0: off; checkpoints "
                  "are also saved by wall time, on Ctrl-C/SIGTERM and at the end)"},
    )  # fmt: skip
    checkpoint_minutes: float = field(
        default=5.0,
        metadata={"help": "also save a checkpoint when this many minutes of wall time have "
                  "passed since the last one (0: off)"},
    )  # fmt: skip
    keep_replay_buffers: int = field(
        default=2,
        metadata={"help": "SAC/TD3: keep the replay buffer (.replay_buffer.pkl) of only the "
                  "newest this many checkpoints, deleting older ones (the models stay)"},
    )  # fmt: skip
    resume: str | None = field(
        default=None,
        metadata={"help": "continue from a checkpoint .zip, or 'auto' for the latest one in "
                  "output_dir/checkpoints (same output folder, timesteps not reset)"},
    )  # fmt: skip
    tensorboard: str | None = field(
        default=None,
        metadata={"help": "tensorboard log folder (needs the tensorboard package)"},
    )
    threads: int = field(default=1, metadata={"help": "torch CPU threads (1 is fastest here)"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    hyperparams: str | None = field(
        default=None, metadata={"help": "RL-Zoo yml file; default hyperparams/<algo>.yml"}
    )
    device: str = field(default="cpu", metadata={"help": "torch device"})
    verbose: int = field(default=0, metadata={"help": "SB3 verbosity (1: SB3's log tables)"})


def _integer(text: str) -> int:
    """An integer, also written like 2e6."""
    value = float(text)
    if value != int(value):
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}")
    return int(value)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (no usage block), exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def parse_args(argv: list[str] | None = None) -> Args:
    """The command line as :class:`Args`; a bad value exits with one line on stderr."""
    parser = _Parser(
        prog="train.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    for f in fields(Args):
        flag = "--" + f.name.replace("_", "-")
        default = f.default_factory() if callable(f.default_factory) else f.default
        help_text = f"{f.metadata['help']} (default: {default})"
        if f.name == "algo":
            parser.add_argument(flag, default=default, choices=ALGORITHMS, help=help_text)
        elif f.name == "progress":
            parser.add_argument(flag, default=default, action=argparse.BooleanOptionalAction,
                                help=f.metadata["help"])  # fmt: skip
        elif f.name == "env_kwargs":
            parser.add_argument(flag, default="{}", metavar="JSON", help=help_text)
        else:  # the annotation says int, float or str (all optional ones default to None)
            kind = {"int": _integer, "float": float}.get(f.type.split(" ")[0], str)
            parser.add_argument(flag, default=default, type=kind, help=help_text)
    parser.add_argument(
        "--env", action="append", default=[], metavar="KEY=VALUE",
        help="one env argument, VALUE parsed as JSON (a bare word is taken as a string), e.g. "
        "--env setting='\"sim\"' --env speed_kmh=600 --env guideway_params='{\"peak_m\": 0.01}';"
        " repeatable",
    )  # fmt: skip
    ns = parser.parse_args(argv)

    try:
        env_kwargs = json.loads(ns.env_kwargs)
    except json.JSONDecodeError as err:
        parser.error(f"--env-kwargs is not valid JSON ({err}): {ns.env_kwargs!r}")
    if not isinstance(env_kwargs, dict):
        parser.error(f"--env-kwargs must be a JSON object, got {ns.env_kwargs!r}")
    for item in ns.env:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            parser.error(f"--env expects KEY=VALUE, got {item!r}")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text  # --env setting=sim: a bare word is a string
        env_kwargs[key.strip()] = value
    values = {f.name: getattr(ns, f.name) for f in fields(Args)}
    values["env_kwargs"] = env_kwargs
    args = Args(**values)
    for name in ("num_envs", "total_timesteps", "eval_episodes", "threads"):
        value = getattr(args, name)
        if value is not None and value < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    for name in ("eval_freq", "checkpoint_freq", "keep_replay_buffers"):
        if getattr(args, name) < 0:
            parser.error(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    if not (math.isfinite(args.checkpoint_minutes) and args.checkpoint_minutes >= 0):
        parser.error(f"--checkpoint-minutes must be >= 0, got {args.checkpoint_minutes}")
    if "guideway_seed" in env_kwargs and env_kwargs["guideway_seed"] == EVALUATION_GUIDEWAY_SEED:
        parser.error(f"guideway_seed={EVALUATION_GUIDEWAY_SEED} is the held-out evaluation bank")
    return args


# ----------------------------------------------------------------------------- hyperparameters
def load_hyperparams(path: str | Path) -> dict[str, Any]:
    """The ``CapsuleSuspension-v0`` entry of an RL-Zoo hyperparameter yml file (read with
    PyYAML when it is installed, else with :func:`parse_simple_yaml`)."""
    path = Path(path)
    if not path.is_file():
        raise SystemExit(f"hyperparameter file not found: {path}")
    text = path.read_text()
    try:
        import yaml
    except ImportError:  # PyYAML is not a dependency of this project
        content = parse_simple_yaml(text)
    else:
        content = yaml.safe_load(text) or {}
    if ENV_ID not in content:
        raise SystemExit(f"{path} has no {ENV_ID!r} entry (keys: {list(content)})")
    return dict(content[ENV_ID])


def parse_simple_yaml(text: str) -> dict[str, Any]:
    """The YAML subset of the hyperparameter files, without PyYAML: nested ``key: value``
    mappings by indentation, ``#`` comments, quoted or bare strings, numbers (``!!float``
    tags allowed), ``true``/``false``/``null`` and JSON-style ``[...]``/``{...}`` values."""
    root: dict[str, Any] = {}
    stack: list[tuple[int, dict]] = [(-1, root)]
    for number, raw in enumerate(text.splitlines(), 1):
        line = _strip_comment(raw).rstrip()
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip(" "))
        key, sep, value = line.strip().partition(":")
        if not sep or not key:
            raise SystemExit(f"hyperparameter file line {number}: expected 'key: value': {raw!r}")
        while indent <= stack[-1][0]:
            stack.pop()
        parent = stack[-1][1]
        key = key.strip().strip("'\"")
        if value.strip():
            parent[key] = _yaml_scalar(value.strip(), number)
        else:
            parent[key] = {}
            stack.append((indent, parent[key]))
    return root


def _strip_comment(line: str) -> str:
    quote = None
    for k, ch in enumerate(line):
        if ch in "'\"" and quote in (None, ch):
            quote = None if quote else ch
        elif ch == "#" and quote is None and (k == 0 or line[k - 1] in " \t"):
            return line[:k]
    return line


def _yaml_scalar(value: str, number: int) -> Any:
    if value.startswith("!!float"):
        return float(value[len("!!float") :].strip())
    if value[0] in "'\"" and value[-1] == value[0] and len(value) > 1:
        return value[1:-1]
    if value[0] in "[{":
        try:
            return json.loads(value)
        except json.JSONDecodeError:
            raise SystemExit(f"hyperparameter file line {number}: not JSON: {value!r}") from None
    lowered = value.lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    if lowered in ("null", "~"):
        return None
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            pass
    return value


def _linear_schedule(initial: float):
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def algo_kwargs_from(hp: dict[str, Any]) -> dict[str, Any]:
    """Turn the RL-Zoo conventions into SB3 constructor arguments (the rest pass through)."""
    import torch.nn as nn
    from stable_baselines3.common.noise import NormalActionNoise

    skip = {"n_envs", "n_timesteps", "normalize", "env_kwargs", "noise_type", "noise_std"}
    kwargs = {k: v for k, v in hp.items() if k not in skip}
    kwargs.setdefault("policy", "MlpPolicy")
    for key in ("learning_rate", "clip_range", "clip_range_vf"):  # "lin_3e-4": linear decay
        if isinstance(kwargs.get(key), str):
            try:  # PyYAML reads 1e-3 (no dot) as a string
                kwargs[key] = float(kwargs[key])
                continue
            except ValueError:
                pass
            kind, _, value = kwargs[key].partition("_")
            if kind != "lin":
                raise SystemExit(f"{key}: only 'lin_<value>' schedules are understood")
            kwargs[key] = _linear_schedule(float(value))
    if isinstance(kwargs.get("policy_kwargs"), str):  # "dict(net_arch=[64, 64])"
        kwargs["policy_kwargs"] = eval(kwargs["policy_kwargs"], {"dict": dict, "nn": nn})
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    if hp.get("noise_type"):
        if hp["noise_type"] != "normal":
            raise SystemExit("noise_type: only 'normal' is understood")
        kwargs["action_noise"] = NormalActionNoise(np.zeros(1), float(hp["noise_std"]) * np.ones(1))
    return kwargs


def normalize_kwargs_from(hp: dict[str, Any]) -> dict[str, Any]:
    """``VecNormalize`` arguments: obs and reward normalised, obs clipped at 10, the algorithm's
    gamma; the file's ``normalize`` (``true`` or a ``"dict(...)"`` string) may change them."""
    kwargs = {"norm_obs": True, "norm_reward": True, "clip_obs": 10.0}
    given = hp.get("normalize", True)
    if isinstance(given, str):
        given = eval(given, {"dict": dict})
    if isinstance(given, dict):
        kwargs.update(given)
    kwargs["gamma"] = float(hp.get("gamma", 0.99))
    if not kwargs["norm_obs"]:
        raise SystemExit("normalize: norm_obs must stay True (agents/sb3_policy.py normalises)")
    return kwargs


def resolve_env_kwargs(file_kwargs: dict, cli_kwargs: dict) -> dict[str, Any]:
    """Training defaults < hyperparameter file < command line; validated, errors name the key."""
    env_kwargs = {**TRAIN_ENV_DEFAULTS, **(file_kwargs or {}), **cli_kwargs}
    try:
        EnvConfig.from_kwargs(**env_kwargs)
    except (ValueError, TypeError) as err:
        culprits = []
        for key, value in env_kwargs.items():  # which argument, if the message does not say
            try:
                EnvConfig.from_kwargs(**{key: value})
            except (ValueError, TypeError):
                culprits.append(f"{key}={value!r}")
        where = f" (check {', '.join(culprits)})" if culprits else ""
        raise SystemExit(f"error: bad environment argument: {err}{where}") from None
    return env_kwargs


# ----------------------------------------------------------------------------- env
def run_seed_for(seed: int, timesteps_done: int) -> int:
    """The seed of a run that starts after ``timesteps_done`` steps: ``seed`` itself for a new
    run, else an integer derived from both by ``numpy.random.SeedSequence`` (not ``seed +
    timesteps``, which could be another run's seed)."""
    if timesteps_done == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(timesteps_done)]).generate_state(1)[0])


def make_env(num_envs: int, seed: int, env_kwargs: dict, norm_kwargs: dict, vecnormalize=None):
    """The batched kernel as an SB3 VecEnv, + VecMonitor + VecNormalize (new, or a saved one)."""
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from capsule_env.sb3 import CapsuleSuspensionSB3VecEnv

    venv = CapsuleSuspensionSB3VecEnv(num_envs, **env_kwargs)
    venv.seed(seed)  # vehicle n: stream n of SeedSequence(seed) (guideway window, noise, ...)
    venv = VecMonitor(venv)
    if vecnormalize is not None:  # resume: keep the checkpoint's running statistics
        return VecNormalize.load(str(vecnormalize), venv)
    return VecNormalize(venv, **norm_kwargs)


class NormalizedPolicy:
    """The model seen through the training ``VecNormalize`` statistics, frozen: what
    ``agents.sb3_policy.SB3Policy`` does with the saved files (``normalize_obs`` never updates
    the statistics)."""

    def __init__(self, model: Any, vec_normalize: Any) -> None:
        self.model = model
        self.vec_normalize = vec_normalize

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = self.vec_normalize.normalize_obs(np.asarray(observation, dtype=np.float32))
        action, state = self.model.predict(
            obs, state=state, episode_start=episode_start, deterministic=deterministic
        )
        return np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0), state


# ----------------------------------------------------------------------------- saving
def policy_env_kwargs(env_kwargs: dict) -> dict:
    return {k: v for k, v in env_kwargs.items() if k not in EVALUATION_CHOSEN}


def save_policy(model: Any, stem: Path, meta: dict, replay_buffer: bool = False) -> None:
    """``stem.zip`` (model), ``stem.vecnormalize.pkl`` (statistics), optionally
    ``stem.replay_buffer.pkl`` (SAC/TD3), and ``stem.json`` (metadata), saved together.

    Every file is written to a temporary name next to it first, then all are renamed into
    place (statistics, replay buffer, model, and the metadata last): a failed save (a full
    disk, a kill) leaves the previous files as they were. The json records the size and
    SHA-256 of the model and statistics (``files``) and of the replay buffer
    (``replay_buffer``), which the loaders check (:func:`checkpoint_problem`,
    ``agents.sb3_policy.SB3Policy.load``): a mixed or truncated set is refused.
    """
    stem = Path(stem)
    zip_path = stem.with_name(stem.name + ".zip")
    pkl_path = stem.with_name(stem.name + ".vecnormalize.pkl")
    rb_path = stem.with_name(stem.name + ".replay_buffer.pkl")
    with StagedFiles() as staged:
        model.get_vec_normalize_env().save(str(staged.temp_for(pkl_path)))
        if replay_buffer:
            model.save_replay_buffer(str(staged.temp_for(rb_path)))
        model.save(str(staged.temp_for(zip_path)))
        temps = staged.staged
        meta = {
            **meta,
            "files": {p.name: file_digest(temps[p]) for p in (zip_path, pkl_path)},
        }
        if replay_buffer:
            meta["replay_buffer"] = {rb_path.name: file_digest(temps[rb_path])}
        staged.write_text(
            stem.with_name(stem.name + ".json"), json.dumps(meta, indent=2, default=str)
        )


def save_checkpoint(model: Any, ckpt_dir: Path, meta: dict, keep_replay_buffers: int = 2) -> Path:
    """``ckpt_dir/ckpt_<steps>.*`` (:func:`save_policy`; SAC/TD3 with the replay buffer unless
    ``keep_replay_buffers`` is 0), then :func:`prune_replay_buffers`. Returns the ``.zip``."""
    stem = ckpt_dir / f"ckpt_{model.num_timesteps:012d}"
    with_buffer = hasattr(model, "save_replay_buffer") and keep_replay_buffers > 0
    save_policy(model, stem, {**meta, "num_timesteps": int(model.num_timesteps)}, with_buffer)
    if hasattr(model, "save_replay_buffer"):
        prune_replay_buffers(ckpt_dir, keep_replay_buffers)
    return Path(str(stem) + ".zip")


def prune_replay_buffers(ckpt_dir: Path, keep: int) -> list[Path]:
    """Delete the ``.replay_buffer.pkl`` files of all but the newest ``keep`` checkpoints (by
    their timesteps); the checkpoints' models stay. Returns the deleted paths."""
    buffers = sorted(Path(ckpt_dir).glob("ckpt_*.replay_buffer.pkl"))  # zero-padded steps
    doomed = buffers[: max(len(buffers) - keep, 0)]
    for path in doomed:
        path.unlink(missing_ok=True)
    return doomed


def checkpoint_problem(zip_path: Path) -> str | None:
    """Why the checkpoint ``zip_path`` (with its ``.vecnormalize.pkl`` and ``.json``, and
    ``.replay_buffer.pkl`` when present) cannot be resumed from, or None when it is intact.

    Checked: the json (written last, the mark of a complete save) is readable; the files
    exist and, when the json records their sizes and SHA-256 (``save_policy``), match them;
    else (older checkpoints) the zip is a readable zip archive and the statistics unpickle.
    """
    zip_path = Path(zip_path)
    stem = zip_path.with_suffix("")
    meta_path = stem.with_suffix(".json")
    pkl_path = Path(str(stem) + ".vecnormalize.pkl")
    if not meta_path.is_file():
        return f"no {meta_path.name} (the save did not finish)"
    try:
        meta = json.loads(meta_path.read_text())
        steps = int(meta["num_timesteps"])
    except (OSError, UnicodeDecodeError, ValueError, TypeError, KeyError) as exc:
        return f"{meta_path.name} is not readable checkpoint metadata ({type(exc).__name__}: {exc})"
    missing = [k for k in ("algo", "num_envs", "train_env_kwargs") if k not in meta]
    if missing:
        return f"{meta_path.name} lacks {', '.join(missing)}"
    if f"ckpt_{steps:012d}" != stem.name and stem.name.startswith("ckpt_"):
        return f"{meta_path.name} says {steps} timesteps, not those of its name"
    for path in (zip_path, pkl_path):
        if not path.is_file() or path.stat().st_size == 0:
            return f"{path.name} is missing or empty"
    if isinstance(meta.get("files"), dict):
        problem = digest_mismatch(zip_path.parent, meta["files"])
        if problem:
            return problem
    else:  # a checkpoint from before the digests: check that the files can be read
        import pickle
        import zipfile

        try:
            with zipfile.ZipFile(zip_path) as archive:
                bad = archive.testzip()
            if bad is not None:
                return f"{zip_path.name}: member {bad} is corrupt"
            with pkl_path.open("rb") as fh:
                pickle.load(fh)
        except Exception as exc:  # a corrupt archive or pickle raises many types
            return f"cannot read it ({type(exc).__name__}: {exc})"
    buffer = meta.get("replay_buffer")
    if isinstance(buffer, dict):  # pruned buffers are allowed to be absent
        present = {n: d for n, d in buffer.items() if (zip_path.parent / n).is_file()}
        problem = digest_mismatch(zip_path.parent, present)
        if problem:
            return problem
    return None


def latest_checkpoint(output_dir: Path) -> Path:
    """The newest intact checkpoint in ``output_dir/checkpoints`` (:func:`checkpoint_problem`);
    each newer one that is not intact is reported on stderr, with the reason, and skipped."""
    ckpt_dir = output_dir / "checkpoints"
    stems = {p.name.split(".")[0] for p in ckpt_dir.glob("ckpt_*.*")}
    if not stems:
        raise ValueError(f"--resume auto: no checkpoint in {ckpt_dir}")
    skipped = 0
    for name in sorted(stems, reverse=True):  # zero-padded timesteps: newest first
        zip_path = ckpt_dir / f"{name}.zip"
        problem = checkpoint_problem(zip_path)
        if problem is None:
            return zip_path
        skipped += 1
        print(f"--resume auto: skipping {zip_path}: {problem}", file=sys.stderr, flush=True)
    raise ValueError(f"--resume auto: no intact checkpoint in {ckpt_dir} ({skipped} skipped)")


# ----------------------------------------------------------------------------- callbacks
def _callbacks():
    from stable_baselines3.common.callbacks import BaseCallback

    class TrainingMonitor(BaseCallback):
        """Held-out evaluation (best model by Wk-weighted RMS body acceleration), periodic
        checkpoints and throughput, every ``eval_freq`` / ``checkpoint_freq`` env steps, and a
        checkpoint every ``checkpoint_minutes`` of wall time."""

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

        def _checkpoint(self, label: str) -> None:
            path = self.run.checkpoint(self.model)
            print(f"[{self.num_timesteps:>10d}] {label} {path}", flush=True)

        def _on_rollout_end(self) -> None:
            self.run.rollout_end_timesteps = self.num_timesteps

    return TrainingMonitor


def _next_multiple(steps: int, every: int) -> float:
    return math.inf if every <= 0 else (steps // every + 1) * every


# ----------------------------------------------------------------------------- the run
class Run:
    """State shared by the callbacks and the main loop: where to save, the clock, the best
    evaluation so far and the metadata that goes with every saved policy."""

    def __init__(self, args: Args, env_kwargs: dict, hp: dict, output_dir: Path) -> None:
        self.args = args
        self.env_kwargs = env_kwargs
        self.hp = hp
        self.output_dir = output_dir
        self.name = args.name or f"{args.algo}-seed{args.seed}"
        self.start_timesteps = 0
        self.rollout_end_timesteps = 0  # PPO: steps of the last complete rollout
        self.wall_before = 0.0  # wall time of the runs this one resumes
        self.t0 = time.perf_counter()
        self.eval_seconds = 0.0
        self.best: dict | None = None  # {"num_timesteps", "wk_rms_body_acc_m_s2", ...}
        self.last_eval_timesteps = -1
        eval_kwargs = policy_env_kwargs(env_kwargs)
        self.eval_kwargs = eval_kwargs
        self.passive = None
        self.references: dict = {}
        self.last_checkpoint_clock = time.monotonic()  # for --checkpoint-minutes
        self.last_checkpoint_timesteps = 0  # set to the checkpoint's on resume

    # -- clock
    def wall_time(self) -> float:
        return self.wall_before + time.perf_counter() - self.t0

    def steps_per_s(self, num_timesteps: int) -> float:
        """Training throughput of this process: env steps / (wall time minus evaluations)."""
        elapsed = time.perf_counter() - self.t0 - self.eval_seconds
        return (num_timesteps - self.start_timesteps) / max(elapsed, 1e-9)

    def meta(self, model: Any, **extra: Any) -> dict:
        return {
            "name": self.name,
            "algo": self.args.algo,
            "env_kwargs": policy_env_kwargs(self.env_kwargs),
            "train_env_kwargs": self.env_kwargs,
            "num_timesteps": int(model.num_timesteps),
            "wall_time_s": round(self.wall_time(), 2),
            "seed": self.args.seed,
            "num_envs": model.n_envs,
            "hyperparams": self.hp,
            "best": self.best,
            **extra,
        }

    # -- evaluation on the held-out guideway bank
    def evaluate(self, model: Any, logger: Any = None) -> dict:
        from agents.classical import PassiveController

        if model.num_timesteps == self.last_eval_timesteps:
            return self.best or {}
        t_start = time.perf_counter()
        a = self.args
        if self.passive is None:  # the VRE reference: passive damper on the same seeds
            passive_kwargs = {**self.eval_kwargs, **PassiveController.env_kwargs}
            self.passive = run_episodes(
                PassiveController(), passive_kwargs, a.eval_episodes, a.eval_seed,
                a.eval_episode_length,
            )  # fmt: skip
            self.references = self._references()
        policy = NormalizedPolicy(model, model.get_vec_normalize_env())
        rollout = run_episodes(
            policy, self.eval_kwargs, a.eval_episodes, a.eval_seed, a.eval_episode_length
        )
        m = episode_metrics(rollout, self.passive)
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
        key = (result["terminated_episodes"], result["wk_rms_body_acc_m_s2"])
        improved = self.best is None or key < (
            self.best["terminated_episodes"],
            self.best["wk_rms_body_acc_m_s2"],
        )
        if improved:
            self.best = result
            save_policy(
                model, self.output_dir / "best_model",
                self.meta(model, eval=self._eval_block(m)),
            )  # fmt: skip
        with (self.output_dir / "evaluations.jsonl").open("a") as fh:
            fh.write(json.dumps(result) + "\n")
        print(
            f"[{result['num_timesteps']:>10d}] eval Wk acc {result['wk_rms_body_acc_m_s2']:.4f} m/s^2"
            f"  VRE body m1 {result['vre_body_mode1_pct']:6.2f} %  stroke "
            f"{1000 * result['max_stroke_m']:5.1f} mm  hits {result['terminated_episodes']}"
            f"  | {result['steps_per_s']:8.0f} steps/s, {result['wall_time_s']:7.1f} s"
            + ("  *best*" if improved else ""),
            flush=True,
        )
        if logger is not None:
            logger.record("eval/wk_rms_body_acc_m_s2", result["wk_rms_body_acc_m_s2"])
            logger.record("eval/vre_body_mode1_pct", result["vre_body_mode1_pct"])
            logger.record("eval/max_stroke_m", result["max_stroke_m"])
            logger.record("time/env_steps_per_s", result["steps_per_s"])
        return result

    def _references(self) -> dict:
        """Passive and the best Skyhook variant on the evaluation seeds (numbers to compare
        with: the seeds differ from evaluate.py's, so do the absolute values)."""
        from agents import classical_controllers

        a = self.args
        wk = "wk_rms_body_acc_m_s2"
        refs = {"passive": {wk: episode_metrics(self.passive, None)[wk]}}
        sky = classical_controllers().get(REFERENCE_CONTROLLER)
        if sky is not None:
            kwargs = {**self.eval_kwargs, **sky.env_kwargs}
            roll = run_episodes(sky, kwargs, a.eval_episodes, a.eval_seed, a.eval_episode_length)
            m = episode_metrics(roll, self.passive)
            refs[REFERENCE_CONTROLLER] = {
                wk: m[wk],
                "vre_body_mode1_pct": m["vre_pct"]["body_mode1"],
            }
        described = [
            f"{name} Wk {r[wk]:.4f} m/s^2"
            + (
                f", VRE body m1 {r['vre_body_mode1_pct']:.2f} %"
                if "vre_body_mode1_pct" in r
                else ""
            )
            for name, r in refs.items()
        ]
        print(f"evaluation: seeds {a.eval_seed}..{a.eval_seed + a.eval_episodes - 1} of the "
              f"held-out guideway bank {EVALUATION_GUIDEWAY_SEED}; references: "
              + "; ".join(described), flush=True)  # fmt: skip
        return refs

    def _eval_block(self, m: dict) -> dict:
        a = self.args
        return {
            "guideway_seed": EVALUATION_GUIDEWAY_SEED,
            "seeds": [a.eval_seed, a.eval_seed + a.eval_episodes - 1],
            "episode_length_s": a.eval_episode_length,
            "metrics": m,
            "references": self.references,
        }

    def checkpoint(self, model: Any) -> Path:
        """Save a checkpoint of ``model`` now (:func:`save_checkpoint`)."""
        path = save_checkpoint(
            model, self.output_dir / "checkpoints", self.meta(model), self.args.keep_replay_buffers
        )
        self.last_checkpoint_clock = time.monotonic()
        self.last_checkpoint_timesteps = int(model.num_timesteps)
        return path


# ----------------------------------------------------------------------------- main
@dataclass
class Plan:
    """What :func:`prepare` checked and loaded before anything is trained."""

    output_dir: Path
    hp: dict
    env_kwargs: dict
    norm_kwargs: dict
    algo_kwargs: dict
    num_envs: int
    total: int
    ckpt: Path | None = None
    ckpt_meta: dict = field(default_factory=dict)
    tensorboard_log: str | None = None


def prepare(args: Args) -> Plan:
    """Check everything the run needs before it starts: the hyperparameters, the env
    arguments, the evaluation episode length, the checkpoint to resume from (``auto``: the
    newest intact one) and that the output and TensorBoard folders can be written. Raises
    ``ValueError``/``OSError`` (or ``SystemExit``) with a one-line message."""
    output_dir = Path(args.output_dir or f"runs/{args.algo}-seed{args.seed}")
    hp_path = args.hyperparams or Path(__file__).resolve().parent / f"hyperparams/{args.algo}.yml"
    hp = load_hyperparams(hp_path)
    env_kwargs = resolve_env_kwargs(hp.get("env_kwargs", {}), args.env_kwargs)
    norm_kwargs = normalize_kwargs_from(hp)
    algo_kwargs = algo_kwargs_from(hp)
    dt_s = EnvConfig.from_kwargs(**policy_env_kwargs(env_kwargs)).dt_s
    check_episode_length(args.eval_episode_length, dt_s, "--eval-episode-length")

    # Output folders: writable before any training time is spent.
    check_writable_dir(output_dir, "--output-dir")
    check_writable_dir(output_dir / "checkpoints", "checkpoint folder")
    if args.tensorboard:
        check_writable_dir(args.tensorboard, "--tensorboard")

    # Resume: the checkpoint fixes the algorithm, the number of vehicles and the statistics.
    ckpt, ckpt_meta = None, {}
    if args.resume:
        if args.resume == "auto":
            ckpt = latest_checkpoint(output_dir)
        else:
            ckpt = Path(args.resume)
            if not ckpt.is_file():
                raise ValueError(f"--resume: no checkpoint {ckpt}")
            problem = checkpoint_problem(ckpt)
            if problem:
                raise ValueError(f"--resume: cannot resume from {ckpt}: {problem}")
        ckpt_meta = json.loads(ckpt.with_suffix(".json").read_text())
        if ckpt_meta["algo"] != args.algo:
            raise ValueError(f"--resume: {ckpt} is {ckpt_meta['algo']}, not {args.algo}")
        if ckpt_meta["train_env_kwargs"] != env_kwargs:
            print(
                f"note: env arguments differ from the checkpoint's {ckpt_meta['train_env_kwargs']}"
            )
        num_envs = args.num_envs or ckpt_meta["num_envs"]
        if args.algo != "ppo" and num_envs != ckpt_meta["num_envs"]:
            raise ValueError("--resume: SAC/TD3 replay buffers need the checkpoint's num_envs")
    else:
        num_envs = args.num_envs or int(hp.get("n_envs", 1))

    total = int(args.total_timesteps or float(hp["n_timesteps"]))
    chunk = num_envs * (algo_kwargs.get("n_steps", 2048) if args.algo == "ppo" else 1)
    if total % chunk:
        total = (total // chunk + 1) * chunk
        print(f"total timesteps rounded up to {total} (a multiple of {chunk})")

    tensorboard_log = None
    if args.tensorboard:
        try:
            import tensorboard  # noqa: F401
        except ImportError:
            print("tensorboard logging disabled: the tensorboard package is not installed "
                  "(pip install tensorboard)", file=sys.stderr)  # fmt: skip
        else:
            tensorboard_log = args.tensorboard
    return Plan(output_dir, hp, env_kwargs, norm_kwargs, algo_kwargs, num_envs, total, ckpt,
                ckpt_meta, tensorboard_log)  # fmt: skip


def _best_so_far(output_dir: Path) -> dict | None:
    """The ``best`` block of ``best_model.json`` (None when absent or unreadable)."""
    path = output_dir / "best_model.json"
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())["best"]
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
        print(f"note: ignoring {path} ({exc!r}); the next evaluation writes a new best model",
              file=sys.stderr)  # fmt: skip
        return None


def train(args: Args, extra_callbacks: list | None = None) -> dict:
    """Train as ``args`` says; returns a summary (paths, timesteps, best evaluation).

    Bad arguments or files found before training starts (:func:`prepare`) raise
    ``SystemExit`` with one line, ``train.py: error: ...``.
    """
    import stable_baselines3 as sb3
    import torch
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.utils import set_random_seed

    try:
        plan = prepare(args)
    except (ValueError, OSError, TypeError) as exc:
        raise SystemExit(f"train.py: error: {exc}") from None
    torch.set_num_threads(args.threads)
    output_dir, env_kwargs, num_envs, total = (
        plan.output_dir, plan.env_kwargs, plan.num_envs, plan.total
    )  # fmt: skip
    ckpt, ckpt_meta, tensorboard_log = plan.ckpt, plan.ckpt_meta, plan.tensorboard_log
    algo_cls = getattr(sb3, args.algo.upper())
    run = Run(args, env_kwargs, plan.hp, output_dir)

    # Seeds in one place. The vehicles get the independent streams
    # SeedSequence(run_seed).spawn(num_envs), so that training seeds 0, 1, 2 share no stream; a
    # resumed run continues with fresh streams (a seed derived from the seed and the timesteps
    # done) instead of replaying the start. torch/numpy/random get the same run seed.
    start = 0
    if ckpt is not None:
        start = int(ckpt_meta["num_timesteps"])
    run_seed = run_seed_for(args.seed, start)
    set_random_seed(run_seed)
    env = make_env(
        num_envs, run_seed, env_kwargs, plan.norm_kwargs,
        vecnormalize=None if ckpt is None else str(ckpt.with_suffix("")) + ".vecnormalize.pkl",
    )  # fmt: skip

    if ckpt is None:
        model = algo_cls(env=env, seed=args.seed, device=args.device, verbose=args.verbose,
                         tensorboard_log=tensorboard_log, **plan.algo_kwargs)  # fmt: skip
    else:
        try:
            model = algo_cls.load(str(ckpt), env=env, device=args.device, verbose=args.verbose,
                                  tensorboard_log=tensorboard_log)  # fmt: skip
        except Exception as exc:  # e.g. the env's spaces differ from the checkpoint's
            env.close()
            raise SystemExit(f"train.py: error: --resume: cannot load {ckpt}: {exc}") from None
        rb = Path(str(ckpt.with_suffix("")) + ".replay_buffer.pkl")
        if hasattr(model, "load_replay_buffer"):
            if rb.is_file():
                model.load_replay_buffer(str(rb))
            else:
                print(f"note: {ckpt} has no replay buffer (--keep-replay-buffers keeps only the "
                      "newest ones): the replay buffer starts empty", file=sys.stderr)  # fmt: skip
        # First reset without updating the statistics, so training goes on from exactly the
        # checkpoint's (SB3's learn() would otherwise reset, and update them, itself).
        env.training = False
        model._last_obs = env.reset()
        model._last_original_obs = env.get_original_obs()
        model._last_episode_starts = np.ones(num_envs, dtype=bool)
        env.training = True
        run.start_timesteps = run.rollout_end_timesteps = model.num_timesteps
        run.last_checkpoint_timesteps = model.num_timesteps
        run.wall_before = float(ckpt_meta.get("wall_time_s", 0.0))
        run.best = _best_so_far(output_dir)  # best_model may be newer than the checkpoint
        print(f"resumed {ckpt} at {model.num_timesteps} timesteps")

    print(
        f"{args.algo.upper()} on {ENV_ID} {env_kwargs}: {num_envs} vehicles, {total} timesteps, "
        f"torch threads {args.threads}; output {output_dir}",
        flush=True,
    )
    callbacks = [_callbacks()(run), *(extra_callbacks or [])]
    interrupted = False
    remaining = total - model.num_timesteps
    try:
        if remaining > 0:
            model.learn(
                remaining, callback=CallbackList(callbacks), reset_num_timesteps=ckpt is None,
                progress_bar=args.progress, tb_log_name=run.name,
            )  # fmt: skip
    except KeyboardInterrupt:
        interrupted = True
        if args.algo == "ppo":  # a rollout cut short was not learned from: count it out
            model.num_timesteps = run.rollout_end_timesteps
        path = run.checkpoint(model)
        print(f"\ninterrupted at {model.num_timesteps} timesteps: checkpoint {path}\n"
              f"continue with: python train.py ... --output-dir {output_dir} --resume auto")  # fmt: skip
    if not interrupted:
        run.evaluate(model)  # the final policy is a candidate for the best one too
        final_meta = run.meta(model, name=f"{run.name}-final")  # its own row in evaluate.py
        save_policy(model, output_dir / "final_model", final_meta)
    if model.num_timesteps != run.last_checkpoint_timesteps:  # always resumable at the end
        run.checkpoint(model)
    steps = model.num_timesteps - run.start_timesteps
    elapsed = time.perf_counter() - run.t0
    print(
        f"done: {model.num_timesteps} timesteps; this process {steps} steps in {elapsed:.1f} s "
        f"wall ({steps / max(elapsed, 1e-9):.0f} steps/s overall, "
        f"{run.steps_per_s(model.num_timesteps):.0f} steps/s training without evaluations; "
        f"total wall time {run.wall_time():.1f} s)",
        flush=True,
    )
    if run.best:
        print(f"best: Wk acc {run.best['wk_rms_body_acc_m_s2']:.4f} m/s^2, VRE body m1 "
              f"{run.best['vre_body_mode1_pct']:.2f} % at {run.best['num_timesteps']} timesteps "
              f"-> {output_dir / 'best_model.zip'}")  # fmt: skip
    env.close()
    return {
        "output_dir": str(output_dir),
        "num_timesteps": int(model.num_timesteps),
        "interrupted": interrupted,
        "best": run.best,
        "wall_time_s": run.wall_time(),
        "model": model,
    }


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    # A termination request (a job scheduler's SIGTERM) also saves a checkpoint, like Ctrl-C.
    signal.signal(signal.SIGTERM, _interrupt)
    summary = train(args)
    return 130 if summary["interrupted"] else 0


if __name__ == "__main__":
    sys.exit(main())
