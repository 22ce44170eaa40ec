"""Check that a rows study reproduces the runs behind a learned-baselines table.

    python experiments/check_row_studies.py experiments/studies/rows-CapsuleTrip-v0.yml \
        docs/figures/learned_baselines-CapsuleTrip-v0.json

A rows study (``experiments/studies/rows-*.yml``) has one block per row of a table of
``docs/learned-baselines.md``, named as the row's group in the table's JSON
(``experiments/learned_baselines.py --json``), with the seeds its runs used. Running it
(``python -m capsule_env.sweep STUDY``) trains every row again. This script checks, without
training, that each trial is the run the table used: for every block, the JSON's group of the
same name; for every trial, the group's run of the same seed (its ``final_model.json``); and
that the run the sweep would start is that run's configuration: the algorithm, the seed, the
hyperparameters (all of them; ``n_timesteps`` too unless the trial gives ``total_timesteps``),
the env options after the task's and the file's are merged, the vehicles, the total steps, the
evaluation's bank, episodes and frequency, and the residual law and scale. Nothing of the
check is taken from the study itself: the expected values are what each run recorded when it
trained.

It checks the runs the table was made from, not a new sweep's output: the table's run
folders are read relative to ``--runs-root`` (default: the current folder; the folder
``learned_baselines.py`` ran in). The other way round too: a group of the table without a
block, or a run whose seed is not in its block, is reported.

One line per trial (``ok``, the keys that differ with both values, or why its run cannot be
read) and per table run the study lacks; exit status 1 if there is any such problem, 0
otherwise, 2 for a bad command line, study or table (one line). A run that was stopped and
resumed (``--resume``) has the same configuration but not the same random stream (the
resumed run starts its episodes afresh; its ``final_model.json`` does not say so): the
table's page says which rows were.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env.common.cli import ArgumentParser  # noqa: E402

#: train.Args fields recorded in a run's ``args`` that decide its training.
ARG_KEYS = ("algo", "seed", "eval_episodes", "eval_seed", "eval_episode_length", "eval_freq",
            "residual", "residual_scale")  # fmt: skip


def planned(trial: Any, folder: Path) -> dict[str, Any]:
    """What the sweep would train for ``trial``: ``train.py``'s own plan (``prepare``) of the
    trial's arguments, in a scratch folder."""
    from capsule_env.agents.learning.training import prepare

    from capsule_env.sweep.kinds import train_args

    args = train_args(trial, folder)
    with contextlib.redirect_stdout(io.StringIO()):  # train.py's notes (rounded totals)
        plan = prepare(args)
    hp = dict(plan.hp)
    out = {key: getattr(plan.args, key) for key in ARG_KEYS}
    out.update(hyperparams=hp, train_env_kwargs=plan.env_kwargs, num_envs=plan.num_envs,
               total_timesteps=plan.total)  # fmt: skip
    return out


def recorded(run_dir: Path) -> dict[str, Any]:
    """What a finished run recorded about its training (``final_model.json``); ValueError
    naming the file and the missing key."""
    path = run_dir / "final_model.json"
    try:
        meta = json.loads(path.read_text())
        args = meta["args"]
        out = {key: args.get(key) for key in ARG_KEYS}
        out.update(hyperparams=meta["hyperparams"], train_env_kwargs=meta["train_env_kwargs"],
                   num_envs=meta["num_envs"], total_timesteps=args["total_timesteps"])  # fmt: skip
    except OSError as exc:
        raise ValueError(
            f"run {run_dir} has no readable final_model.json ({exc.strerror})"
        ) from None
    except (json.JSONDecodeError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(
            f"{path}: not a finished run's record ({type(exc).__name__}: {exc})"
        ) from None
    return out


def differences(want: dict[str, Any], got: dict[str, Any], explicit_total: bool) -> list[str]:
    """The keys where the planned run differs from the recorded one, with both values."""
    diff = []
    for key in sorted(set(want) | set(got)):
        a, b = want.get(key), got.get(key)
        if key == "hyperparams":
            a, b = dict(a or {}), dict(b or {})
            if explicit_total:  # train.py's --total-timesteps overrides the file's n_timesteps
                a.pop("n_timesteps", None)
                b.pop("n_timesteps", None)
            for hk in sorted(set(a) | set(b)):
                if json.dumps(a.get(hk)) != json.dumps(b.get(hk)):
                    diff.append(f"hp.{hk}: study {a.get(hk)!r}, run {b.get(hk)!r}")
        elif json.dumps(a, sort_keys=True) != json.dumps(b, sort_keys=True):
            diff.append(f"{key}: study {a!r}, run {b!r}")
    return diff


def table_runs(table_json: Path) -> dict[str, list[tuple[int, str]]]:
    """The table's groups: name -> [(seed, run folder)]; ValueError naming what is wrong."""
    try:
        groups = json.loads(table_json.read_text())["runs"]
        out = {str(g): [(r["seed"], r["folder"]) for r in runs] for g, runs in groups.items()}
    except (KeyError, TypeError, AttributeError):
        raise ValueError(
            f"{table_json}: expected 'runs' mapping each group to a list of "
            "{'seed': int, 'folder': str} (experiments/learned_baselines.py --json)"
        ) from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{table_json}: not JSON ({exc})") from None
    for g, runs in out.items():
        for seed, folder in runs:
            if isinstance(seed, bool) or not isinstance(seed, int) or not isinstance(folder, str):
                raise ValueError(f"{table_json}: runs.{g}: expected integer seeds and folder "
                                 f"strings, got {seed!r}, {folder!r}")  # fmt: skip
    return out


def coverage(study: Any, groups: dict[str, list[tuple[int, str]]]) -> list[str]:
    """What the table has that the study does not: groups without a block, runs whose seed
    is not in their block, a seed twice in one group."""
    problems = []
    blocks = {b: {t.seed for t in study.trials if t.block == b} for b in study.blocks()}
    for g, runs in groups.items():
        seeds = [seed for seed, _ in runs]
        if g not in blocks:
            problems.append(f"group {g!r}: no block of that name in the study")
            continue
        for seed in sorted({s for s in seeds if seeds.count(s) > 1}):
            problems.append(f"group {g!r}: seed {seed} twice in the table")
        for seed in sorted(set(seeds) - blocks[g]):
            problems.append(f"group {g!r}: its run of seed {seed} is not a trial of the block")
    return problems


def check(study_path: Path, table_json: Path, runs_root: Path = Path(".")) -> int:
    """Print one line per trial (and per table run the study lacks); return the number of
    problems: trials that differ or have no run, runs without a trial."""
    from capsule_env.sweep.study import load_study

    groups = table_runs(table_json)
    bad = 0
    with tempfile.TemporaryDirectory() as scratch:
        study = load_study(study_path, scratch)
        for t in study.trials:
            if t.kind != "train":
                raise ValueError(f"{study_path}: block {t.block!r} is of kind {t.kind!r}: a "
                                 "rows study has train blocks only")  # fmt: skip
        for i, trial in enumerate(study.trials):
            runs = dict(groups.get(trial.block, []))
            if trial.seed not in runs:
                print(f"{trial.name}: no run of seed {trial.seed} in group {trial.block!r} "
                      f"of {table_json}")  # fmt: skip
                bad += 1
                continue
            try:
                got = recorded(runs_root / runs[trial.seed])
            except ValueError as exc:
                print(f"{trial.name}: {exc}")
                bad += 1
                continue
            want = planned(trial, Path(scratch) / f"t{i}")
            diff = differences(want, got, "total_timesteps" in trial.params)
            print(f"{trial.name}: {'ok' if not diff else 'DIFFERS'} ({runs[trial.seed]})")
            for line in diff:
                print(f"    {line}")
            bad += bool(diff)
        for line in coverage(study, groups):
            print(line)
            bad += 1
    return bad


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(description="Check that a rows study reproduces a table's runs.")
    p.add_argument("study", type=Path, help="the rows study file")
    p.add_argument("table", type=Path, help="the table's JSON (experiments/learned_baselines.py)")
    p.add_argument("--runs-root", type=Path, default=Path("."), metavar="DIR",
                   help="the folder the table's run folders are relative to (where "
                   "learned_baselines.py ran; default: the current folder)")  # fmt: skip
    a = p.parse_args(argv)
    for path, what in ((a.study, "study"), (a.table, "table")):
        if not path.is_file():
            p.error(f"{what}: no file {path}")
    if not a.runs_root.is_dir():
        p.error(f"--runs-root: no folder {a.runs_root}")
    try:
        bad = check(a.study, a.table, a.runs_root)
    except (ValueError, OSError, TypeError) as exc:
        p.error(str(exc))
    print(f"{bad} problem(s)" if bad else "every trial is its row's run, every run a trial")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
