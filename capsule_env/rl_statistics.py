"""Statistics of learned results the way the RL community reports them (rliable).

Agarwal, Schwarzer, Castro, Courville & Bellemare, "Deep reinforcement learning at the edge of
the statistical precipice", NeurIPS 2021: with a handful of training seeds, a mean or a median
hides how uncertain a result is. The protocol, on scores normalised per task:

- the **interquartile mean** (IQM: the mean of the middle 50 % of all runs x tasks scores) with a
  95 % **stratified bootstrap** confidence interval (runs resampled within each task);
- the **probability of improvement** ``P(X > Y)`` of one algorithm over another (a Mann-Whitney
  statistic averaged over tasks), with its interval;
- **sample-efficiency curves**: the IQM and its interval at every checkpoint of training.

Scores here are the task's normalised score (:func:`capsule_env.tasks.normalised_score`: 0 the
passive damper, 1 the clairvoyant oracle, from the Wk-weighted body acceleration on the
evaluation bank), so "higher is better" as rliable expects. The computations are rliable's
(``pip install 'capsule-env[rl]'``); this module fixes their inputs' shape ``(runs, tasks)``,
makes the intervals reproducible (rliable 1.2 resamples with NumPy's global generator: it is
seeded with ``seed`` for the call and restored afterwards) and names the errors.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

__all__ = ["Estimate", "normalised_scores", "iqm", "probability_of_improvement", "iqm_curves"]


@dataclass(frozen=True)
class Estimate:
    """A point estimate and its confidence interval ``[low, high]``."""

    value: float
    low: float
    high: float


def normalised_scores(wk_m_s2: np.ndarray, passive_m_s2: np.ndarray, oracle_m_s2: np.ndarray):
    """``(passive - wk) / (passive - oracle)`` per task: ``wk`` of shape (runs, tasks), the
    references of shape (tasks,); ``ValueError`` unless every passive exceeds its oracle."""
    wk, passive, oracle = (np.asarray(a, dtype=float) for a in (wk_m_s2, passive_m_s2,
                                                                 oracle_m_s2))  # fmt: skip
    if wk.ndim != 2 or passive.shape != (wk.shape[1],) or oracle.shape != passive.shape:
        raise ValueError(f"wk_m_s2 must be (runs, tasks) and the references (tasks,), got "
                         f"{wk.shape}, {passive.shape}, {oracle.shape}")  # fmt: skip
    if not np.all(passive > oracle):
        raise ValueError("passive_m_s2 must exceed oracle_m_s2 on every task")
    return (passive - wk) / (passive - oracle)


def _check(name: str, scores: np.ndarray) -> np.ndarray:
    scores = np.asarray(scores, dtype=float)
    if scores.ndim != 2 or scores.shape[0] < 2 or not np.all(np.isfinite(scores)):
        raise ValueError(f"{name} must be a finite (runs, tasks) array with runs >= 2, got shape "
                         f"{scores.shape}")  # fmt: skip
    return scores


@contextmanager
def _seeded(seed: int) -> Iterator[None]:
    """NumPy's global generator seeded with ``seed`` inside, restored on exit."""
    state = np.random.get_state()  # noqa: NPY002  (rliable draws from the legacy global generator)
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def _rliable():
    try:
        from rliable import library, metrics
    except ImportError as err:  # pragma: no cover - the rl extra is installed in CI
        raise ImportError("capsule_env.rl_statistics needs rliable: pip install "
                          "'capsule-env[rl]'") from err  # fmt: skip
    return library, metrics


def iqm(scores: Mapping[str, np.ndarray], reps: int = 20_000, seed: int = 0) -> dict[str, Estimate]:
    """IQM of each algorithm's ``(runs, tasks)`` scores with a 95 % stratified-bootstrap
    interval (``reps`` resamples, percentile method, reproducible with ``seed``)."""
    library, metrics = _rliable()
    data = {name: _check(f"scores[{name!r}]", s) for name, s in scores.items()}
    with _seeded(seed):
        points, intervals = library.get_interval_estimates(
            data, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps
        )
    return {name: Estimate(float(points[name][0]), float(intervals[name][0, 0]),
                           float(intervals[name][1, 0])) for name in data}  # fmt: skip


def probability_of_improvement(x: np.ndarray, y: np.ndarray, reps: int = 20_000,
                               seed: int = 0) -> Estimate:  # fmt: skip
    """``P(X > Y)`` (ties count one half) of runs of ``x`` over runs of ``y``, averaged over
    tasks, with a 95 % stratified-bootstrap interval; both ``(runs, tasks)``, same tasks."""
    library, metrics = _rliable()
    x, y = _check("x", x), _check("y", y)
    if x.shape[1] != y.shape[1]:
        raise ValueError(f"x and y must score the same tasks, got {x.shape[1]} and {y.shape[1]}")
    with _seeded(seed):
        points, intervals = library.get_interval_estimates(
            {"pair": (x, y)}, metrics.probability_of_improvement, reps=reps
        )
    low, high = np.ravel(intervals["pair"])
    return Estimate(float(points["pair"]), float(low), float(high))


def iqm_curves(scores: Mapping[str, np.ndarray], reps: int = 5_000,
               seed: int = 0) -> dict[str, np.ndarray]:  # fmt: skip
    """Sample-efficiency curves: for each algorithm's ``(runs, tasks, checkpoints)`` scores,
    an array ``(3, checkpoints)`` of the IQM and its 95 % interval's low and high ends."""
    library, metrics = _rliable()
    out = {}
    for name, s in scores.items():
        s = np.asarray(s, dtype=float)
        if s.ndim != 3:
            raise ValueError(f"scores[{name!r}] must be (runs, tasks, checkpoints), got {s.shape}")
        _check(f"scores[{name!r}]", s[..., 0])
        with _seeded(seed):
            points, intervals = library.get_interval_estimates(
                {name: s}, lambda x: np.array([metrics.aggregate_iqm(x[..., k])
                                               for k in range(x.shape[-1])]), reps=reps)  # fmt: skip
        out[name] = np.vstack([points[name], intervals[name]])
    return out
