"""Choose the policy to ship among finished training runs, on a selection bank of its own.

    python experiments/select_policy.py --runs 'runs/ship10/ppo-measured-seed*' \
        --json docs/figures/selection-CapsuleRide-v0.json
    python experiments/select_policy.py --task CapsuleTrip-v0 --runs 'runs/tasks30/trip-*-seed*' \
        --json trip-selection.json

Why: ``train.py`` keeps each run's best checkpoint by 10 episodes of the validation bank
(guideway seed 7, episodes 5000..5009). Choosing among runs on those same episodes picks noise
when runs are within 0.01 m/s^2 of each other (docs/learned-baselines.md: on the trip task the
validation bank's best runs are not the evaluation bank's), and favours the runs whose
checkpoints were chosen on them. This script scores every run's ``best_model`` and the shipped
policies on the **selection bank**: guideway seed 11
(:data:`~capsule_env.evaluation.episodes.SELECTION_GUIDEWAY_SEED`, neither the training, validation nor
evaluation bank) with a bank of ``--profiles`` (128) guideway profiles, so that the episodes'
windows rarely share a profile; episodes ``--first-seed`` (0) .. + ``--episodes`` (60), 10 s,
the task's setting and options with each policy's own reading options over them (what
evaluate.py runs). A run, shipped policy or law made for another task (other physics, other
signals, another preview horizon) is refused.

The rule: the episodes are split by their profile (even profile index: the *choice* half, odd:
the *comparison* half, no profile in both). The run with the lowest mean Wk-weighted body
acceleration on the choice half is the candidate; it is shipped only if, on the comparison
half, its paired difference to the best shipped policy there (candidate - shipped, episode by
episode) has a 95 % interval entirely below 0. The interval is a cluster bootstrap over the
profiles (10,000 resamples, fixed seed): episodes on one profile are not independent. The
script prints the ``agents.ship`` command and does not ship: that is a deliberate step.
"""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env.common.cli import ArgumentParser, integer  # noqa: E402

LENGTH_S = 10.0
BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED = 10_000, 20261125
MIN_EPISODES, MAX_EPISODES = 10, 1000


def bank_kwargs(task: dict, setting: str, profiles: int) -> dict:
    """The selection bank's env options over the task's."""
    from capsule_env.evaluation.episodes import SELECTION_GUIDEWAY_SEED

    return {**task, "setting": setting, "guideway_seed": SELECTION_GUIDEWAY_SEED,
            "guideway_bank_size": profiles}  # fmt: skip


def episode_profiles(kwargs: dict, seeds: list[int]) -> np.ndarray:
    """The guideway profile each episode's window lies on (episode k: the env seeded seeds[k])."""
    from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv

    env = CapsuleSuspensionVectorEnv(num_envs=len(seeds), episode_length_s=LENGTH_S, **kwargs)
    env.reset(seed=[int(s) for s in seeds])
    return np.array(env.batch.profile_index, dtype=np.int64)


def per_episode_wk(policy, kwargs: dict, seeds: list[int]) -> np.ndarray:
    """Wk-weighted RMS body acceleration (m/s^2) of ``policy`` per episode, on the bank's
    options ``kwargs`` with the policy's own over them (as evaluate.py runs a controller)."""
    from capsule_env.evaluation.episodes import episode_metrics, run_episodes

    own = {k: v for k, v in policy.env_kwargs.items() if k not in ("setting", "guideway_seed")}
    rollout = run_episodes(policy, {**kwargs, **own}, seeds=seeds, episode_length_s=LENGTH_S)
    return np.array([episode_metrics(rollout.select(slice(k, k + 1)), None)
                     ["wk_rms_body_acc_m_s2"] for k in range(len(seeds))])  # fmt: skip


def paired_interval(a, b, clusters) -> tuple[float, float, float]:
    """Mean of ``a - b`` over paired episodes and its 95 % percentile interval, bootstrapping
    the ``clusters`` (one label per episode; episodes of one label resampled together)."""
    a, b, clusters = np.asarray(a, float), np.asarray(b, float), np.asarray(clusters)
    if not (a.ndim == 1 and a.shape == b.shape == clusters.shape):
        raise ValueError(f"paired episodes: a, b and clusters must be 1-D of one length, got "
                         f"{a.shape}, {b.shape}, {clusters.shape}")  # fmt: skip
    labels, group = np.unique(clusters, return_inverse=True)
    if labels.size < 2:
        raise ValueError(f"paired episodes: need >= 2 clusters, got {labels.size}")
    sums = np.bincount(group, weights=a - b)
    counts = np.bincount(group).astype(float)
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    idx = rng.integers(0, labels.size, size=(BOOTSTRAP_RESAMPLES, labels.size))
    means = sums[idx].sum(axis=1) / counts[idx].sum(axis=1)
    low, high = np.percentile(means, [2.5, 97.5])
    return float((a - b).mean()), float(low), float(high)


def decide(runs: dict[str, np.ndarray], shipped: dict[str, np.ndarray],
           profiles: np.ndarray) -> dict:  # fmt: skip
    """The rule of the module docstring on per-episode Wk (``runs``, ``shipped``: name ->
    array over the episodes; ``profiles``: each episode's profile)."""
    if not runs or not shipped:
        raise ValueError("decide: need at least one run and one shipped policy")
    choice, compare = profiles % 2 == 0, profiles % 2 == 1
    if np.unique(profiles[choice]).size < 2 or np.unique(profiles[compare]).size < 2:
        raise ValueError("decide: each half needs episodes on >= 2 profiles; add episodes")
    ranking = sorted(runs, key=lambda k: float(runs[k][choice].mean()))
    best = ranking[0]
    rival = min(shipped, key=lambda k: float(shipped[k][compare].mean()))
    diff = paired_interval(runs[best][compare], shipped[rival][compare], profiles[compare])
    return {"choice_ranking": [(k, float(runs[k][choice].mean())) for k in ranking],
            "best": best, "best_on_comparison_m_s2": float(runs[best][compare].mean()),
            "best_shipped": (rival, float(shipped[rival][compare].mean())),
            "difference_m_s2": list(diff), "ship": diff[2] < 0.0,
            "choice_episodes": int(choice.sum()), "comparison_episodes": int(compare.sum())}  # fmt: skip


def _report(result: dict) -> list[str]:
    d = result["decision"]
    lines = [f"selection bank: guideway seed {result['guideway_seed']}, {result['profiles']} "
             f"profiles, episodes {result['seeds'][0]}..{result['seeds'][-1]}, {LENGTH_S:g} s; "
             f"choice half {d['choice_episodes']} episodes:"]  # fmt: skip
    lines += [f"  {wk:.4f}  {name}" for name, wk in d["choice_ranking"][:10]]
    for name, wk in result["laws_wk_m_s2"].items():
        lines.append(f"  {wk:.4f}  {name} (classical law, all episodes, reference)")
    (rival, wk), (mean, low, high) = d["best_shipped"], d["difference_m_s2"]
    lines.append(f"comparison half ({d['comparison_episodes']} episodes): {d['best']} "
                 f"{d['best_on_comparison_m_s2']:.4f}, best shipped {rival} {wk:.4f}; "
                 f"difference {mean:+.4f} [{low:+.4f}, {high:+.4f}] m/s^2 (95 %, by profile)")  # fmt: skip
    if d["ship"]:
        lines.append(f"decision: ship {d['best']}\n  python -m capsule_env.agents.learning.ship "
                     f"{d['best']}/best_model.zip NAME --note '...'")  # fmt: skip
    else:
        lines.append(f"decision: keep {rival} (the candidate's interval is not below 0)")
    return lines


def _parser() -> ArgumentParser:
    p = ArgumentParser(prog="select_policy.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", action="append", required=True, metavar="GLOB",
                   help="train.py output folders (with best_model.zip), repeatable")  # fmt: skip
    p.add_argument("--shipped", action="append", default=[], metavar="NAME",
                   help="a shipped policy to beat (capsule_env/pretrained/NAME.zip), repeatable "
                   "(default: the task's shipped policy)")  # fmt: skip
    p.add_argument("--law", action="append", default=[], metavar="NAME",
                   help="a classical law scored on all the episodes for reference, not a "
                   "candidate; it must read the task's signals; repeatable")  # fmt: skip
    p.add_argument(
        "--task",
        default="CapsuleRide-v0",
        metavar="ID",
        help="the registered task the runs were trained on (default CapsuleRide-v0)",
    )
    p.add_argument(
        "--episodes",
        type=integer,
        default=60,
        help=f"episodes, in [{MIN_EPISODES}, {MAX_EPISODES}] (default 60)",
    )
    p.add_argument(
        "--profiles",
        type=integer,
        default=128,
        help="guideway profiles in the selection bank, in [2, 1024] (default 128)",
    )
    p.add_argument("--first-seed", type=integer, default=0, help="first episode seed (default 0)")
    p.add_argument("--json", type=Path, required=True, help="the result (written atomically)")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    try:
        inputs = load_inputs(args)
    except ValueError as error:
        print(f"select_policy.py: error: {error}", file=sys.stderr)
        return 2
    from capsule_env.agents.learning.sb3_policy import use_one_torch_thread

    from capsule_env.common.safe_io import atomic_write_text

    use_one_torch_thread()
    kwargs, seeds = inputs["bank_kwargs"], inputs["seeds"]
    profiles = episode_profiles(kwargs, seeds)
    scored = {part: {name: per_episode_wk(c, kwargs, seeds) for name, c in inputs[part].items()}
              for part in ("runs", "shipped", "laws")}  # fmt: skip
    result = {"task": args.task, "guideway_seed": kwargs["guideway_seed"], "profiles": args.profiles,
              "seeds": seeds, "episode_length_s": LENGTH_S, "episode_profiles": profiles.tolist(),
              "bootstrap": {"resamples": BOOTSTRAP_RESAMPLES, "seed": BOOTSTRAP_SEED},
              "decision": decide(scored["runs"], scored["shipped"], profiles),
              "laws_wk_m_s2": {k: float(v.mean()) for k, v in scored["laws"].items()},
              "per_episode_wk_m_s2": {part: {k: v.tolist() for k, v in d.items()}
                                      for part, d in scored.items()},
              "files": inputs["digests"], "git_commit": _git_commit(),
              "command": shlex.join(["python", "experiments/select_policy.py", *argv])}  # fmt: skip
    atomic_write_text(args.json, json.dumps(result, indent=1) + "\n")
    print("\n".join(_report(result)))
    return 0


def _folders(patterns: list[str]) -> list[Path]:
    import glob

    found = {Path(f) for p in patterns for f in glob.glob(p)}
    return sorted(f for f in found if (f / "best_model.zip").is_file())


def _reads_the_task(own: dict, task: dict, setting: str, trained: bool) -> bool:
    """Whether a controller with the env options ``own`` belongs to the task: it reads the
    task's kind of signals and preview (``observation``, ``preview_points``,
    ``preview_horizon_s``; the env's defaults where none is named) and runs in the task's physics: for a trained policy
    :func:`fits_condition` (its training options), for a law its options other than
    :data:`READING_OPTIONS` leave the task's env as it is."""
    from capsule_env.agents.learning.sb3_policy import READING_OPTIONS, fits_condition

    from capsule_env.engine.config import EnvConfig

    condition = {**task, "setting": setting}
    own = {k: v for k, v in own.items() if k != "setting"}
    try:
        asked, runs_in = (
            EnvConfig.from_kwargs(**condition),
            EnvConfig.from_kwargs(**{**condition, **own}),
        )
    except (ValueError, TypeError):
        return False
    reads = ("observation", "preview_points", "preview_horizon_s")
    same = all(getattr(asked, k) == getattr(runs_in, k) for k in reads)
    if trained:
        return same and fits_condition(own, condition)
    reading = {k: v for k, v in own.items() if k in READING_OPTIONS}
    return same and EnvConfig.from_kwargs(**{**condition, **reading}) == runs_in


def _check_arguments(args) -> None:
    """``ValueError`` naming the first bad argument (before anything is loaded or run)."""
    from capsule_env.tasks import TASKS

    ids = [t.env_id for t in TASKS]
    if args.task not in ids:
        raise ValueError(f"--task must be one of {', '.join(ids)}, got {args.task!r}")
    if not MIN_EPISODES <= args.episodes <= MAX_EPISODES:
        raise ValueError(f"--episodes must be in [{MIN_EPISODES}, {MAX_EPISODES}], got "
                         f"{args.episodes}")  # fmt: skip
    if not 2 <= args.profiles <= 1024:
        raise ValueError(f"--profiles must be in [2, 1024], got {args.profiles}")
    if not 0 <= args.first_seed <= 2**62:
        raise ValueError(f"--first-seed must be in [0, 2**62], got {args.first_seed}")
    parent = args.json.parent if str(args.json.parent) else Path(".")
    if args.json.is_dir() or not parent.is_dir():
        raise ValueError(f"--json must be a file in an existing folder, got {str(args.json)!r}")
    if not _folders(args.runs):
        raise ValueError(f"--runs {args.runs} matches no train.py output folder with a "
                         "best_model.zip")  # fmt: skip


def load_inputs(args) -> dict:
    """The runs', shipped policies' and laws' controllers, checked against the task, with the
    bank's options, the seeds and the files' digests; ``ValueError`` naming a bad one."""
    from capsule_env.agents.controllers.classical import FACTORIES, make_controller
    from capsule_env.agents.learning.sb3_policy import (
        PRETRAINED_DIR,
        load_policy,
        shipped_policy_paths,
    )

    from capsule_env.common.safe_io import file_digest
    from capsule_env.tasks import task_named

    _check_arguments(args)
    task = task_named(args.task)
    stems = [Path(p).stem for p in shipped_policy_paths()]
    names = args.shipped or [n for n in [task.shipped_policy] if n]
    if not names:
        raise ValueError(f"--shipped: {args.task} has no shipped policy; name one of {stems}")
    for name in names:
        if name not in stems:
            raise ValueError(f"--shipped must be one of {stems}, got {name!r}")
    for name in args.law:
        if name not in FACTORIES:
            raise ValueError(f"--law {name!r} is not a classical controller")
    zips = {str(f): f / "best_model.zip" for f in _folders(args.runs)}
    shipped_zips = {n: PRETRAINED_DIR / f"{n}.zip" for n in names}
    loaded = {"runs": {}, "shipped": {}, "laws": {}}
    for part, table in (("runs", zips), ("shipped", shipped_zips)):
        for name, path in table.items():
            try:
                loaded[part][name] = load_policy(path)
            except (ValueError, OSError) as error:
                raise ValueError(f"{path} does not load: {error}") from None
    loaded["laws"] = {n: make_controller(n) for n in args.law}
    for part, table in loaded.items():
        for name, controller in table.items():
            trained = part != "laws"
            if not _reads_the_task(controller.env_kwargs, dict(task.kwargs), task.setting, trained):
                raise ValueError(f"{name} ({part}) was not made for {args.task}: its options "
                                 f"{controller.env_kwargs} change the task's physics or signals")  # fmt: skip
    digests = {str(p): file_digest(p) for p in zips.values()}
    digests.update(
        {f"capsule_env/pretrained/{n}.zip": file_digest(p) for n, p in shipped_zips.items()}
    )
    seeds = list(range(args.first_seed, args.first_seed + args.episodes))
    return {**loaded, "digests": digests, "seeds": seeds,
            "bank_kwargs": bank_kwargs(dict(task.kwargs), task.setting, args.profiles)}  # fmt: skip


def _git_commit() -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                             cwd=Path(__file__).resolve().parent, check=True, timeout=10)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


if __name__ == "__main__":
    sys.exit(main())
