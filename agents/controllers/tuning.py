"""Tune the classical controllers' gains on the TRAINING guideway bank and ship them.

    python -m capsule_env.agents.controllers.tuning                 # every tuned law; writes agents/controllers/tuned_gains.json
    python -m capsule_env.agents.controllers.tuning --controllers sh-add-meas,add-meas
    python -m capsule_env.agents.controllers.tuning --quick --out /tmp/gains.json   # a tiny budget (tests)

The problem, per controller (its free gains: :mod:`capsule_env.agents.learning.search_space`): minimise the mean
ISO 2631-1 Wk-weighted RMS car-body acceleration over the training episodes in ``hils``
(guideway bank ``guideway_seed=0``, episode seeds 0..9, 10 s each; the evaluation bank 2026
is never used; a law made for a registered task, :attr:`SearchSpace.task`, runs in that
task's env options on the same bank), subject to a stroke limit: ``max |stroke| <= 15 mm`` on every training episode
(a quarter of the 60 mm bump stop) and no bump-stop hit.

The search: a coarse grid over the whole (log) ranges (17 points for one gain, 9 x 9 for two,
7 x 7 x 7 for three), then rounds of local refinement, each a 5-point-per-gain grid around the
best feasible point so far with half the previous spacing (3 rounds: the final spacing is an
eighth of the coarse one). The objective is deterministic in the gains (the same guideway
seeds and noise for every candidate: common random numbers), so the grids compare candidates
exactly. Every grid is evaluated at once: the controllers take one gain value per vehicle, so
one vector env of (candidates x episodes) vehicles runs a whole grid.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from capsule_env.agents.controllers.classical import make_controller
from capsule_env.agents.controllers.tuned import TUNED_GAINS_PATH
from capsule_env.agents.learning.search_space import SEARCH_SPACES, SearchSpace

from capsule_env import metrics
from capsule_env.common.cli import ArgumentParser, exits_on_interrupt
from capsule_env.common.safe_io import atomic_write_text, check_writable_file
from capsule_env.evaluation.episodes import Rollout, run_episodes
from capsule_env.tasks import task_named

#: What the search records per vehicle.
_RECORDED = ("car_body_acceleration_m_s2", "stroke_m")


@dataclass(frozen=True)
class TuningSettings:
    """Everything the search depends on (written into the gains file)."""

    setting: str = "hils"
    guideway_seed: int = 0  # the TRAINING bank
    episode_seeds: tuple[int, ...] = tuple(range(10))
    episode_length_s: float = 10.0
    stroke_limit_m: float = 0.015
    coarse_points: tuple[int, int, int] = (17, 9, 7)  # per gain, for 1, 2, 3 free gains
    refine_rounds: int = 3
    max_vehicles: int = 4000  # per vector env (memory)

    @classmethod
    def quick(cls) -> TuningSettings:
        """A tiny budget: 2 episodes of 2 s, coarse 5/3/2 points, one refinement round."""
        return cls(episode_seeds=(0, 1), episode_length_s=2.0, coarse_points=(5, 3, 2),
                   refine_rounds=1)  # fmt: skip


@dataclass
class Evaluation:
    """Per candidate: mean Wk over the episodes (m/s^2), ``max |stroke|`` over them (m), and
    whether any episode hit the bump stop."""

    wk_m_s2: np.ndarray
    max_stroke_m: np.ndarray
    terminated: np.ndarray


class Record(NamedTuple):
    """One candidate's result: mean Wk (m/s^2), ``max |stroke|`` (m), any bump-stop hit."""

    wk_m_s2: float
    max_stroke_m: float
    terminated: bool

    def feasible(self, stroke_limit_m: float) -> bool:
        return self.max_stroke_m <= stroke_limit_m and not self.terminated


def _training_rollout(ctrl: Any, settings: TuningSettings, seeds: Any, task: str = "") -> Rollout:
    """``ctrl`` on the training bank, episode ``k`` seeded ``seeds[k]``; with ``task`` (a
    registered id) in that task's env options (the controller's own on top)."""
    env_kwargs = {**(task_named(task).kwargs if task else {}), **ctrl.env_kwargs,
                  "setting": settings.setting, "guideway_seed": settings.guideway_seed}  # fmt: skip
    return run_episodes(ctrl, env_kwargs, episode_length_s=settings.episode_length_s,
                        seeds=seeds, recorded=_RECORDED)  # fmt: skip


def evaluate_gains(name: str, gains: dict[str, np.ndarray], settings: TuningSettings) -> Evaluation:
    """Run controller ``name`` with each candidate's gains (``gains``: arrays ``(C,)``) on the
    training episodes, all candidates in one vector env (chunked to ``max_vehicles``)."""
    seeds = np.asarray(settings.episode_seeds)
    n_ep = len(seeds)
    n_cand = len(next(iter(gains.values())))
    per_chunk = max(1, settings.max_vehicles // n_ep)
    wk, stroke, hit = np.empty(n_cand), np.empty(n_cand), np.empty(n_cand, dtype=bool)
    for lo in range(0, n_cand, per_chunk):
        hi = min(n_cand, lo + per_chunk)
        ctrl = make_controller(name, **{g: np.repeat(v[lo:hi], n_ep) for g, v in gains.items()})
        roll = _training_rollout(ctrl, settings, np.tile(seeds, hi - lo), SEARCH_SPACES[name].task)
        acc = roll.signals["car_body_acceleration_m_s2"]
        wk[lo:hi] = metrics.wk_weighted_rms(acc, roll.dt_s).reshape(-1, n_ep).mean(axis=1)
        peak = np.max(np.abs(roll.signals["stroke_m"]), axis=1)
        stroke[lo:hi] = peak.reshape(-1, n_ep).max(axis=1)
        hit[lo:hi] = roll.terminated.reshape(-1, n_ep).any(axis=1)
    return Evaluation(wk, stroke, hit)


def _coarse_points(space: SearchSpace, settings: TuningSettings) -> int:
    return settings.coarse_points[min(len(space.params), len(settings.coarse_points)) - 1]


def tune(name: str, settings: TuningSettings, log: Any = None) -> dict[str, Any]:
    """Search the gains of controller ``name`` (see the module docstring). Returns the entry
    of the gains file: the tuned controller's :meth:`~capsule_env.agents.controllers.base.Controller.gains`, its
    training Wk and max stroke, and the search's counts. Raises ``RuntimeError`` if no
    candidate meets the stroke limit."""
    space = SEARCH_SPACES[name]
    t0 = time.perf_counter()
    limit = space.stroke_limit_m or settings.stroke_limit_m
    seen: dict[tuple[float, ...], Record] = {}

    def run(units: np.ndarray) -> None:
        new = np.array([u for u in units if tuple(np.round(u, 12)) not in seen])
        if len(new) == 0:
            return
        result = evaluate_gains(name, space.gains(new), settings)
        for k, u in enumerate(new):
            seen[tuple(np.round(u, 12))] = Record(
                float(result.wk_m_s2[k]), float(result.max_stroke_m[k]), bool(result.terminated[k])
            )  # fmt: skip

    def best() -> tuple[tuple[float, ...], Record]:
        ok = [(u, r) for u, r in seen.items() if r.feasible(limit)]
        if not ok:
            raise RuntimeError(f"{name}: no candidate keeps max |stroke| <= {limit:g} m")
        return min(ok, key=lambda item: item[1].wk_m_s2)

    points = _coarse_points(space, settings)
    run(space.coarse_grid(points))
    step = 1.0 / (points - 1)
    for _ in range(settings.refine_rounds):
        step /= 2.0
        run(space.local_grid(np.array(best()[0]), step))
    units, (wk, stroke, _) = best()
    tuned = make_controller(name, **{g: v[0] for g, v in space.gains(np.array(units)).items()})
    feasible = sum(r.feasible(limit) for r in seen.values())
    gains = tuned.gains()
    entry = {
        "gains": gains,
        "training": {"wk_rms_body_acc_m_s2": wk, "max_stroke_m": stroke},
        "candidates": len(seen),
        "feasible_candidates": feasible,
        "at_range_edge": [p.name for p, u in zip(space.params, units) if u in (0.0, 1.0)],
        "search_s": round(time.perf_counter() - t0, 1),
    }
    if space.task:  # searched in a registered task's env options
        entry["task"] = space.task
    if space.stroke_limit_m:  # the task's own stroke limit
        entry["stroke_limit_m"] = space.stroke_limit_m
    if log is not None:
        listed = ", ".join(f"{k} {v:.4g}" for k, v in gains.items())
        print(f"{name:<24} Wk {wk:.4f} m/s^2  max stroke {1e3 * stroke:5.2f} mm  "
              f"{len(seen):4d} candidates ({feasible} feasible)  {entry['search_s']:6.1f} s  "
              f"{listed}", file=log, flush=True)  # fmt: skip
    return entry


def passive_reference(settings: TuningSettings) -> dict[str, float]:
    """The passive damper on the training episodes (for scale)."""
    roll = _training_rollout(make_controller("passive"), settings, settings.episode_seeds)
    wk = metrics.wk_weighted_rms(roll.signals["car_body_acceleration_m_s2"], roll.dt_s)
    return {"wk_rms_body_acc_m_s2": float(wk.mean()),
            "max_stroke_m": float(np.abs(roll.signals["stroke_m"]).max())}  # fmt: skip


def tune_all(
    names: list[str], settings: TuningSettings, command: str, log: Any = None
) -> dict[str, Any]:
    """Tune each of ``names`` (a line each on ``log`` if given); returns the gains file's
    content."""
    t0 = time.perf_counter()
    entries = {name: tune(name, settings, log) for name in names}
    total = time.perf_counter() - t0
    return {
        "description": "Classical controllers' gains tuned on the TRAINING guideway bank "
        "(never the evaluation bank): minimum mean ISO Wk-weighted RMS body acceleration "
        "subject to max |stroke| <= stroke_limit_m on every episode (agents/controllers/tuning.py).",
        "date": datetime.date.today().isoformat(),
        "command": command,
        "settings": {
            **asdict(settings),
            "episode_seeds": list(settings.episode_seeds),
            "coarse_points": list(settings.coarse_points),
        },  # fmt: skip
        "search_s": round(total, 1),
        "candidates": sum(e["candidates"] for e in entries.values()),
        "training_reference": {"passive": passive_reference(settings)},
        "controllers": entries,
    }


def merge_previous(data: dict[str, Any], path: Path) -> dict[str, Any]:
    """``data`` with the entries of the controllers it does not tune kept from the file at
    ``path`` when that file was made with the same settings (a partial re-run); otherwise
    ``data`` alone (a warning names what is dropped)."""
    try:
        old = json.loads(path.read_text()) if path.is_file() else {}
    except (OSError, json.JSONDecodeError):
        old = {}
    kept = {n: e for n, e in old.get("controllers", {}).items() if n not in data["controllers"]}
    if not kept:
        return data
    if old.get("settings") != data["settings"]:
        print(f"warning: {path} was made with other settings; its entries {sorted(kept)} are "
              "dropped", file=sys.stderr)  # fmt: skip
        return data
    merged = {**data, "controllers": {**old["controllers"], **data["controllers"]}}
    merged["candidates"] = sum(e["candidates"] for e in merged["controllers"].values())
    return merged


@exits_on_interrupt("python -m capsule_env.agents.controllers.tuning")
def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    p = ArgumentParser(prog="python -m capsule_env.agents.controllers.tuning", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--controllers", default="all",
                   help="comma-separated names, or 'all': " + ", ".join(SEARCH_SPACES))  # fmt: skip
    p.add_argument("--quick", action="store_true",
                   help="a tiny budget (2 episodes of 2 s, small grids); writes only to --out")  # fmt: skip
    p.add_argument("--stroke-limit-mm", type=float, default=None,
                   help="the stroke limit (default 15 mm)")  # fmt: skip
    p.add_argument("--out", type=Path, default=None,
                   help=f"the gains file (default {TUNED_GAINS_PATH}, not with --quick)")  # fmt: skip
    args = p.parse_args(argv)
    names = list(SEARCH_SPACES) if args.controllers == "all" else args.controllers.split(",")
    unknown = [n for n in names if n not in SEARCH_SPACES]
    if unknown:
        p.error(f"--controllers: no search space for {unknown}; tuned: {', '.join(SEARCH_SPACES)}")
    settings = TuningSettings.quick() if args.quick else TuningSettings()
    if args.stroke_limit_mm is not None:
        if not args.stroke_limit_mm > 0:
            p.error(f"--stroke-limit-mm must be > 0, got {args.stroke_limit_mm}")
        settings = replace(settings, stroke_limit_m=args.stroke_limit_mm / 1e3)
    out = args.out if args.out is not None or args.quick else TUNED_GAINS_PATH
    if out is not None:
        try:
            check_writable_file(out, "--out")
        except (ValueError, OSError) as exc:
            p.error(str(exc))
    words = sys.argv[1:] if argv is None else argv
    command = " ".join(["python -m capsule_env.agents.controllers.tuning", *words])
    data = tune_all(names, settings, command, log=sys.stdout)
    passive = data["training_reference"]["passive"]
    print(f"{data['candidates']} candidates in {data['search_s']:.1f} s; passive on the "
          f"training episodes: Wk {passive['wk_rms_body_acc_m_s2']:.4f} m/s^2, max stroke "
          f"{1e3 * passive['max_stroke_m']:.2f} mm")  # fmt: skip
    if out is not None:
        data = merge_previous(data, out)
        atomic_write_text(out, json.dumps(data, indent=2) + "\n")
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
