"""Statistics of learned results the way the RL community reports them (rliable).

Agarwal, Schwarzer, Castro, Courville & Bellemare, "Deep reinforcement learning at the edge of
the statistical precipice", NeurIPS 2021: with a handful of training seeds, a mean or a median
hides how uncertain a result is. The protocol, on scores normalised per task:

- the **interquartile mean** (IQM: the mean of the middle 50 % of all runs x tasks scores) with a
  95 % **stratified bootstrap** confidence interval (runs resampled within each task);
- the **probability of improvement** ``P(X > Y)`` of one algorithm over another (a Mann-Whitney
  statistic averaged over tasks), with its interval;
- **sample-efficiency curves**: the IQM and its interval at every checkpoint of training.

Those intervals resample the training seeds only: each run's figure is its mean over the same
evaluation episodes, so they say nothing of how the comparison would move on other episodes.
:func:`paired_ratio_interval` compares a learned group with a classical law on the same
episodes and resamples both: the seeds, and the episodes jointly for the group and the law.

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

__all__ = ["Estimate", "normalised_scores", "iqm", "probability_of_improvement", "iqm_curves",
           "paired_ratio_interval"]  # fmt: skip


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
        raise ImportError("capsule_env.evaluation.rl_statistics needs rliable: pip install "
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


_RESAMPLED = ("both", "seeds", "episodes")


def _check_paired(group_wk, law_wk, reps: int, statistic: str, resample: str, seed: int):
    """The arrays of :func:`paired_ratio_interval`, checked; ``ValueError`` naming the
    parameter otherwise."""
    if resample not in _RESAMPLED:
        raise ValueError(f"resample must be one of {', '.join(_RESAMPLED)}, got {resample!r}")
    group, law = np.asarray(group_wk, dtype=float), np.asarray(law_wk, dtype=float)
    fewest = 1 if resample == "episodes" else 2
    if (group.ndim != 2 or group.shape[0] < fewest or group.shape[1] < 2
            or not np.all(np.isfinite(group))):  # fmt: skip
        raise ValueError(f"group_wk must be a finite (seeds, episodes) array with at least "
                         f"{fewest} seed(s) and 2 episodes, got shape {group.shape}")  # fmt: skip
    if law.shape != (group.shape[1],) or not np.all(np.isfinite(law)) or not law.mean() > 0:
        raise ValueError(f"law_wk must be finite, of shape ({group.shape[1]},) (the group's "
                         f"episodes) with a positive mean, got shape {law.shape}")  # fmt: skip
    if isinstance(reps, bool) or not isinstance(reps, (int, np.integer)) or reps < 100:
        raise ValueError(f"reps must be an integer >= 100, got {reps!r}")
    if statistic not in ("mean", "iqm"):
        raise ValueError(f"statistic must be 'mean' or 'iqm', got {statistic!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    return group, law


def paired_ratio_interval(group_wk: np.ndarray, law_wk: np.ndarray, *, statistic: str = "iqm",
                          reps: int = 20_000, seed: int = 0,
                          resample: str = "both") -> Estimate:  # fmt: skip
    """The ratio of a learned group's Wk to a classical law's on the same episodes, with a 95 %
    percentile-bootstrap interval that resamples the seeds and the episodes.

    ``group_wk``: ``(seeds, episodes)``, each run's Wk (m/s^2) on each evaluation episode;
    ``law_wk``: ``(episodes,)``, the law's Wk on the same episodes, in the same order. The
    ratio is ``A(mean over episodes of each seed) / mean(law_wk)`` with ``A`` the IQM over the
    seeds (``statistic="iqm"``, scipy's 25 % trimmed mean, as rliable's) or their mean
    (``"mean"``): below 1 the group rides better. Each of ``reps`` resamples draws the seeds
    with replacement and, independently, the episodes with replacement, the same episodes for
    the group and the law (paired: an episode's roughness cancels in the ratio); ``resample``
    ``"seeds"`` or ``"episodes"`` draws only one of them (the seed-only interval is the one
    conditional on these episodes; ``"episodes"`` accepts a single run, ``(1, episodes)``).
    Reproducible with ``seed``.

    Resampling both ways at once (Owen's "pigeonhole" bootstrap, Ann. Appl. Stat. 1(1), 2007)
    counts the seed x episode interaction about three times: the interval is wide where that
    interaction dominates, and with as few as 10 seeds x 10 episodes the percentile interval
    covers a little under 95 % where the seed and episode effects dominate (about 90-94 % in
    simulations, tests/test_rl_statistics.py); read it at that precision.
    """
    group, law = _check_paired(group_wk, law_wk, reps, statistic, resample, seed)
    seeds, episodes = group.shape
    rng = np.random.default_rng(seed)
    if resample == "seeds":
        counts = np.ones((reps, episodes))
    else:
        counts = rng.multinomial(episodes, np.full(episodes, 1.0 / episodes), size=reps)
    seed_means = counts @ group.T / episodes  # (reps, seeds): each seed on the drawn episodes
    if resample != "episodes":
        drawn = rng.integers(0, seeds, size=(reps, seeds))
        seed_means = np.take_along_axis(seed_means, drawn, axis=1)
    ratios = _aggregate(seed_means, statistic) / (counts @ law / episodes)
    value = float(_aggregate(group.mean(axis=1)[None, :], statistic)[0] / law.mean())
    low, high = np.percentile(ratios, [2.5, 97.5])
    return Estimate(value, float(low), float(high))


def _aggregate(seed_means: np.ndarray, statistic: str) -> np.ndarray:
    """Per row, the IQM (scipy's 25 % trimmed mean) or the mean of the seeds' figures."""
    if statistic == "mean":
        return seed_means.mean(axis=1)
    from scipy import stats

    return stats.trim_mean(seed_means, 0.25, axis=1)
