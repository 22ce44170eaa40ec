"""The condition an evaluation runs in: ``evaluate.py --task ID`` and ``--env KEY=VALUE``.

An evaluation's env options come from, in order (each over the one before):

1. the registered task ``--task ID`` (its env kwargs read from Gymnasium's registration,
   :mod:`capsule_env.tasks`; none without ``--task``);
2. ``--setting`` and ``--episode-length`` when given on the command line;
3. the ``--env KEY=VALUE`` items (any :class:`~capsule_env.engine.config.EnvConfig` option, read as
   ``train.py`` reads them: :func:`capsule_env.common.cli.parse_env_item`); an item naming
   ``setting`` or ``episode_length_s`` that contradicts ``--setting`` /
   ``--episode-length`` given too is refused.

Without ``--task`` and without a setting from ``--setting`` or ``--env`` both settings are
run (the paper's two tables); with ``--task`` its setting (the env's default, ``sim``, when
the task names none). Every controller runs on these options, except those it declares itself
(:attr:`capsule_env.agents.controllers.base.Controller.env_kwargs`: what it reads and how it acts, e.g. the
passive row's ``damper="passive"``, a law's ``observation`` and ``inverse_model``, a policy's
training options): a controller keeps its own value, and the results say so
(:func:`controller_env`). A controller whose gains were tuned (``agents/controllers/tuned_gains.json``)
keeps them; :func:`tuned_condition_changes` names the options in which the evaluated env
differs from the one they were tuned in.

Nothing here lists the env's options by hand: they are the fields of ``EnvConfig``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from dataclasses import dataclass, field
from typing import Any

from capsule_env.common.cli import parse_env_item
from capsule_env.engine.config import SETTINGS, EnvConfig
from capsule_env.evaluation.episodes import check_episode_length
from capsule_env.tasks import DECLARED_TASKS, TASKS

__all__ = [
    "Condition",
    "EpisodeLengthError",
    "build_condition",
    "config_at_length",
    "task_env_kwargs",
    "controller_env",
    "tuned_condition_changes",
    "plant_physics",
    "physics_changes",
    "format_options",
    "headline",
    "table_notes",
]

#: The options an evaluation chooses for every controller and compares across conditions
#: only by design: the guideway bank and the episode length.
EVALUATION_CHOSEN = ("guideway_seed", "episode_length_s")
#: Both of the paper's settings, run when nothing names one.
BOTH_SETTINGS = ("sim", "hils")
#: Longest name of a ``--plots`` sub-folder before it is shortened with a digest.
MAX_LABEL_CHARS = 100


@dataclass(frozen=True)
class Condition:
    """The evaluated env options, resolved from ``--task``, ``--setting``,
    ``--episode-length`` and ``--env``.

    Attributes
    ----------
    task : the registered task id, or None (``CapsuleSuspension-v0`` with its defaults).
    task_env_kwargs : the task's registered env kwargs (``{}`` without a task).
    env_overrides : the ``--env`` items, ``{KEY: VALUE}`` in command-line order (a later
        item of the same KEY replaces an earlier one).
    settings : the settings to run, one table each.
    episode_length_s : seconds per episode.
    env_kwargs : every other option set for all controllers: the task's kwargs and the
        ``--env`` items over them, without ``setting`` and ``episode_length_s``.
    """

    task: str | None
    task_env_kwargs: dict[str, Any] = field(default_factory=dict)
    env_overrides: dict[str, Any] = field(default_factory=dict)
    settings: tuple[str, ...] = BOTH_SETTINGS
    episode_length_s: float = 10.0
    env_kwargs: dict[str, Any] = field(default_factory=dict)

    @property
    def is_default(self) -> bool:
        """True for the paper's run: no ``--task`` and no ``--env`` item."""
        return self.task is None and not self.env_overrides

    def label(self) -> str | None:
        """The ``--plots`` sub-folder of a non-default condition (None for the paper's run):
        the task id (``CapsuleSuspension-v0`` without one), then ``+KEY=VALUE`` per ``--env``
        item; characters other than letters, digits and ``._=+-`` become ``_``, and a name
        over :data:`MAX_LABEL_CHARS` is cut and ends with a digest of the whole."""
        if self.is_default:
            return None
        parts = [self.task or "CapsuleSuspension-v0"]
        parts += [f"{k}={_compact(v)}" for k, v in self.env_overrides.items()]
        label = re.sub(r"[^A-Za-z0-9._=+-]", "_", "+".join(parts))
        if len(label) > MAX_LABEL_CHARS:
            digest = hashlib.sha256(label.encode()).hexdigest()[:12]
            label = f"{label[: MAX_LABEL_CHARS - 13]}-{digest}"
        return label

    def describe(self) -> dict[str, Any]:
        """The JSON's ``condition`` entry (what the result file was run in)."""
        return {
            "task": self.task,
            "task_env_kwargs": dict(self.task_env_kwargs),
            "env_overrides": dict(self.env_overrides),
            "env_kwargs": dict(self.env_kwargs),
            "settings": list(self.settings),
            "episode_length_s": self.episode_length_s,
        }


def _compact(value: Any) -> str:
    """``value`` as a short text: a string as it is, anything else as compact JSON."""
    if isinstance(value, str):
        return value
    try:
        return json.dumps(value, separators=(",", ":"), sort_keys=True)
    except (TypeError, ValueError):
        return repr(value)


def format_options(options: dict[str, Any]) -> str:
    """``KEY=VALUE, ...`` with each value's ``repr`` (``setting='hils', speed_kmh=400``)."""
    return ", ".join(f"{k}={v!r}" for k, v in options.items())


def task_env_kwargs(task_id: str) -> dict[str, Any]:
    """The env kwargs ``task_id`` is registered with (Gymnasium's registry); ``ValueError``
    listing the registered task ids when it is not one of :data:`capsule_env.tasks.TASKS`."""
    from gymnasium.envs.registration import registry

    import capsule_env  # noqa: F401  (registers the tasks)

    ids = [task.env_id for task in TASKS]
    if task_id not in ids or task_id not in registry:
        raise ValueError(f"--task must be one of {', '.join(ids)}, got {task_id!r}")
    return dict(registry[task_id].kwargs or {})


def _env_items(items: list[str]) -> dict[str, Any]:
    """The ``--env`` items as ``{KEY: VALUE}``; ``ValueError`` for an item without ``=`` or
    a KEY that is not an env option (the message lists the options)."""
    known = {f.name for f in dataclasses.fields(EnvConfig)}
    overrides: dict[str, Any] = {}
    for item in items:
        key, value = parse_env_item(item)
        if key not in known:
            raise ValueError(f"--env {item!r}: {key!r} is not an env option; accepted: "
                             f"{', '.join(sorted(known))}")  # fmt: skip
        overrides[key] = value
    return overrides


def _pick(name: str, overrides: dict, given: Any, option: str, task_kwargs: dict) -> Any:
    """The value of ``name``: the ``--env`` item, else the ``option`` given on the command
    line (``given``, None when not given), else the task's; None when none says.
    ``ValueError`` when the ``--env`` item and the option both say, differently."""
    if name in overrides:
        if given is not None and given != overrides[name]:
            raise ValueError(f"--env {name}={overrides[name]!r} contradicts {option} {given!r}: "
                             "give one of them")  # fmt: skip
        return overrides[name]
    if given is not None:
        return given
    return task_kwargs.get(name)


def build_condition(
    task: str | None, env_items: list[str], setting: str | None, episode_length_s: float | None
) -> Condition:
    """The :class:`Condition` of the command line: ``--task`` (None: none), the ``--env``
    items, ``--setting`` (``"sim"``, ``"hils"``, ``"both"``; None when not given) and
    ``--episode-length`` (None when not given). Checks every option with
    :class:`~capsule_env.engine.config.EnvConfig` in each setting; raises ``ValueError`` (or
    ``TypeError``) naming the option and what it accepts."""
    known = [t.env_id for t in TASKS + DECLARED_TASKS]  # evaluate.py runs the declared ones
    if task is not None and task not in known:
        raise ValueError(f"--task must be one of {', '.join(known)}, got {task!r}")
    task_kwargs = task_env_kwargs(task) if task is not None else {}
    overrides = _env_items(env_items)
    if overrides.get("setting") == "both":  # --setting's word, not an env option
        raise ValueError(f"--env setting must be one of {', '.join(SETTINGS)} (--setting both "
                         "runs both), got 'both'")  # fmt: skip
    defaults = {f.name: f.default for f in dataclasses.fields(EnvConfig)}
    setting = _pick("setting", overrides, setting, "--setting", task_kwargs)
    if setting == "both":
        settings: tuple[str, ...] = BOTH_SETTINGS
    elif setting is not None:
        settings = (setting,)
    else:
        settings = BOTH_SETTINGS if task is None else (defaults["setting"],)
    task_setting = task_kwargs.get("setting", defaults["setting"])
    if (
        task is not None
        and setting is not None
        and "setting" not in overrides
        and setting != task_setting
    ):
        # --setting over a task's own: a change of the task, named as one (issue 40: the
        # header and the --plots folder named the bare task)
        overrides = {**overrides, "setting": setting}
    length = _pick("episode_length_s", overrides, episode_length_s, "--episode-length",
                   task_kwargs)  # fmt: skip
    length = defaults["episode_length_s"] if length is None else length
    merged = {**task_kwargs, **overrides}
    env_kwargs = {k: v for k, v in merged.items() if k not in ("setting", "episode_length_s")}
    where = "--env" if task is None else f"--task {task} / --env"
    if "episode_length_s" in overrides:
        label = "--env episode_length_s"
    elif "episode_length_s" in task_kwargs and episode_length_s is None:
        label = f"--task {task}'s episode_length_s"
    else:
        label = "--episode-length"
    for one in settings:
        try:
            config = config_at_length({**env_kwargs, "setting": one}, length, label)
        except EpisodeLengthError:
            raise
        except (ValueError, TypeError) as exc:
            raise type(exc)(f"{where}: {exc}") from None
        if label != "--episode-length":  # --episode-length: checked with the controllers
            check_episode_length(length, config.dt_s, label)
    return Condition(task, task_kwargs, overrides, settings, float(length), env_kwargs)


class EpisodeLengthError(ValueError):
    """An episode length the metrics or the env refuse (its message names where it came
    from)."""


def config_at_length(env_kwargs: dict[str, Any], length_s: float, label: str) -> EnvConfig:
    """The :class:`EnvConfig` of ``env_kwargs`` with episodes of ``length_s`` seconds (what
    the run builds: a trip shorter than the default episode is valid at its own length).
    Where that is refused and the options alone are valid, the length's own check
    (:func:`~capsule_env.evaluation.episodes.check_episode_length`, naming ``label``) speaks first:
    :class:`EpisodeLengthError`; otherwise the env's error."""
    try:
        return EnvConfig.from_kwargs(**env_kwargs, episode_length_s=length_s)
    except (ValueError, TypeError) as exc:
        error = exc
    try:
        alone = EnvConfig.from_kwargs(**env_kwargs)
    except (ValueError, TypeError):
        raise error from None
    try:
        check_episode_length(length_s, alone.dt_s, label)
    except ValueError as exc:
        raise EpisodeLengthError(str(exc)) from None
    raise error


def controller_env(
    condition_kwargs: dict[str, Any],
    own: dict[str, Any],
    setting: str,
    episode_length_s: float | None = None,
) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """A controller's env options in ``setting``: the condition's (``condition_kwargs``) with
    the controller's own (``own``, :attr:`Controller.env_kwargs`) over them, and the options
    where the controller's own value replaced another of the condition's, or one the condition
    left at the env's default that changes the plant's physics (:func:`plant_physics`; e.g. a
    law made for trips run on a constant-speed task), ``{KEY: {"controller": own value,
    "condition": the condition's value, or the env's default}}``; ``episode_length_s``: the
    run's episode length (default the condition's or the env's)."""
    kept = {
        key: {"controller": own[key], "condition": value}
        for key, value in condition_kwargs.items()
        if key in own and _as_tuple(own[key]) != _as_tuple(value)
    }
    base = {**condition_kwargs, "setting": setting}
    added = {key: value for key, value in own.items() if key not in base}
    try:  # a condition the env refuses is refused where it is built, with its own message
        changing = _physics_keys(base, added, episode_length_s) if added else {}
    except (ValueError, TypeError):
        changing = {}
    defaults = _env_defaults()
    kept.update({key: {"controller": own[key], "condition": defaults.get(key)} for key in changing})
    return {**condition_kwargs, **own, "setting": setting}, kept


def _as_tuple(value: Any) -> Any:
    """A list as a tuple (a policy's options read back from JSON have lists for tuples)."""
    return tuple(value) if isinstance(value, list) else value


def tuned_condition_changes(
    env_kwargs: dict[str, Any], own: dict[str, Any], tuning: dict[str, Any]
) -> dict[str, dict[str, Any]]:
    """The options in which the env a tuned controller is evaluated in (``env_kwargs``)
    differs from the env its gains were tuned in (``tuning``, e.g. ``{"setting": "hils"}``:
    ``capsule_env.agents.controllers.tuned.tuning_env_kwargs``, with the controller's own options
    ``own`` over it), compared as whole :class:`EnvConfig` values (defaults included), the
    guideway bank and the episode length left out: ``{KEY: {"tuned": value, "evaluated":
    value}}``."""
    tuned = dataclasses.asdict(EnvConfig.from_kwargs(**{**tuning, **own}))
    evaluated = dataclasses.asdict(EnvConfig.from_kwargs(**env_kwargs))
    return {
        key: {"tuned": tuned[key], "evaluated": value}
        for key, value in evaluated.items()
        if key not in EVALUATION_CHOSEN and tuned[key] != value
    }


def plant_physics(env_kwargs: dict[str, Any], episode_length_s: float | None = None) -> str:
    """What the plant of ``env_kwargs`` is and meets, resolved (defaults filled in, so that an
    option given at its default value changes nothing): the speeds, the envelope (levitation,
    trip, spans), the vehicle and its randomisation and payload, the guideway (its kind,
    parameters, bank seed and size) and the bump stop. Not what a controller reads or how it
    acts (observation, noise, delay, inverse model, force limit, control rate), nor the
    damper, the controller's actuator (the passive row's ``damper="passive"``; in ``sim`` the
    plant's damper is the inverse model's: compare ``EnvConfig.plant_damper_name`` where that
    matters). A text to compare (``repr`` of the resolved values); ``ValueError`` or
    ``TypeError`` for options the env refuses."""
    from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED

    kwargs = {"guideway_seed": EVALUATION_GUIDEWAY_SEED, **env_kwargs}
    if episode_length_s is not None:
        kwargs["episode_length_s"] = episode_length_s
    c = EnvConfig.from_kwargs(**kwargs)
    payload = None if c.payload_range is None else tuple(c.payload_range)
    return repr((c.speed_range_mps, c.envelope, c.vehicle, c.vehicle_randomization, payload,
                 c.guideway_spec, c.guideway_seed, c.guideway_bank_size,
                 c.stroke_limit_m))  # fmt: skip


def _env_defaults() -> dict[str, Any]:
    """Every env option's default value (the guideway bank: the evaluation bank)."""
    from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED

    defaults = {f.name: f.default if f.default_factory is dataclasses.MISSING
                else f.default_factory() for f in dataclasses.fields(EnvConfig)}  # fmt: skip
    defaults["guideway_seed"] = EVALUATION_GUIDEWAY_SEED
    return defaults


def _physics_keys(
    base: dict[str, Any], own: dict[str, Any], episode_length_s: float | None
) -> dict[str, str]:
    """The keys of ``own`` that, each set alone over ``base``, change its
    :func:`plant_physics`, with ``""`` or the refusal's message where ``base`` does not accept
    it (``base`` itself must be accepted)."""
    reference = plant_physics(base, episode_length_s)
    keys = {}
    for key in own:
        try:
            if plant_physics({**base, key: own[key]}, episode_length_s) != reference:
                keys[key] = ""
        except (ValueError, TypeError) as exc:
            keys[key] = str(exc)
    return keys


def physics_changes(
    base: dict[str, Any],
    own: dict[str, Any],
    episode_length_s: float | None = None,
    base_label: str = "the condition",
) -> list[str]:
    """The options of ``own`` (a controller's :attr:`Controller.env_kwargs`) that change the
    plant's physics (:func:`plant_physics`) when set over ``base`` (the condition's options,
    a ``setting`` included; ``own``'s ``setting`` is not one: the evaluation sets it), each
    as ``"KEY=value (<base_label>: its value there)"``, with ``"; refused there: ..."`` where
    ``base`` does not accept it; ``[]`` when ``{**base, **own}`` has ``base``'s physics
    (options that only say what a controller reads and how it acts never count). Options
    that change it only together are named together."""
    defaults = _env_defaults()
    own = {k: v for k, v in own.items() if k != "setting"}
    reference = plant_physics(base, episode_length_s)

    def describe(key: str, why: str = "") -> str:
        there = base.get(key, defaults.get(key))
        return f"{key}={own[key]!r} ({base_label}: {there!r}{why})"

    changed = [describe(key, f"; refused there: {refusal}" if refusal else "")
               for key, refusal in _physics_keys(base, own, episode_length_s).items()]  # fmt: skip
    if not changed:
        try:
            together = plant_physics({**base, **own}, episode_length_s) != reference
        except (ValueError, TypeError) as exc:
            return [f"{format_options(own)} (refused by {base_label}: {exc})"]
        if together:
            changed = [describe(key) for key in own]
    return changed


# ----------------------------------------------------------------------------- the tables' notes
def headline(results: dict[str, Any]) -> str | None:
    """The tables' line naming the task and the ``--env`` items of ``results`` (None for the
    paper's run, or results without a ``condition``)."""
    described = results.get("condition")
    if not described or (described["task"] is None and not described["env_overrides"]):
        return None
    task = described["task"] or "CapsuleSuspension-v0 (no --task)"
    if described["task_env_kwargs"]:
        task += f" [{format_options(described['task_env_kwargs'])}]"
    env = format_options(described["env_overrides"]) if described["env_overrides"] else "none"
    return (f"evaluated env: task {task}; overrides (--env, --setting): {env}; episode "
            f"{described['episode_length_s']:g} s. Each controller keeps the options it "
            "declares itself (JSON: env_kwargs, own_options_kept).")  # fmt: skip


def table_notes(controllers: dict[str, dict[str, Any]], tuning: dict[str, Any]) -> list[str]:
    """One setting's notes under its title: the options some controllers kept over the
    evaluated env's (``own_options_kept``), and where the env differs from the one the tuned
    gains were tuned in (``tuning``; the rows' ``tuned_condition_differs``); ``[]`` when
    neither applies."""
    notes = []
    kept: dict[tuple[str, str], list[str]] = {}
    for name, entry in controllers.items():
        for key, values in entry.get("own_options_kept", {}).items():
            kept.setdefault((key, repr(values["controller"])), []).append(name)
    if kept:
        notes.append("own options kept over the evaluated env's: " + "; ".join(
            f"{key}={value} ({', '.join(names)})" for (key, value), names in kept.items()))  # fmt: skip
    differs: dict[str, dict[str, Any]] = {}
    for entry in controllers.values():
        for key, values in entry.get("tuned_condition_differs", {}).items():
            differs.setdefault(key, values)
    if differs:
        where = format_options(tuning) or "the env's defaults"
        notes.append(
            f"note: the tuned gains (agents/controllers/tuned_gains.json) were tuned at {where} (other "
            "options the env's defaults) and are kept as shipped; this table's env differs in "
            + ", ".join(
                f"{k}={v['evaluated']!r} (tuned: {v['tuned']!r})" for k, v in differs.items()
            )  # fmt: skip
        )
    return notes
