"""Reproduce the paper's vibration-reduction comparison and compare any controller with it.

    python evaluate.py                          # both settings, the default controllers
    python evaluate.py --setting hils --episodes 20 --json out/eval.json --plots out/plots
    python evaluate.py --policy runs/ppo/best_model.zip   # add a trained SB3 policy
    python evaluate.py --task CapsuleRide-v0              # on a registered task
    python evaluate.py --setting hils --env speed_kmh=400 --env vehicle_params='{"car_body_mass_kg": 8400}'

Read top to bottom: arguments; controllers; the checks made before anything runs; for each
setting the passive run and every controller on the same guideway seeds; metrics; the tables
(Tables 5 and 6 analogues, :mod:`capsule_env.evaluation.tables`) with the paper's published
figures beside ours; optional JSON and figures.

Policy rows are named by the policy's metadata ``name`` (its file stem without a ``.json``);
when that name is taken (by a classical controller or an earlier ``--policy``), ``#2``, ``#3``
... is appended in command-line order, and the table's footer lists each policy row's file.
Bad arguments or files (a missing, empty, corrupt or mismatched policy, a policy without its
``.vecnormalize.pkl`` unless ``--allow-unnormalized``, an episode too short for the spectra,
an unwritable ``--json``/``--plots`` path) stop the script before the run with one line on
stderr and exit status 1 (2 for argument syntax, an unknown ``--task`` and a bad ``--env``).

``--task ID`` and ``--env KEY=VALUE`` set the evaluated env (:mod:`capsule_env.evaluation.condition`
says how they combine with ``--setting``, ``--episode-length`` and each controller's own
options); the tables and the JSON (``condition``) name them, and ``--plots DIR`` then writes
into the sub-folder ``DIR/<task>+KEY=VALUE...`` so that the paper run's figures stay.

``--task CapsuleHalfRide-v0`` (a declared vehicle, two dampers) runs the half-car's own
evaluation (:mod:`capsule_env.evaluation.half_car`: its laws, its shipped policy, ``--oracle``
the declared oracle) and writes the same JSON layout, the headline ``wk_rms_body_acc_m_s2``
the floor's mean over its front, centre and rear; ``--task CapsuleHalfRidePreview-v0`` the
same rows and the survey-preview LQ's (:mod:`capsule_env.evaluation.half_car_preview`). They
take ``--episodes``, ``--seed``, ``--oracle``, ``--no-shipped-policy`` and ``--json``, and
refuse any other option in one line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.agents import classical_controllers
from capsule_env.agents.controllers.tuned import tuning_env_kwargs, tuning_task_kwargs
from capsule_env.agents.learning.policy_files import shown_path
from capsule_env.common.cli import ArgumentParser, exits_on_interrupt, nonempty_path
from capsule_env.common.safe_io import atomic_write_text, check_writable_dir, check_writable_file
from capsule_env.engine.config import EnvConfig
from capsule_env.evaluation.condition import (
    Condition,
    EpisodeLengthError,
    build_condition,
    config_at_length,
    controller_env,
    physics_changes,
    tuned_condition_changes,
)
from capsule_env.evaluation.episodes import check_episode_length, episode_metrics, run_episodes
from capsule_env.evaluation.floor_block import add_floor, check_floor_settings
from capsule_env.evaluation.tables import format_markdown, format_tables, group_of  # noqa: F401
from capsule_env.metrics import DEFAULT_BANDS_HZ
from capsule_env.tasks import DECLARED_TASKS, TASKS, task_named
from capsule_env.vehicles.modes import natural_frequencies_hz

PAPER_CONTROLLERS = ["passive", "skyhook-csdc", "skyhook-biexp"]
#: The default run: the paper's rows, the open-loop references, the classical laws on ideal
#: sensors (``full_state``) and the same laws on measured signals (``-meas``).
DEFAULT_CONTROLLERS = PAPER_CONTROLLERS + [
    "mr-0A",
    "mr-imax",
    "skyhook-tanh",
    "skyhook-cont-biexp",
    "hybrid-biexp",
    "lqr-clipped-biexp",
    "skyhook-meas",
    "skyhook-cont-biexp-meas",
    "hybrid-biexp-meas",
    "add-meas",
    "sh-add-meas",
    "lqr-clipped-biexp-meas",
    "preview-lq-biexp-meas",
    "preview-lq-biexp",
    "mpc-biexp-meas",
    "preview-mpc-biexp-meas",
    "mpc-biexp",
    "preview-mpc-biexp",
]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (syntax only; :func:`check_args` checks the values)."""
    p = ArgumentParser(
        prog="evaluate.py", description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    p.add_argument("--setting", choices=["sim", "hils", "both"], default=None,
                   help="sim: plant damper = inverted model; hils: reference damper with coil "
                   "lag, noise, delay (default: the --task's or --env's setting, else both)")  # fmt: skip
    p.add_argument("--task", metavar="ID",
                   help="evaluate on a registered task (capsule_env.tasks: "
                   + ", ".join(t.env_id for t in TASKS + DECLARED_TASKS) + "): its env options, "
                   "its setting (a declared vehicle's task: its own evaluation, "
                   "capsule_env.evaluation.half_car, half_car_preview)")  # fmt: skip
    p.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                   help="one env option of the evaluated env (VALUE JSON or a Python literal, "
                   "a bare word a string; over the --task's), repeatable, as train.py's: "
                   "--env speed_kmh=400 --env setting=hils")  # fmt: skip
    p.add_argument("--controllers", default=",".join(DEFAULT_CONTROLLERS),
                   help="comma-separated controller names, or 'all' (classical: "
                   + ", ".join(classical_controllers()) + ")")  # fmt: skip
    p.add_argument("--policy", action="append", default=[], metavar="PATH",
                   help="a saved SB3 model (.zip; its .vecnormalize.pkl statistics next to it "
                   "are required and loaded); repeatable")  # fmt: skip
    p.add_argument("--allow-unnormalized", action="store_true",
                   help="run a --policy without its .vecnormalize.pkl on raw observations "
                   "(usually far worse than it was in training)")  # fmt: skip
    p.add_argument(
        "--no-shipped-policy",
        action="store_true",
        help="do not add the pretrained policies shipped with the package (those trained in the evaluated physics whose observation fits)",
    )
    p.add_argument(
        "--episodes",
        type=int,
        default=10,
        help="guideway seeds per controller (>= 1; >= 2 with a half-car task)",
    )
    p.add_argument("--seed", type=int, default=1000, help="first episode seed (>= 0)")
    p.add_argument("--episode-length", type=float, default=None,
                   help="seconds per episode (default: the --task's or --env's "
                   "episode_length_s, else 10; at least 0.335 s at the default 200 Hz "
                   "control rate: the spectra need a line in each mode band)")  # fmt: skip
    p.add_argument("--oracle", action="store_true",
                   help="also run the clairvoyant search (capsule_env.oracle: a multi-start "
                   "local search knowing the guideway; a reference, not a proven limit) on the "
                   "same episodes: an 'oracle' row per setting and each controller's share of the "
                   "headroom passive -> oracle (slow: a few minutes per setting)")  # fmt: skip
    p.add_argument("--floor", type=int, nargs="?", const=0, default=None, metavar="NODES",
                   help="also compute the certified floor (capsule_env.bounds: a proven lower "
                   "bound on every controller's Wk on the same episodes) per setting: a 'floor' "
                   "block; the sim plant only, episodes of <= about 2.2 s; slow (minutes per "
                   "episode); --floor NODES also branches on the stroke rate's sign")  # fmt: skip
    p.add_argument("--json", type=nonempty_path, help="write all results to this JSON file")
    p.add_argument("--plots", type=nonempty_path, help="write figures (PNG) to this folder (with "
                   "--task or --env: to its sub-folder named after them)")  # fmt: skip
    args = p.parse_args(argv)
    if args.task in {t.env_id for t in DECLARED_TASKS}:  # its own evaluation (main)
        if args.floor is not None:
            p.error(f"--floor is not supported with --task {args.task}: the certified floor "
                    "covers the quarter-car's sim plant (docs/fair-comparison.md)")  # fmt: skip
        args.condition = None
        return args
    try:  # the evaluated env: --task, --setting, --episode-length, --env (eval_condition.py)
        args.condition = build_condition(args.task, args.env, args.setting, args.episode_length)
    except (ValueError, TypeError) as exc:
        p.error(str(exc))
    args.episode_length = args.condition.episode_length_s
    return args


def check_args(args: argparse.Namespace) -> None:
    """Check the values before anything runs (the output paths: :func:`check_outputs`, last);
    raises ``ValueError`` naming the option."""
    if args.episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    last = 2**63 - args.episodes  # episode k uses seed + k, an int64 of the kernels
    if not 0 <= args.seed <= last:
        raise ValueError(f"--seed must be in 0..{last} (2**63 - --episodes: episode k uses "
                         f"seed + k, a 64-bit seed), got {args.seed}")  # fmt: skip
    if not [n for n in args.controllers.split(",") if n.strip()]:
        raise ValueError(f"--controllers names no controller (got {args.controllers!r}): give "
                         "comma-separated names, or 'all'")  # fmt: skip
    if getattr(args, "floor", None) is not None:
        condition, seeds = _condition(args), range(args.seed, args.seed + args.episodes)
        check_floor_settings(condition.env_kwargs, condition.settings, seeds, args.episode_length,
                             args.floor)  # fmt: skip


def check_outputs(args: argparse.Namespace) -> None:
    """Check that the ``--json``/``--plots`` paths can be written (creating their folders):
    the last check before the run, so that a refused run creates nothing."""
    if args.json is not None:
        check_writable_file(args.json, "--json")
    if args.plots is not None:
        check_writable_dir(plots_dir(args), "--plots")


def plots_dir(args: argparse.Namespace) -> Path:
    """The folder of the figures: ``--plots``, or its sub-folder named by the condition
    (:meth:`capsule_env.evaluation.condition.Condition.label`) with ``--task`` or ``--env``."""
    label = _condition(args).label()
    return args.plots if label is None else args.plots / label


def _condition(args: argparse.Namespace) -> Condition:
    """The evaluated env of ``args`` (a namespace built by hand: ``--setting`` and
    ``--episode-length`` alone, as before ``--task``/``--env``)."""
    condition = getattr(args, "condition", None)
    if condition is None:
        condition = build_condition(None, [], getattr(args, "setting", None),
                                    getattr(args, "episode_length", None))  # fmt: skip
    return condition


def unique_name(name: str, taken: dict | set) -> str:
    """``name``, or ``name#2``, ``name#3`` ... the first one not in ``taken``."""
    if name not in taken:
        return name
    k = 2
    while f"{name}#{k}" in taken:
        k += 1
    return f"{name}#{k}"


def build_controllers(
    names: list[str],
    policies: list[str],
    shipped: bool,
    allow_unnormalized: bool = False,
    env_kwargs: dict | None = None,
) -> dict:
    """The named classical controllers (passive always first) and the policies loaded from
    ``policies`` (after the shipped ones when ``shipped``: those that belong in the evaluation
    of the env options ``env_kwargs``, ``{}`` the paper's env,
    :func:`capsule_env.agents.learning.sb3_policy.fits_condition`), each under a unique name
    (:func:`unique_name`). Raises ``ValueError`` for an unknown name or a bad policy file."""
    available = classical_controllers()
    # not named one by one: 'all', or the default run (with a task's own laws after it)
    implicit = names == ["all"] or names[: len(DEFAULT_CONTROLLERS)] == DEFAULT_CONTROLLERS
    if names == ["all"]:
        names = list(available)
    unknown = [n for n in names if n not in available]
    if unknown:
        raise ValueError(
            f"unknown controller(s) {unknown}; accepted: {', '.join(available)} or 'all'"
        )
    names = _without_missing_solver(names, implicit)
    ctrls = {n: available[n] for n in names}
    if "passive" not in ctrls:
        ctrls = {"passive": available["passive"], **ctrls}  # VRE needs the passive run
    paths = list(policies)
    if shipped:
        from capsule_env.agents.learning.sb3_policy import runnable, shipped_policy_paths

        kept, left_out = runnable(shipped_policy_paths(env_kwargs or {}))
        for name, law in left_out.items():  # as the MPC rows: the default run goes on
            print(f"evaluate.py: warning: {name} left out: its law {law} needs DAQP "
                  "(pip install 'capsule-env[mpc]')", file=sys.stderr)  # fmt: skip
        paths = kept + paths
    if paths:
        from capsule_env.agents.learning.sb3_policy import use_one_torch_thread

        use_one_torch_thread()
    for path in paths:
        from capsule_env.agents.learning.sb3_policy import load_policy

        policy = load_policy(path, require_normalization=not allow_unnormalized)
        if getattr(policy, "obs_rms", None) is None:
            print(f"evaluate.py: warning: {path} runs on raw observations (no normalisation "
                  "statistics)", file=sys.stderr)  # fmt: skip
        policy.name = unique_name(str(policy.name), ctrls)
        ctrls[policy.name] = policy
    return ctrls


def _without_missing_solver(names: list[str], implicit: bool) -> list[str]:
    """``names`` without the MPC rows when their QP solver (DAQP, the ``mpc`` extra) is not
    installed: dropped
    from the default run and from ``all`` (``implicit``) with a warning, refused when named."""
    from capsule_env.agents.controllers.mpc_solver import solver_available

    mpc = [n for n in names if "mpc" in n.split("-")]
    if not mpc or solver_available():
        return names
    if not implicit:
        raise ValueError(f"{', '.join(mpc)} need a QP solver: pip install 'capsule-env[mpc]'")
    print(f"evaluate.py: warning: {', '.join(mpc)} left out: DAQP is not installed "
          "(pip install 'capsule-env[mpc]')", file=sys.stderr)  # fmt: skip
    return [n for n in names if n not in mpc]


def check_controllers(
    ctrls: dict, settings: list[str], episode_length_s: float, env_kwargs: dict | None = None
) -> None:
    """Before the run: each controller's env arguments (its own over the evaluated env's
    ``env_kwargs``, :func:`capsule_env.evaluation.condition.controller_env`) are valid in each
    setting, the episode is long enough for the metrics at its control rate, and each
    policy's observation and action sizes are the env's. Raises ``ValueError`` naming the
    controller (and file)."""
    for name, ctrl in ctrls.items():
        where = f"{name} ({ctrl.path})" if getattr(ctrl, "path", None) else name
        for setting in settings:
            env, _ = controller_env(env_kwargs or {}, ctrl.env_kwargs, setting, episode_length_s)
            try:
                config = config_at_length(env, episode_length_s, "--episode-length")
            except EpisodeLengthError:
                raise
            except (ValueError, TypeError) as exc:
                raise ValueError(f"{where}: bad env arguments {env}: {exc}") from None
            check_episode_length(episode_length_s, config.dt_s, "--episode-length")
            model = getattr(ctrl, "model", None)
            if model is None:
                continue
            obs_size = (len(config.observation_names),)
            if tuple(model.observation_space.shape) != obs_size:
                raise ValueError(
                    f"{where} takes observations of shape {tuple(model.observation_space.shape)}"
                    f", but its env ({config.observation!r} observation) gives {obs_size}: the "
                    "policy was trained on another observation set"
                )
            if tuple(model.action_space.shape) != (1,):
                raise ValueError(
                    f"{where} gives actions of shape {tuple(model.action_space.shape)}, the "
                    "env takes (1,)"
                )


def prepare(args: argparse.Namespace) -> dict:
    """Every check made before the run (:func:`check_args`, :func:`build_controllers`,
    :func:`check_controllers`, :func:`check_outputs`); returns the controllers."""
    check_args(args)
    names = [n.strip() for n in args.controllers.split(",") if n.strip()]
    condition = _condition(args)
    if names == DEFAULT_CONTROLLERS and condition.task is not None:  # the task's own laws too
        names += [n for n in task_named(condition.task).own_laws if n not in names]
    ctrls = build_controllers(
        names, args.policy, shipped=not args.no_shipped_policy,
        allow_unnormalized=args.allow_unnormalized, env_kwargs=condition.env_kwargs,
    )  # fmt: skip
    check_controllers(ctrls, list(condition.settings), args.episode_length, condition.env_kwargs)
    check_outputs(args)
    return ctrls


def evaluate(args: argparse.Namespace, ctrls: dict | None = None) -> dict:
    """Run every controller (``ctrls``, default :func:`prepare`'s) in each setting; returns
    the results (metrics per setting and controller, the policies' files)."""
    condition = _condition(args)
    if ctrls is None:
        ctrls = prepare(args)
    results: dict = {
        "condition": condition.describe(),
        "gains_tuned_env_kwargs": tuning_env_kwargs(),
        "natural_frequencies_hz": [float(f) for f in natural_frequencies_hz()],
        "bands_hz": {k: list(v) for k, v in DEFAULT_BANDS_HZ.items()},
        "episodes": args.episodes,
        "seeds": [args.seed, args.seed + args.episodes - 1],
        "policies": {n: shown_path(c.path) for n, c in ctrls.items() if getattr(c, "path", None)},
        "settings": {},
    }
    rollouts: dict = {}
    if not kernels_cached():
        print("evaluate.py: compiling the numba kernels (a first run, or kernels.py changed: "
              "about 30 s before the first row; cached afterwards)", file=sys.stderr)  # fmt: skip
    done, t0 = 0, time.perf_counter()
    total = len(condition.settings) * len(ctrls)
    for setting in condition.settings:
        results["settings"][setting] = {"controllers": {}}
        passive = None
        for name, ctrl in ctrls.items():
            env_kwargs, kept = controller_env(
                condition.env_kwargs, ctrl.env_kwargs, setting, args.episode_length
            )
            roll = run_episodes(ctrl, env_kwargs, args.episodes, args.seed, args.episode_length)
            if name == "passive":
                passive = roll
            rollouts[(setting, name)] = roll
            entry = episode_metrics(roll, passive if name != "passive" else None)
            entry.update(describe(ctrl))
            entry.update(env_kwargs=env_kwargs, own_options_kept=kept)
            if entry["gains_tuned"]:
                tuning = {**results["gains_tuned_env_kwargs"], **tuning_task_kwargs(name)}
                entry["tuned_condition_differs"] = tuned_condition_changes(
                    {**env_kwargs, "episode_length_s": args.episode_length}, ctrl.env_kwargs,
                    tuning,
                )  # fmt: skip
            results["settings"][setting]["controllers"][name] = entry
            done += 1
            _progress(done, total, f"{setting}/{name}", time.perf_counter() - t0)
        if getattr(args, "oracle", False):
            _progress(done, total, f"{setting}/oracle (search)", time.perf_counter() - t0)
            own = {name: rollouts[(setting, name)] for name in ctrls}
            add_oracle(results["settings"][setting], setting, args, passive, ctrls, own)
        if getattr(args, "floor", None) is not None:
            _progress(done, total, f"{setting}/floor (dual)", time.perf_counter() - t0)
            floor_kwargs = {**condition.env_kwargs, "setting": setting}
            add_floor(results["settings"][setting], floor_kwargs,
                      range(args.seed, args.seed + args.episodes), args.episode_length, args.floor)  # fmt: skip
    print(file=sys.stderr)
    if args.plots:
        from capsule_env.plots import evaluation_figures

        evaluation_figures(rollouts, plots_dir(args))
    return results


def add_oracle(block: dict, setting: str, args: argparse.Namespace, passive: Any,
               ctrls: dict, rollouts: dict | None = None) -> None:  # fmt: skip
    """Add the clairvoyant search's row (``"oracle"``, :func:`capsule_env.oracle.clairvoyant_bound`
    on the same episodes) to a setting's results, and to every controller on the same plant
    (the same physics: :func:`~capsule_env.evaluation.condition.physics_changes`, e.g. not a law
    whose own options run it on trips where the oracle's episodes keep one speed) its share
    of the headroom, ``oracle_headroom_captured_rel = (Wk_passive - Wk) /
    (Wk_passive - Wk_oracle)`` (0: passive, 1: the oracle, a local search's best, not a proven
    optimum). In ``sim`` the plant
    is the damper model a controller inverts: the oracle's is the Bi-exponential model, and
    controllers on another plant get no share (passive, the reference, has 0 by definition).

    The applied currents of every controller on the same plant (from ``rollouts``, name ->
    its :class:`~capsule_env.evaluation.episodes.Rollout` on these episodes) are the search's
    ``candidates``: per episode the oracle is never above any of them, and it is searched
    from the best one too (``search.best_starts`` names the start that won each episode)."""
    from capsule_env.oracle import applied_currents, clairvoyant_bound

    seeds = range(args.seed, args.seed + args.episodes)
    condition_kwargs = _condition(args).env_kwargs
    oracle_kwargs = {**condition_kwargs, "setting": setting}
    length = args.episode_length
    same = _same_plant(block["controllers"], ctrls, condition_kwargs, setting, length)
    own = rollouts or {}
    candidates = {name: applied_currents(own[name], d) for name, d in same.items() if name in own}
    result = clairvoyant_bound(oracle_kwargs, seeds, length, candidates=candidates)
    entry = episode_metrics(result.rollout, passive)
    summary = result.summary()
    entry.update({
        "observation": "oracle", "uses_unmeasured_signals": True, "preview": True,
        "gains": {}, "gains_tuned": False,
        "search": {k: v for k, v in summary.items() if k != "env_kwargs"},
    })  # fmt: skip
    controllers = block["controllers"]
    controllers["oracle"] = entry
    wk_passive = controllers["passive"]["wk_rms_body_acc_m_s2"]
    headroom = wk_passive - entry["wk_rms_body_acc_m_s2"]
    for name, m in controllers.items():
        if name in ("oracle", "passive") or name in same:  # passive: the reference, 0
            m["oracle_headroom_captured_rel"] = (
                (wk_passive - m["wk_rms_body_acc_m_s2"]) / headroom if headroom > 0 else None
            )


def _same_plant(
    controllers: dict, ctrls: dict, condition_kwargs: dict, setting: str, length: float
) -> dict[str, int]:
    """The controllers (of ``controllers``, a setting's rows, passive and the oracle left out)
    that run on the oracle's plant and physics, each with its control delay (steps)."""
    oracle_kwargs = {**condition_kwargs, "setting": setting}
    plant = EnvConfig.from_kwargs(**oracle_kwargs, episode_length_s=length).plant_damper_name
    same = {}
    for name in controllers:
        if name in ("oracle", "passive"):
            continue
        ctrl = ctrls.get(name)
        own = ctrl.env_kwargs if ctrl is not None else {}
        env, _ = controller_env(condition_kwargs, own, setting)
        config = EnvConfig.from_kwargs(**env, episode_length_s=length)
        if config.plant_damper_name == plant and not physics_changes(oracle_kwargs, own, length):
            same[name] = config.effective_control_delay_steps
    return same


def describe(ctrl: Any) -> dict[str, Any]:
    """What the JSON says about a controller besides its metrics: the observation set it
    reads, whether that includes unmeasured signals, whether it previews the guideway, its
    gains and whether they are the tuned ones (``agents/controllers/tuned_gains.json``)."""
    return {
        "observation": ctrl.observation,
        "uses_unmeasured_signals": bool(ctrl.uses_unmeasured_signals),
        "preview": bool(ctrl.preview),
        "gains": ctrl.gains(),
        "gains_tuned": bool(getattr(ctrl, "gains_tuned", False)),
    }


def kernels_cached() -> bool:
    """Whether numba's cache holds the env's compiled step for the present source: an index
    file of ``capsule_env.engine.kernels`` not older than ``kernels.py``, in the folder numba's own
    locator caches that module in (the package's ``__pycache__``, ``NUMBA_CACHE_DIR``, the
    user-wide cache of a read-only installation, :mod:`capsule_env._jit`'s fallback). False on
    a first run, which compiles for about half a minute, and after ``kernels.py`` changed
    (numba then compiles again); a cheap test, not numba's own (it also compiles a variant,
    e.g. the trip task's step, the first time it is used)."""
    from capsule_env.engine import kernels

    source = Path(kernels.__file__)
    try:  # numba's locator for the module, as chosen when it was imported
        folder = Path(kernels.env_args._cache._cache_path)
    except AttributeError:  # a numba without these attributes: its default, in-tree
        folder = source.parent / "__pycache__"
    indexes = list(folder.glob("kernels.*.nbi")) if folder.is_dir() else []
    return any(i.stat().st_mtime >= source.stat().st_mtime for i in indexes)


def _progress(done: int, total: int, label: str, elapsed: float) -> None:
    width = 30
    filled = int(width * done / total)
    bar = "#" * filled + "-" * (width - filled)
    sys.stderr.write(f"\r[{bar}] {done}/{total} {label:<28} {elapsed:6.1f} s")
    sys.stderr.flush()


#: The options a declared vehicle's task takes (its evaluation: :mod:`capsule_env.evaluation.half_car`).
DECLARED_OPTIONS = "--episodes (>= 2), --seed, --oracle, --no-shipped-policy and --json"


def _declared_evaluations() -> dict[str, Any]:
    """The declared vehicles' tasks that ``evaluate.py`` evaluates, each with its evaluation's
    module (``evaluation_results``, ``format_rows``, ``ORACLE_ITERATIONS``)."""
    from capsule_env.evaluation import half_car, half_car_preview

    return {half_car.TASK_ID: half_car, half_car_preview.TASK_ID: half_car_preview}


def _declared_refusal(args: argparse.Namespace) -> str:
    """Why ``args`` (``--task`` a declared vehicle's task) cannot run ("" when they can): the
    half-car's evaluations run their own laws and the half-car task's shipped policies on the
    ``hils`` plant, 10 s episodes; the other options of ``evaluate.py`` are refused, each named."""
    evaluated = _declared_evaluations()
    if args.task not in evaluated:
        return (f"evaluate.py does not evaluate {args.task} yet (of the declared vehicles' "
                f"tasks, {' and '.join(evaluated)} only)")  # fmt: skip
    given = {"--setting": args.setting not in (None, "hils"), "--env": bool(args.env),
             "--controllers": args.controllers != ",".join(DEFAULT_CONTROLLERS),
             "--policy": bool(args.policy), "--allow-unnormalized": args.allow_unnormalized,
             "--episode-length": args.episode_length not in (None, 10.0),
             "--plots": args.plots is not None}  # fmt: skip
    refused = [option for option, set_ in given.items() if set_]
    if refused:
        return (f"{', '.join(refused)} not supported with --task {args.task} (its evaluation, "
                f"{evaluated[args.task].__name__}, runs its own laws and shipped policies on the "
                f"hils plant, 10 s episodes); it takes {DECLARED_OPTIONS}")  # fmt: skip
    if args.episodes < 2:
        return (f"--episodes must be >= 2 with --task {args.task} (intervals over the "
                f"episodes), got {args.episodes}")  # fmt: skip
    if not 0 <= args.seed <= 2**63 - args.episodes:
        return f"--seed must be in 0..{2**63 - args.episodes}, got {args.seed}"
    return ""


def _declared_main(args: argparse.Namespace) -> int:
    """``--task`` a declared vehicle's task: its evaluation's rows (``evaluate.py``'s JSON
    layout, the headline ``wk_rms_body_acc_m_s2`` the floor's mean over three points), a
    table on stdout, the JSON with ``--json``. Bad options: one line, exit status 2."""
    problem = _declared_refusal(args)
    try:
        if not problem and args.json is not None:
            check_writable_file(args.json, "--json")
    except (ValueError, OSError) as exc:
        problem = str(exc)
    if problem:
        print(f"evaluate.py: error: {problem}", file=sys.stderr)
        return 2
    evaluation = _declared_evaluations()[args.task]
    options = [f"--task {args.task}", f"--episodes {args.episodes}", f"--seed {args.seed}"]
    options += ["--oracle"] * args.oracle + ["--no-shipped-policy"] * args.no_shipped_policy
    options += [f"--json {args.json}"] if args.json is not None else []
    results = evaluation.evaluation_results(
        list(range(args.seed, args.seed + args.episodes)),
        evaluation.ORACLE_ITERATIONS if args.oracle else 0, not args.no_shipped_policy,
        "python -m capsule_env.evaluation.evaluate " + " ".join(options),
    )  # fmt: skip
    print(evaluation.format_rows(results))
    if args.json:
        atomic_write_text(args.json, json.dumps(results, indent=1))
        print(f"\nwrote {args.json}")
    return 0


@exits_on_interrupt("evaluate.py")
def main(argv: list[str] | None = None) -> int:
    """Entry point (the exit status): bad arguments or files exit with one line (``evaluate.py:
    error: ...``) before anything runs; a declared vehicle's ``--task``: :func:`_declared_main`."""
    args = parse_args(argv)
    if args.condition is None:
        return _declared_main(args)
    try:
        ctrls = prepare(args)
    except (ValueError, OSError, TypeError) as exc:
        sys.exit(f"evaluate.py: error: {exc}")
    results = evaluate(args, ctrls)
    print(format_tables(results))
    for setting, block in results["settings"].items():
        if "floor" in block:
            print(f"\n{setting}: certified floor {block['floor']['wk_rms_body_acc_m_s2']:.4f} "
                  "m/s^2 (a proven lower bound for every controller; docs/fair-comparison.md)")  # fmt: skip
    if args.json:
        try:
            atomic_write_text(args.json, json.dumps(results, indent=2))
        except OSError as exc:
            sys.exit(f"evaluate.py: error: cannot write --json {args.json} ({exc}); any "
                     "previous file there is unchanged")  # fmt: skip
        print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    sys.exit(main())
