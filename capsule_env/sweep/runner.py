"""Run a study's trials (with Ray Tune, or one after another) and report them.

- :func:`run_trial`: the plain function every trial is, with or without Ray: it runs the
  trial's kind in the trial's folder (stdout and stderr to ``output.log`` there), counts the
  attempt (``attempts.log``) and writes ``result.json`` (or ``error.json``).
- :func:`run_serial`: every trial in this process, in order; a trial with a ``result.json``
  is finished and not run again; a failed one is run again unless ``retry_failed`` is off.
- :func:`run_ray`: the trials as Ray Tune trials (one CPU each by default) in the experiment
  ``<out>/tune``; when that experiment exists, ``tune.Tuner.restore`` continues it:
  unfinished trials run, errored ones run again when ``retry_failed`` (``restart_errored``).
  A trial's ``result.json`` is the source of truth, not Tune's state: a finished trial never
  runs again, even where the restored state (saved before it finished: a Ctrl-C, a killed
  driver) lists it as unfinished (:func:`tune_trainable` returns the stored result), and
  trials already finished by :func:`run_serial` are left out of a new experiment.
- :func:`write_results`: ``results.csv``, ``results.json`` and ``summary.png`` (the
  Wk-weighted RMS body acceleration of every finished trial, one panel per block).
"""

from __future__ import annotations

import csv
import datetime
import io
import json
import os
import platform
import traceback
from collections.abc import Callable, Iterable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.common.safe_io import atomic_write_text
from capsule_env.sweep.kinds import KINDS, SUMMARY_METRIC, flat_metrics
from capsule_env.sweep.study import Study, StudyError, Trial

#: The Tune experiment's folder name under the study's output folder (or ``--storage``).
EXPERIMENT = "tune"


@dataclass
class Outcome:
    """What became of one trial: ``status`` ``finished``, ``failed`` or ``not run``."""

    trial: Trial
    status: str
    metrics: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    attempts: int | None = None


def error_line(exc: BaseException) -> str:
    """``Type: message`` on one line (a Ray task error: its cause's)."""
    cause = getattr(exc, "cause", None)
    if isinstance(cause, BaseException):
        exc = cause
    text = " ".join(str(exc).split())
    if "Traceback" in text or len(text) > 500:  # a wrapped remote traceback: its last line
        lines = [line for line in str(exc).splitlines() if line.strip()]
        text = lines[-1].strip() if lines else text
    return f"{type(exc).__name__}: {text[:500]}"


def _attempts(folder: Path) -> int | None:
    try:
        return len((folder / "attempts.log").read_text().splitlines())
    except OSError:
        return None


def run_trial(trial: Trial | dict[str, Any]) -> dict[str, Any]:
    """Run one trial in its folder; returns ``{"trial", "metrics", "attempts"}`` (also written
    to ``result.json``). The kind's exception propagates, after ``error.json`` is written."""
    trial = trial if isinstance(trial, Trial) else Trial.from_dict(trial)
    folder = Path(trial.dir)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "error.json").unlink(missing_ok=True)
    (folder / "result.json").unlink(missing_ok=True)
    stamp = datetime.datetime.now().isoformat(timespec="seconds")
    with (folder / "attempts.log").open("a") as fh:
        fh.write(f"{stamp} {platform.node()} pid {os.getpid()}\n")
    attempts = _attempts(folder)
    try:
        with (folder / "output.log").open("a") as log, redirect_stdout(log), redirect_stderr(log):
            print(f"--- attempt {attempts}, {stamp}", flush=True)
            try:
                metrics = flat_metrics(KINDS[trial.kind].run(trial))
            except BaseException:
                traceback.print_exc()
                raise
    except BaseException as exc:
        error = {"trial": trial.name, "error": error_line(exc), "attempts": attempts}
        atomic_write_text(folder / "error.json", json.dumps(error, indent=1) + "\n")
        raise
    result = {"trial": trial.name, "metrics": metrics, "attempts": attempts}
    atomic_write_text(folder / "result.json", json.dumps(result, indent=1) + "\n")
    return result


def finished_on_disk(trial: Trial) -> Outcome | None:
    """The trial's outcome from its ``result.json``, if it finished: the file :func:`run_trial`
    writes, of this trial, with its metrics and attempts. Anything else there (``{}``, another
    trial's file, a hand-edited one) is not a finished trial, which then runs (again)."""
    try:
        result = json.loads((Path(trial.dir) / "result.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None
    whole = (isinstance(result, dict) and result.get("trial") == trial.name
             and isinstance(result.get("metrics"), dict)
             and "attempts" in result)  # fmt: skip
    if not whole:
        return None
    return Outcome(trial, "finished", result["metrics"], None, result["attempts"])


def failed_on_disk(trial: Trial) -> Outcome | None:
    """The trial's outcome from its ``error.json``, if its last attempt failed."""
    try:
        error = json.loads((Path(trial.dir) / "error.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return Outcome(trial, "failed", {}, error.get("error"), error.get("attempts"))


def check_same_study(study: Study, out_dir: Path) -> None:
    """Record the study's trials in ``<out_dir>/study.json``. The folder may hold an earlier
    version of the study: every trial recorded there must still be in the study, unchanged
    (same name, kind, parameters and seed); new trials may be added (blocks or grid points).
    Anything else is a :class:`StudyError` naming the first trial changed or gone (a restart
    must not mix the results of other trials)."""
    path = out_dir / "study.json"
    record = {"name": study.name, "file": study.path, "trials": study.fingerprint()}
    if path.is_file():
        try:
            old = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            old = None
        if not isinstance(old, dict) or not isinstance(old.get("trials"), list):
            raise StudyError(f"{path}: not a study record; give another --out, or remove "
                             f"{out_dir}")  # fmt: skip
        new = {json.dumps(t, sort_keys=True) for t in record["trials"]}
        gone = [t for t in old["trials"] if json.dumps(t, sort_keys=True) not in new]
        if gone:
            name = gone[0].get("name") if isinstance(gone[0], dict) else gone[0]
            raise StudyError(
                f"{out_dir} holds the results of study {old.get('name')!r} ({old.get('file')}) "
                f"whose trial {name!r} is changed or gone in {Path(study.path).name} (a study "
                "may only gain trials): give another --out, or remove the folder"
            )
        if old["trials"] == record["trials"]:
            return
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(record, indent=1) + "\n")


def run_serial(
    study: Study, retry_failed: bool = True, log: Callable[[str], None] = print
) -> list[Outcome]:
    """Every trial here, one after another (see the module docstring)."""
    outcomes = []
    for k, trial in enumerate(study.trials, 1):
        done = finished_on_disk(trial) or (None if retry_failed else failed_on_disk(trial))
        if done is not None:
            log(f"[{k}/{len(study.trials)}] {trial.name}: {done.status} before, not run again")
            outcomes.append(done)
            continue
        what = [trial.kind, *(f"{key}={v}" for key, v in trial.point.items())]
        what += [] if trial.seed is None else [f"seed {trial.seed}"]
        log(f"[{k}/{len(study.trials)}] {trial.name}: running ({', '.join(what)})")
        try:
            result = run_trial(trial)
        except Exception as exc:
            outcomes.append(
                Outcome(trial, "failed", {}, error_line(exc), _attempts(Path(trial.dir)))
            )
            log(f"    failed: {outcomes[-1].error}")
            continue
        outcomes.append(Outcome(trial, "finished", result["metrics"], None, result["attempts"]))
    return outcomes


# ----------------------------------------------------------------------------- Ray Tune
def tune_trainable(config: dict[str, Any]) -> dict[str, Any]:
    """The Ray Tune function trainable: :func:`run_trial` of ``config["trial"]``, with
    numba's threads limited to the trial's CPUs (``config["threads"]``). A trial whose folder
    holds its ``result.json`` is not run again: that result is returned as it is, whatever Tune
    restored (an experiment state saved before the trial finished, after a Ctrl-C or a killed
    driver, lists it as unfinished)."""
    trial = Trial.from_dict(config["trial"])
    done = _stored_result(trial)
    if done is not None:
        return done
    import numba

    numba.set_num_threads(
        max(1, min(int(config.get("threads", 1)), numba.config.NUMBA_NUM_THREADS))
    )
    return run_trial(trial)


def _stored_result(trial: Trial) -> dict[str, Any] | None:
    """The trial's ``result.json`` as :func:`run_trial` wrote it, if it finished."""
    done = finished_on_disk(trial)
    if done is None:
        return None
    return {"trial": trial.name, "metrics": done.metrics, "attempts": done.attempts}


def _trial_name(trial: Any) -> str:
    return str(trial.config["trial"]["name"])


def run_ray(
    study: Study,
    out_dir: Path,
    address: str | None = None,
    num_cpus: int | None = None,
    storage: str | None = None,
    working_dir: str | None = None,
    retry_failed: bool = True,
    verbose: int = 1,
    experiment: str = EXPERIMENT,
) -> list[Outcome]:
    """The trials as Ray Tune trials: locally (``ray.init`` with ``num_cpus``, default the
    machine's cores) or on the cluster at ``address``; the experiment lives in
    ``<storage or out_dir>/<experiment>`` (default ``tune``; one per set of blocks run alone)
    and is continued when it exists."""
    import ray

    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False}
        if address:
            kwargs["address"] = address
        else:
            kwargs["num_cpus"] = num_cpus or os.cpu_count()
        if working_dir:
            kwargs["runtime_env"] = {"working_dir": working_dir,
                                     "excludes": [".git", ".venv", "runs"]}  # fmt: skip
        ray.init(**kwargs)
        started = True
    try:
        return _tune(study, out_dir, storage, retry_failed, verbose, experiment)
    finally:
        if started:
            ray.shutdown()


def _experiment_path(storage_path: str, experiment: str, todo: list[Trial]) -> tuple[str, str]:
    """The Tune experiment to continue or start for the trials ``todo``: ``experiment`` if it
    does not exist yet or holds every one of them, else the first of ``experiment-2``,
    ``experiment-3``, ... that does (a study that grew, or a block that gained a grid point,
    has trials its earlier experiment never had: restoring it would not run them)."""
    from ray import tune
    from ray.tune import ExperimentAnalysis

    wanted = {t.name for t in todo}
    for k in range(1, 1000):
        name = experiment if k == 1 else f"{experiment}-{k}"
        path = f"{storage_path}/{name}"
        if not tune.Tuner.can_restore(path):
            return path, name
        try:
            held = {str(t.config["trial"]["name"]) for t in ExperimentAnalysis(path).trials}
        except Exception:  # an experiment Tune cannot read: leave it, take the next name
            continue
        if wanted <= held:
            return path, name
    raise StudyError(f"{storage_path}: 999 Tune experiments named {experiment}-*; remove them")


def _tune(
    study: Study,
    out_dir: Path,
    storage: str | None,
    retry_failed: bool,
    verbose: int,
    experiment: str = EXPERIMENT,
) -> list[Outcome]:
    from ray import tune

    storage_path = storage or str(out_dir.resolve())
    cpus = study.cpus_per_trial
    trainable = tune.with_resources(tune_trainable, {"cpu": cpus})
    todo = [t for t in study.trials if finished_on_disk(t) is None]
    if not todo:  # every trial finished: nothing for Tune to do
        return [finished_on_disk(t) for t in study.trials]  # type: ignore[misc]
    path, experiment = _experiment_path(storage_path.rstrip("/"), experiment, todo)
    if tune.Tuner.can_restore(path):
        tuner = tune.Tuner.restore(path, trainable, resume_unfinished=True,
                                   resume_errored=False, restart_errored=retry_failed)  # fmt: skip
    else:
        space = {"trial": tune.grid_search([t.to_dict() for t in todo]),
                 "threads": max(1, int(cpus))}  # fmt: skip
        tuner = tune.Tuner(
            trainable,
            param_space=space,
            tune_config=tune.TuneConfig(
                trial_name_creator=_trial_name, trial_dirname_creator=_trial_name
            ),
            run_config=tune.RunConfig(
                name=experiment,
                storage_path=storage_path,
                verbose=verbose,
                failure_config=tune.FailureConfig(max_failures=0),
            ),
        )
    grid = tuner.fit()
    trials = {t.name: t for t in study.trials}
    by_name: dict[str, Outcome] = {}
    for result in grid:
        # the trial's folder is named after it (an errored, restored trial has no config)
        trial = trials.get(Path(str(result.path)).name)
        if trial is None:
            continue
        metrics = result.metrics or {}
        if result.error is not None:
            attempts = _attempts(Path(trial.dir))
            by_name[trial.name] = Outcome(trial, "failed", {}, error_line(result.error), attempts)
        elif "metrics" in metrics:
            by_name[trial.name] = Outcome(trial, "finished", dict(metrics["metrics"]), None,
                                          metrics.get("attempts"))  # fmt: skip
    # the trial's result.json is the source of truth: Tune's state may be older than it
    return [finished_on_disk(t) or by_name.get(t.name) or Outcome(t, "not run")
            for t in study.trials]  # fmt: skip


# ----------------------------------------------------------------------------- results
_FIRST = ("trial", "block", "kind", "status", "seed")
_LAST = ("attempts", "error")


def result_rows(outcomes: Iterable[Outcome]) -> list[dict[str, Any]]:
    """One row per trial: name, block, kind, status, seed, ``param.<key>`` (every parameter),
    the metrics, attempts and the error (failed trials)."""
    rows = []
    for o in outcomes:
        row: dict[str, Any] = {"trial": o.trial.name, "block": o.trial.block,
                               "kind": o.trial.kind, "status": o.status, "seed": o.trial.seed}  # fmt: skip
        row.update({f"param.{k}": v for k, v in o.trial.params.items()})
        row.update(o.metrics)
        row.update({"attempts": o.attempts, "error": o.error})
        rows.append(row)
    return rows


def _columns(rows: list[dict[str, Any]]) -> list[str]:
    seen = dict.fromkeys(k for row in rows for k in row if k not in (*_FIRST, *_LAST))
    params = [k for k in seen if k.startswith("param.")]
    metrics = [k for k in seen if not k.startswith("param.")]
    return [*_FIRST, *params, *metrics, *_LAST]


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return value


def write_results(
    study: Study, outcomes: list[Outcome], out_dir: Path, mode: str
) -> dict[str, Path]:
    """``results.csv``, ``results.json`` and ``summary.png`` in ``out_dir``; returns the
    paths."""
    rows = result_rows(outcomes)
    columns = _columns(rows)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({c: _cell(row.get(c)) for c in columns})
    paths = {"csv": out_dir / "results.csv", "json": out_dir / "results.json",
             "figure": out_dir / "summary.png"}  # fmt: skip
    atomic_write_text(paths["csv"], buffer.getvalue())
    failed = [{"trial": o.trial.name, "error": o.error} for o in outcomes if o.status == "failed"]
    document = {
        "study": study.name,
        "file": study.path,
        "written": datetime.datetime.now().isoformat(timespec="seconds"),
        "mode": mode,
        "counts": {
            s: sum(o.status == s for o in outcomes) for s in ("finished", "failed", "not run")
        },
        "failed": failed,
        "columns": columns,
        "trials": rows,
    }
    atomic_write_text(paths["json"], json.dumps(document, indent=1, default=str) + "\n")
    summary_figure(study, outcomes, paths["figure"])
    return paths


def _where(trial: Trial) -> str:
    """Under a panel: where the kind's metric comes from."""
    if trial.kind == "train":
        return "best evaluation, validation guideway bank 7"
    if trial.kind == "gains":
        return f"guideway bank {trial.params.get('guideway_seed', 0)}"
    return ""


def _label(point: dict[str, Any]) -> str:
    if not point:
        return "(params)"
    return "\n".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in point.items())


def summary_figure(study: Study, outcomes: list[Outcome], path: Path) -> None:
    """One panel per block: the Wk-weighted RMS body acceleration of each finished trial
    (dots: replicates; bar: their mean) at each grid point, the passive damper's (dashed) where
    the trials report it; trials not finished counted in the title."""
    from matplotlib.figure import Figure

    blocks = study.blocks()
    fig = Figure(figsize=(max(5.0, 4.5 * len(blocks)), 4.2), layout="constrained")
    axes = fig.subplots(1, len(blocks), squeeze=False)[0]
    for ax, block in zip(axes, blocks):
        mine = [o for o in outcomes if o.trial.block == block]
        points = list(dict.fromkeys(json.dumps(o.trial.point, sort_keys=True) for o in mine))
        for x, key in enumerate(points):
            values = [o.metrics.get(SUMMARY_METRIC) for o in mine
                      if json.dumps(o.trial.point, sort_keys=True) == key and o.status == "finished"]  # fmt: skip
            values = [v for v in values if isinstance(v, (int, float))]
            if values:
                ax.bar(x, float(np.mean(values)), width=0.6, color="tab:blue", alpha=0.35)
                ax.plot([x] * len(values), values, "o", color="tab:blue", ms=4)
        passive = [o.metrics.get(f"passive_{SUMMARY_METRIC}") for o in mine]
        passive = [v for v in passive if isinstance(v, (int, float))]
        if passive:  # gains trials: the passive damper on the same episodes
            ax.axhline(float(np.mean(passive)), color="0.4", ls="--", lw=1, label="passive")
            ax.legend(fontsize=7, loc="lower right")
        ax.set_xticks(range(len(points)), [_label(json.loads(p)) for p in points], fontsize=7)
        n_failed = sum(o.status != "finished" for o in mine)
        title = f"{block} ({mine[0].trial.kind}, {len(mine)} trials)"
        ax.set_title(title + (f": {n_failed} not finished" if n_failed else ""), fontsize=9)
        ax.set_ylabel("Wk-weighted RMS body acceleration (m/s$^2$)", fontsize=8)
        ax.set_xlabel(_where(mine[0].trial), fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(f"study {study.name}", fontsize=10)
    fig.savefig(path, dpi=110)
