"""Command line of :mod:`capsule_env.sweep`: ``python -m capsule_env.sweep STUDY [options]``."""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import sys
import time
from pathlib import Path

from capsule_env.common.cli import ArgumentParser
from capsule_env.common.safe_io import check_creatable_dir
from capsule_env.sweep import __doc__ as DOC
from capsule_env.sweep.runner import (
    EXPERIMENT,
    Outcome,
    check_same_study,
    failed_on_disk,
    finished_on_disk,
    run_ray,
    run_serial,
    write_results,
)
from capsule_env.sweep.study import Study, StudyError, load_study, read_study_file

PROG = "python -m capsule_env.sweep"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = ArgumentParser(
        prog=PROG, description=DOC, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("study", type=Path, help="the study file (.yml, .yaml or .json)")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default runs/sweep/<study name>); running again with "
                   "the same folder continues the study")  # fmt: skip
    p.add_argument("--no-ray", action="store_true",
                   help="run the trials one after another in this process, without Ray")  # fmt: skip
    p.add_argument("--address", default=None,
                   help="a Ray cluster to run on (e.g. 'auto' or ray://head:10001); default: a "
                   "local Ray with this machine's cores")  # fmt: skip
    p.add_argument("--num-cpus", type=int, default=None,
                   help="CPU cores of the local Ray (default: all)")  # fmt: skip
    p.add_argument("--storage", default=None,
                   help="Tune's storage_path (default: the output folder); on a cluster, a "
                   "folder every node sees or a cloud URI")  # fmt: skip
    p.add_argument("--working-dir", default=None,
                   help="a folder Ray ships to the cluster's workers (runtime_env working_dir), "
                   "e.g. the checkout")  # fmt: skip
    p.add_argument("--no-retry-failed", dest="retry_failed", action="store_false",
                   help="on a restart, keep failed trials failed instead of running them again")  # fmt: skip
    p.add_argument("--block", action="append", default=None, metavar="NAME",
                   help="run only this block of the study (one row of a rows study; "
                   "repeatable); the other blocks' trials are left as they are")  # fmt: skip
    p.add_argument("--check", action="store_true",
                   help="check the study file and list its trials; run nothing")  # fmt: skip
    p.add_argument("--quiet", action="store_true", help="no Tune progress tables")
    args = p.parse_args(argv)
    if args.num_cpus is not None and args.num_cpus < 1:
        p.error(f"--num-cpus must be >= 1, got {args.num_cpus}")
    if args.no_ray and (args.address or args.storage or args.working_dir):
        p.error("--address, --storage and --working-dir need Ray: leave out --no-ray")
    return args


def _check_out(out: Path) -> None:
    """``--out`` is a writable folder or can be made (nothing made here); ``StudyError``
    naming it otherwise, before any trial runs."""
    try:
        check_creatable_dir(out, "--out")
    except ValueError as exc:
        raise StudyError(str(exc)) from None


def only_blocks(study: Study, names: list[str] | None) -> Study:
    """The study with the trials of the blocks ``names`` only (all for None); StudyError
    naming an unknown block and the study's blocks."""
    if not names:
        return study
    for name in names:
        if name not in study.blocks():
            raise StudyError(f"--block: no block {name!r} in {Path(study.path).name}; its "
                             f"blocks: {', '.join(study.blocks())}")  # fmt: skip
    return dataclasses.replace(study, trials=[t for t in study.trials if t.block in names])


def all_outcomes(study: Study, ran: list[Outcome]) -> list[Outcome]:
    """One outcome per trial of the whole study: those that ran, else what the trial's folder
    holds (finished or failed before), else not run."""
    by_name = {o.trial.name: o for o in ran}
    return [by_name.get(t.name) or finished_on_disk(t) or failed_on_disk(t)
            or Outcome(t, "not run") for t in study.trials]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status: 0 when every trial finished (with ``--block``:
    every trial of those blocks), 1 when some failed (or did not run), 2 for a bad study file
    or command line."""
    args = parse_args(argv)
    try:
        data = read_study_file(args.study)
        name = data.get("name", args.study.stem) if isinstance(data, dict) else args.study.stem
        out = args.out or Path("runs") / "sweep" / str(name)
        study = load_study(args.study, out)
        chosen = only_blocks(study, args.block)
        if args.check:
            for t in chosen.trials:
                seed = "" if t.seed is None else f" seed {t.seed}"
                print(f"{t.name}: {t.kind}{seed} {t.params}")
            print(f"{len(chosen.trials)} trials; output {out}")
            return 0
        if not args.no_ray and importlib.util.find_spec("ray") is None:
            raise StudyError("Ray is not installed (pip install 'capsule-env[scale]'); --no-ray "
                             "runs the trials one after another without it")  # fmt: skip
        _check_out(out)
        check_same_study(study, out)
    except StudyError as exc:
        print(f"sweep: error: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    mode = "serial" if args.no_ray else ("ray " + (args.address or "local"))
    print(f"study {study.name}: {len(chosen.trials)} trials ({mode}); output {out}", flush=True)
    try:
        if args.no_ray:
            ran = run_serial(chosen, args.retry_failed)
        else:
            blocks = "+".join(sorted(set(args.block or [])))
            experiment = f"{EXPERIMENT}-{blocks}" if blocks else EXPERIMENT  # its own Tune state
            ran = run_ray(chosen, out, args.address, args.num_cpus, args.storage,
                          args.working_dir, args.retry_failed,
                          verbose=0 if args.quiet else 1, experiment=experiment)  # fmt: skip
    except KeyboardInterrupt:
        print(f"\ninterrupted: run the same command again to continue ({out})", file=sys.stderr)
        return 130
    paths = write_results(study, all_outcomes(study, ran), out, mode.split()[0])
    outcomes = ran
    elapsed = time.perf_counter() - t0
    counts = {s: sum(o.status == s for o in outcomes) for s in ("finished", "failed", "not run")}
    of = f" of block(s) {', '.join(dict.fromkeys(args.block))}" if args.block else ""
    print(f"{counts['finished']} finished, {counts['failed']} failed, {counts['not run']} not "
          f"run{of} in {elapsed:.1f} s; {paths['csv']}, {paths['json']} (every block), "
          f"{paths['figure']}")  # fmt: skip
    for o in outcomes:
        if o.status != "finished":
            print(f"{o.status}: {o.trial.name}: {o.error or 'did not run'} "
                  f"(log: {Path(o.trial.dir) / 'output.log'})", file=sys.stderr)  # fmt: skip
    return 0 if counts["finished"] == len(outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
