"""The kinds of trial a study can run: a small registry, one :class:`Kind` per kind.

A kind is a plain function ``run(trial) -> metrics`` (``trial``: a
:class:`capsule_env.sweep.study.Trial` with ``name``, ``params``, ``seed`` and ``dir``, the
trial's own folder; ``metrics``: a flat mapping of numbers and strings, one table column each)
plus the parameter names it accepts and a cheap ``check(params)`` run on every trial before the
study starts. The functions run the same with or without Ray.

- ``train``: ``train.py``'s ``train(Args)`` with the trial's seed; parameters: the fields of
  ``train.Args`` (``total_timesteps``, ``num_envs``, ``algo``, ``eval_freq``, ...),
  ``hp.<key>`` (an entry of the hyperparameter file, e.g. ``hp.learning_rate``; its value
  checked as :mod:`capsule_env.sweep.hyperparameters` says) and ``env.<key>`` (an env
  argument). The trial writes its hyperparameter file
  (``hyperparams.yml``) and train.py's output folder (``run/``: ``best_model.*``, ...) into its
  folder; a trial started again continues from train.py's newest checkpoint there. Metrics:
  the best held-out evaluation (validation bank 7) and the timesteps.
- ``gains``: a classical controller (``capsule_env.agents.controllers.classical``) with the given gains
  (``gain.<name>``, numbers >= 0) on ``episodes`` episodes (seeds ``episode_seed ..``) of the
  guideway bank ``guideway_seed`` (default 0, the training bank, as
  ``python -m capsule_env.agents.controllers.tuning``), through
  :func:`capsule_env.evaluation.episodes.run_episodes` and :func:`~capsule_env.evaluation.episodes.
  episode_metrics` (the passive damper on the same episodes is the VRE reference). Every grid
  point runs the same episodes (common random numbers: the grid compares gains, not noise).
  ``env.<key>`` changes the env, never the law: the keys the controller fixes (its
  ``env_kwargs``, as evaluate.py runs it: action mode, observation, inverse model, ...) and
  the trial's own (``setting``, ``guideway_seed``, ``episode_length_s``, ``num_envs``) are
  refused.
- ``oracle``: ``capsule_env.oracle.clairvoyant_bound(env_kwargs, seeds, episode_length_s)``;
  ``env.episode_length_s`` and ``env.num_envs`` are refused (the trial sets them).

The train kind reads :mod:`capsule_env.agents.learning` (the ``rl`` extra) through
:mod:`capsule_env.sweep._rl` only, on first use; the rest of the package is imported at the
top (the rule is written there).

Adding a kind is one function and one :func:`register_kind` call; on Ray, the workers must
register it too (the trials look their kind up by name), e.g. with
``ray.init(runtime_env={"worker_process_setup_hook": register})`` before the sweep runs::

    def run_mine(trial):
        return {"wk_rms_body_acc_m_s2": ...}

    register_kind(Kind("mine", run_mine, keys={"episodes": "how many"}))
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import json
import shutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from capsule_env.agents.controllers.classical import FACTORIES, PassiveController, make_controller
from capsule_env.common.cli import field_docs
from capsule_env.common.safe_io import atomic_write_text
from capsule_env.engine.config import EnvConfig
from capsule_env.evaluation.condition import config_at_length
from capsule_env.evaluation.episodes import (
    EVALUATION_GUIDEWAY_SEED,
    check_episode_length,
    episode_metrics,
    run_episodes,
)
from capsule_env.oracle import clairvoyant_bound
from capsule_env.sweep._rl import learning, train_module
from capsule_env.sweep.hyperparameters import check_hp_values

if TYPE_CHECKING:
    from capsule_env.sweep.study import Trial

#: The metric every built-in kind reports and the summary figure plots.
SUMMARY_METRIC = "wk_rms_body_acc_m_s2"


def _nothing_to_check(params: dict[str, Any]) -> None:
    return None


def _available() -> str | None:
    return None


def _as_given(params: dict[str, Any]) -> dict[str, Any]:
    return params


@dataclass(frozen=True)
class Kind:
    """A kind of trial.

    ``run(trial)`` does the work and returns the metrics; ``keys`` are the parameter names it
    accepts (name -> meaning), ``prefixes`` the accepted ``prefix.<key>`` families;
    ``check(params)`` raises ``ValueError`` (one line, naming the key) for values that cannot
    run; ``seeded``: its trials get a seed each (replicates); ``unavailable()`` returns why the
    kind cannot run here (a missing library), or ``None``; ``resolve(params)`` returns them
    ready to run anywhere (relative paths made absolute: a Ray trial runs in its own folder)."""

    name: str
    run: Callable[[Trial], Mapping[str, Any]]
    keys: Mapping[str, str] | Callable[[], Mapping[str, str]] = field(default_factory=dict)
    prefixes: Mapping[str, str] = field(default_factory=dict)
    check: Callable[[dict[str, Any]], None] = _nothing_to_check
    seeded: bool = False
    unavailable: Callable[[], str | None] = _available
    resolve: Callable[[dict[str, Any]], dict[str, Any]] = _as_given

    def accepted_keys(self) -> Mapping[str, str]:
        return self.keys() if callable(self.keys) else self.keys

    def check_key(self, key: str, where: str) -> None:
        """``ValueError`` naming ``key`` and the accepted names unless this kind takes it."""
        from capsule_env.sweep.study import StudyError

        keys = self.accepted_keys()
        prefix, dot, rest = key.partition(".")
        if key in keys or (dot and f"{prefix}." in self.prefixes and rest):
            return
        accepted = [*keys, *(f"{p}<key>" for p in self.prefixes)]
        raise StudyError(f"{where}: unknown parameter {key!r} for kind {self.name!r}; "
                         f"accepted: {', '.join(accepted)}")  # fmt: skip


#: Every kind, by name.
KINDS: dict[str, Kind] = {}


def register_kind(kind: Kind) -> Kind:
    """Add ``kind`` to :data:`KINDS` (replacing one of the same name); returns it."""
    KINDS[kind.name] = kind
    return kind


def split_params(params: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """``params`` as (plain keys, ``{prefix: {key: value}}`` for the ``prefix.key`` ones)."""
    plain: dict[str, Any] = {}
    groups: dict[str, dict[str, Any]] = {}
    for key, value in params.items():
        prefix, dot, rest = key.partition(".")
        if dot:
            groups.setdefault(prefix, {})[rest] = value
        else:
            plain[key] = value
    return plain, groups


def flat_metrics(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Numbers and strings of a nested mapping, keys joined with ``.`` (lists dropped)."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flat_metrics(value, f"{name}."))
        elif isinstance(value, (bool, int, float, str)) or hasattr(value, "item"):
            value = value.item() if hasattr(value, "item") else value
            out[name] = int(value) if isinstance(value, bool) else value
    return out


def _number(value: Any, where: str, minimum: float | None = None, integer: bool = False) -> None:
    ok = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok or (minimum is not None and value < minimum):
        what = "an integer" if integer else "a number"
        bound = f" >= {minimum:g}" if minimum is not None else ""
        raise ValueError(f"{where}: expected {what}{bound}, got {value!r}")


def _env_config(env_kwargs: dict[str, Any]) -> Any:
    """The env's configuration of ``env_kwargs`` (its own one-line errors name the key)."""

    return EnvConfig.from_kwargs(**env_kwargs)


def _env_config_at(env_kwargs: dict[str, Any], episode_length_s: float) -> Any:
    """The env's configuration of ``env_kwargs`` with the trial's episodes (a trip shorter
    than the env's default episode is valid at its own length); a refused length is the
    length's own error (:func:`capsule_env.evaluation.condition.config_at_length`)."""

    return config_at_length(env_kwargs, episode_length_s, "episode_length_s")


# ----------------------------------------------------------------------------- train
#: train.Args fields a study does not set: the sweep chooses them per trial.
_TRAIN_CHOSEN = ("seed", "output_dir", "name", "resume", "progress", "env", "env_kwargs",
                 "explicit")  # fmt: skip


def _train_unavailable() -> str | None:
    for module in ("stable_baselines3", "yaml"):
        if importlib.util.find_spec(module) is None:
            return f"{module} is not installed (pip install 'capsule-env[rl,scale]')"
    return None


def _train_keys() -> dict[str, str]:
    docs = field_docs(train_module().Args)
    return {k: v for k, v in docs.items() if k not in _TRAIN_CHOSEN}


def _hyperparams(plain: dict[str, Any]) -> tuple[Path, dict[str, Any]]:
    """The base hyperparameter file of a train trial and its entry."""
    load_hyperparams = learning("hyperparams").load_hyperparams
    HYPERPARAMS_DIR = learning("training").HYPERPARAMS_DIR

    algo = plain.get("algo", "ppo")
    path = Path(plain.get("hyperparams") or HYPERPARAMS_DIR / f"{algo}.yml").resolve()
    return path, load_hyperparams(path)


def _hp_keys(algo: str, base: dict[str, Any]) -> set[str]:
    algorithm_class = learning("algorithms").algorithm_class
    NOT_ALGORITHM_ARGUMENTS = learning("hyperparams").NOT_ALGORITHM_ARGUMENTS

    signature = inspect.signature(algorithm_class(algo).__init__)
    taken = {"self", "env", "seed", "device", "verbose", "tensorboard_log", "_init_setup_model"}
    return {*base, *NOT_ALGORITHM_ARGUMENTS, *(p for p in signature.parameters if p not in taken)}


def check_train(params: dict[str, Any]) -> None:
    """A train trial's arguments: train.Args' values and ranges, the env arguments, the
    evaluation episode length and the ``hp.`` keys (the algorithm's arguments)."""
    resolve_env_kwargs = learning("hyperparams").resolve_env_kwargs
    check_args = learning("run_args").check_args
    ALGORITHMS = learning("sb3_policy").ALGORITHMS
    policy_env_kwargs = learning("training").policy_env_kwargs

    plain, groups = split_params(params)
    algo = plain.get("algo", "ppo")
    if algo not in ALGORITHMS:
        raise ValueError(f"algo: unknown algorithm {algo!r}; accepted: {', '.join(ALGORITHMS)}")
    defaults = train_module().Args()
    for key, value in plain.items():
        default = getattr(defaults, key)
        if key in ("total_timesteps", "num_envs", "eval_freq", "eval_episodes", "eval_seed",
                   "checkpoint_freq", "keep_replay_buffers", "threads", "env_threads",
                   "verbose"):  # fmt: skip
            _number(value, key, 0, integer=True)
        elif isinstance(default, (int, float)) and not isinstance(default, bool):
            _number(value, key, 0)
        elif key in ("hyperparams", "tensorboard", "device") and not isinstance(value, str):
            raise ValueError(f"{key}: expected a string, got {value!r}")
    args = train_module().Args(**plain, env_kwargs=groups.get("env", {}))
    check_args(args)
    path, base = _hyperparams(plain)
    unknown = sorted(set(groups.get("hp", {})) - _hp_keys(algo, base))
    if unknown:
        raise ValueError(f"hp.{unknown[0]}: not a hyperparameter of {algo} (the keys of {path} "
                         f"and {algo.upper()}'s arguments)")  # fmt: skip
    check_hp_values(algo, base, groups.get("hp", {}))
    env_kwargs = resolve_env_kwargs(base.get("env_kwargs", {}), groups.get("env", {}))
    dt_s = _env_config(policy_env_kwargs(env_kwargs)).dt_s
    check_episode_length(args.eval_episode_length, dt_s, "eval_episode_length")


def resolve_train(params: dict[str, Any]) -> dict[str, Any]:
    """``hyperparams`` and ``tensorboard`` as absolute paths."""
    out = dict(params)
    for key in ("hyperparams", "tensorboard"):
        if out.get(key):
            out[key] = str(Path(out[key]).resolve())
    return out


def train_args(trial: Trial, folder: str | Path) -> Any:
    """``train.Args`` of a train trial run in ``folder``: the base hyperparameter file with the
    trial's ``hp.`` values written to ``folder/hyperparams.yml``, the run in ``folder/run``
    (resumed from its newest checkpoint when it has one)."""
    import yaml

    ENV_ID = learning("hyperparams").ENV_ID

    plain, groups = split_params(trial.params)
    _, hp = _hyperparams(plain)
    hp.update(groups.get("hp", {}))
    folder = Path(folder)
    yml = folder / "hyperparams.yml"
    atomic_write_text(yml, yaml.safe_dump({ENV_ID: hp}, sort_keys=False))
    out = folder / "run"
    resume = "auto" if any((out / "checkpoints").glob("ckpt_*.zip")) else None
    if resume is None and out.exists():  # this trial's own start, stopped before a checkpoint:
        RunFolderLock = learning("checkpoints").RunFolderLock

        with RunFolderLock() as lock:  # not while a process still trains in it (ValueError)
            lock.acquire(out)
            shutil.rmtree(out)  # nothing to continue; train.py starts only in an empty folder
    plain["hyperparams"] = str(yml)
    return train_module().Args(**plain, seed=int(trial.seed or 0),
                               env_kwargs=groups.get("env", {}), output_dir=str(out),
                               name=trial.name, resume=resume, progress=False)  # fmt: skip


def run_train(trial: Trial) -> dict[str, Any]:
    """Train with ``train.py``'s ``train(Args)`` in the trial's folder (see the module
    docstring); returns the best evaluation, the timesteps and the output folder."""
    train = train_module()
    args = train_args(trial, trial.dir)
    try:
        summary = train.train(args)
    except SystemExit as exc:  # train's one-line errors
        raise RuntimeError(str(exc.code)) from None
    if summary["interrupted"]:  # Ctrl-C: stop the sweep (train.py saved a checkpoint)
        raise KeyboardInterrupt
    best = summary.get("best") or {}
    metrics = {k: best[k] for k in ("wk_rms_body_acc_m_s2", "rms_body_acc_m_s2",
               "vre_body_mode1_pct", "max_stroke_m", "terminated_episodes") if k in best}  # fmt: skip
    metrics["best_timesteps"] = best.get("num_timesteps")
    metrics["num_timesteps"] = summary["num_timesteps"]
    metrics["train_wall_time_s"] = summary["wall_time_s"]
    metrics["output_dir"] = summary["output_dir"]
    return metrics


# ----------------------------------------------------------------------------- gains
#: Constructor arguments of the classical laws that are not gains.
_NOT_GAINS = ("observation", "vehicle", "extra_units", "extra_given", "extra_fallback")
_GAINS_KEYS = {
    "controller": "a classical controller of capsule_env.agents.controllers.classical (required)",
    "setting": "sim or hils (default hils)",
    "guideway_seed": "the guideway bank (default 0, the training bank)",
    "episodes": "episodes per trial (default 10)",
    "episode_seed": "the first episode's seed (default 0)",
    "episode_length_s": "seconds per episode (default 10)",
}


def _gains_settings(params: dict[str, Any]) -> tuple[dict, dict, dict]:
    plain, groups = split_params(params)
    settings = {"setting": "hils", "guideway_seed": 0, "episodes": 10, "episode_seed": 0,
                "episode_length_s": 10.0, **plain}  # fmt: skip
    return settings, groups.get("gain", {}), groups.get("env", {})


def gain_names(controller: str) -> list[str]:
    """The gains the classical controller ``controller`` takes (its constructor's names)."""

    signature = inspect.signature(FACTORIES[controller])
    return [p for p in signature.parameters if p not in _NOT_GAINS]


#: Env arguments a gains trial sets itself (its own keys; one vehicle per episode).
_GAINS_OWN_ENV = {
    "setting": "give it as the trial's 'setting'",
    "guideway_seed": "give it as the trial's 'guideway_seed'",
    "episode_length_s": "give it as the trial's 'episode_length_s'",
    "num_envs": "one vehicle runs each episode: give 'episodes'",
}


def _check_gain_values(name: str, gains: dict[str, Any]) -> None:
    """Every gain is one of the controller's, a number >= 0 (an integer where its default
    is one): damping coefficients, forces, currents, weights and counts are never negative."""

    parameters = inspect.signature(FACTORIES[name]).parameters
    accepted = gain_names(name)
    for gain, value in gains.items():
        if gain not in accepted:
            raise ValueError(f"gain.{gain}: {name} has no such gain; accepted: "
                             f"{', '.join(accepted) or 'none'}")  # fmt: skip
        default = parameters[gain].default
        integer = isinstance(default, int) and not isinstance(default, bool)
        _number(value, f"gain.{gain}", 0, integer=integer)


def _check_gains_env(name: str, fixed: Mapping[str, Any], env: dict[str, Any]) -> None:
    """``env.<key>`` may not change what the trial or the controller sets: the controller's
    ``env_kwargs`` (what it needs, as evaluate.py runs it) and the trial's own keys."""
    for key in env:
        if key in _GAINS_OWN_ENV:
            raise ValueError(f"env.{key}: the gains trial sets it; {_GAINS_OWN_ENV[key]}")
        if key in fixed:
            hint = f" (a gain of {name}: give gain.{key})" if key in gain_names(name) else ""
            raise ValueError(
                f"env.{key}: {name} fixes {key}={fixed[key]!r}{hint}; accepted: env arguments "
                f"other than those it fixes ({', '.join(fixed)}) and the trial's own "
                f"({', '.join(_GAINS_OWN_ENV)})"
            )


def check_gains(params: dict[str, Any]) -> None:
    """A gains trial: a known controller, its gain names, numbers >= 0, env arguments that
    leave the controller's and the trial's own alone, a valid env and an episode long enough
    for the metrics."""

    settings, gains, env = _gains_settings(params)
    name = settings.get("controller")
    if not isinstance(name, str) or name not in FACTORIES:
        raise ValueError(f"controller: unknown controller {name!r}; accepted: "
                         f"{', '.join(FACTORIES)}")  # fmt: skip
    _check_gain_values(name, gains)
    _number(settings["episodes"], "episodes", 1, integer=True)
    _number(settings["episode_seed"], "episode_seed", 0, integer=True)
    _number(settings["episode_length_s"], "episode_length_s")  # > 0: below
    ctrl = make_controller(name, **gains)
    _check_gains_env(name, ctrl.env_kwargs, env)
    config = _env_config_at({**ctrl.env_kwargs, "setting": settings["setting"],
                             "guideway_seed": settings["guideway_seed"], **env},
                            settings["episode_length_s"])  # fmt: skip
    check_episode_length(settings["episode_length_s"], config.dt_s, "episode_length_s")


def run_gains(trial: Trial) -> dict[str, Any]:
    """The controller with the trial's gains and the passive damper on the same episodes;
    returns :func:`~capsule_env.evaluation.episodes.episode_metrics` flattened (``vre_body_mode1_pct``,
    ... and the spread of the Wk-weighted RMS acceleration over the episodes)."""

    settings, gains, env = _gains_settings(trial.params)
    ctrl = make_controller(settings["controller"], **gains)
    base = {"setting": settings["setting"], "guideway_seed": settings["guideway_seed"], **env}
    first = settings["episode_seed"]
    seeds = list(range(first, first + settings["episodes"]))
    length = float(settings["episode_length_s"])
    roll = run_episodes(ctrl, {**ctrl.env_kwargs, **base}, episode_length_s=length, seeds=seeds)
    passive = run_episodes(PassiveController(), {**base, **PassiveController.env_kwargs},
                           episode_length_s=length, seeds=seeds)  # fmt: skip
    m = episode_metrics(roll, passive)
    out = {k: v for k, v in m.items() if isinstance(v, (int, float))}
    out.update({f"vre_{k}_pct": v for k, v in m["vre_pct"].items()})
    out[f"{SUMMARY_METRIC}_std"] = m["std"][SUMMARY_METRIC]
    out[f"passive_{SUMMARY_METRIC}"] = episode_metrics(passive, None)[SUMMARY_METRIC]
    return out


# ----------------------------------------------------------------------------- oracle
_ORACLE_KEYS = {
    "episodes": "episodes per trial (default 5)",
    "episode_seed": "the first episode's seed (default 1000, the evaluation seeds)",
    "episode_length_s": "seconds per episode (default 4)",
    "max_iter": "L-BFGS-B iterations per search (default 150)",
}


def _oracle_settings(params: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    plain, groups = split_params(params)
    defaults = {"episodes": 5, "episode_seed": 1000, "episode_length_s": 4.0, "max_iter": 150}
    return {**defaults, **plain}, groups.get("env", {})


#: Env arguments an oracle trial sets itself.
_ORACLE_OWN_ENV = {
    "episode_length_s": "give it as the trial's 'episode_length_s'",
    "num_envs": "one vehicle runs each episode: give 'episodes'",
}


def check_oracle(params: dict[str, Any]) -> None:
    """An oracle trial: episode counts, search iterations, a valid env that leaves the trial's
    own arguments alone, and an episode long enough for the metrics."""

    settings, env = _oracle_settings(params)
    for key in env:
        if key in _ORACLE_OWN_ENV:
            raise ValueError(f"env.{key}: the oracle trial sets it; {_ORACLE_OWN_ENV[key]}")
    _number(settings["episodes"], "episodes", 1, integer=True)
    _number(settings["episode_seed"], "episode_seed", 0, integer=True)
    _number(settings["episode_length_s"], "episode_length_s")  # > 0: below
    _number(settings["max_iter"], "max_iter", 1, integer=True)
    config = _env_config_at(
        {"guideway_seed": EVALUATION_GUIDEWAY_SEED, **env}, settings["episode_length_s"]
    )
    check_episode_length(settings["episode_length_s"], config.dt_s, "episode_length_s")


def run_oracle(trial: Trial) -> dict[str, Any]:
    """``clairvoyant_bound(env_kwargs, seeds, episode_length_s, max_iter=...)``: the mean
    Wk-weighted RMS body acceleration it reaches, how much it depends on the start and what
    the restarts added (:class:`capsule_env.oracle.OracleResult`), and the search's time."""
    settings, env = _oracle_settings(trial.params)
    first = settings["episode_seed"]
    seeds = list(range(first, first + settings["episodes"]))
    result = clairvoyant_bound(env, seeds, float(settings["episode_length_s"]),
                               max_iter=int(settings["max_iter"]))  # fmt: skip
    summary = result.summary()
    return {
        SUMMARY_METRIC: summary["wk_oracle_mean_m_s2"],
        "spread_over_starts_mean_m_s2": summary["spread_over_starts_mean_m_s2"],
        "restart_gain_mean_m_s2": summary["restart_gain_mean_m_s2"],
        "search_time_s": summary["total_time_s"],
    }


register_kind(Kind("train", run_train, _train_keys,
                   {"hp.": "a hyperparameter file entry", "env.": "an env argument"},
                   check_train, seeded=True, unavailable=_train_unavailable,
                   resolve=resolve_train))  # fmt: skip
register_kind(Kind("gains", run_gains, _GAINS_KEYS,
                   {"gain.": "a gain of the controller", "env.": "an env argument"},
                   check_gains))  # fmt: skip
register_kind(Kind("oracle", run_oracle, _ORACLE_KEYS, {"env.": "an env argument"},
                   check_oracle))  # fmt: skip


def json_ready(value: Any) -> bool:
    """True if ``value`` survives JSON (study parameters travel as JSON and Tune configs)."""
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        return False
    return True
