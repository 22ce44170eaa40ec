"""The clairvoyant oracle: multi-start L-BFGS-B over the applied coil currents of each episode
(a local search: an achievable reference, not a certified limit).

See :mod:`capsule_env.oracle` for the method and what the numbers mean.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import Bounds, minimize

from capsule_env.common.validation import check_integer, check_nonnegative, check_positive
from capsule_env.engine.config import check_seed
from capsule_env.engine.layout import (
    BODY_DISP,
    BODY_VEL,
    BOGIE_DISP,
    BOGIE_VEL,
    COIL_CURRENT,
    OUT_BODY_ACC,
    OUT_FORCE,
    OUT_GUIDEWAY,
)
from capsule_env.evaluation.episodes import (
    EVALUATION_GUIDEWAY_SEED,
    RECORDED,
    Rollout,
    check_episode_length,
)
from capsule_env.oracle.lockstep import Lockstep
from capsule_env.oracle.plant import OracleEpisodes, RideObjective, adjoint_gradient
from capsule_env.oracle.starts import (
    DEFAULT_STARTS,
    START_NAMES,
    candidate_starts,
    named_starts,
    searched_starts,
)

__all__ = [
    "DEFAULT_STARTS",
    "EVALUATION_SEEDS",
    "START_NAMES",
    "OracleResult",
    "applied_currents",
    "clairvoyant_bound",
]

#: The seeds ``evaluate.py`` runs by default (``--seed 1000 --episodes 10``).
EVALUATION_SEEDS = tuple(range(1000, 1010))
#: Env arguments the oracle sets itself.
_OWN_ARGUMENTS = ("episode_length_s", "num_envs")


@dataclass
class OracleResult:
    """The clairvoyant search's outcome, one row per episode (``E`` episodes of ``T`` steps,
    ``S`` starts, ``R`` restart rounds).

    Every Wk figure is measured on the env's own plant (its adaptive substeps, its kernel):
    the currents replayed open loop.

    Attributes
    ----------
    seeds
        The episodes (episode ``k``: the single env seeded ``seeds[k]``).
    env_kwargs
        The env arguments of the episodes (``guideway_seed`` included).
    dt_s
        Control interval (s).
    currents_a
        (E, T) the best applied-current sequence found (A).
    signals
        ``capsule_env.evaluation.episodes.RECORDED`` signals of the best runs, (E, T) each
        (``current_command_a`` is the applied current; ``desired_force_n`` is 0: no force is
        requested), as the env records them.
    wk_rms_body_acc_m_s2
        (E,) the objective: Wk-weighted RMS body acceleration of the best sequence (m/s^2).
    start_names
        The starts, in order (a name of :data:`START_NAMES`, ``"constant:<A>"`` or
        ``"given:<j>"`` for an array given as ``starts[j]``), then the ``candidates``' names.
    start_wk_m_s2
        (E, S) Wk of each start's own sequence, before the search (m/s^2): for a controller's
        applied currents (a candidate), that controller's own Wk on the episode.
    final_wk_m_s2
        (E, S) Wk reached from each start (m/s^2); NaN where the start was not searched from.
    searched
        (E, S) whether the episode was searched from the start: every start, and the
        ``searched_candidates`` candidates of lowest own Wk of each episode.
    best_start
        (E,) the start the best sequence came from (a name of ``start_names``).
    best_stage
        (E,) how it got there: ``"search"`` (the search from that start), ``"own sequence"``
        (the start itself, unimproved: no search from it ended lower) or ``"restart"`` (a
        restart round from the best so far).
    restart_wk_m_s2
        (E, R) Wk reached by each restart round (m/s^2).
    iterations
        (E, S) L-BFGS-B iterations from each start (0 where not searched).
    messages
        (E, S) L-BFGS-B's stop messages (``"not searched"`` where not searched).
    max_stroke_m
        (E,) largest ``abs(stroke)`` of the best runs (m).
    terminated
        (E,) whether the best run crosses the env's bump stop (``stroke_limit_m``), where the
        env would have ended the episode.
    time_s
        (E,) wall time attributed to each episode: the call's total shared in proportion to
        each episode's objective evaluations (the episodes' searches run in lockstep).
    total_time_s
        Wall time of the whole call (s).
    evaluations
        (E,) objective evaluations (open-loop run + gradient) per episode.
    options
        The search's options (JSON-ready).
    """

    seeds: tuple[int, ...]
    env_kwargs: dict[str, Any]
    dt_s: float
    currents_a: np.ndarray
    signals: dict[str, np.ndarray]
    wk_rms_body_acc_m_s2: np.ndarray
    start_names: tuple[str, ...]
    start_wk_m_s2: np.ndarray
    final_wk_m_s2: np.ndarray
    searched: np.ndarray
    best_start: tuple[str, ...]
    best_stage: tuple[str, ...]
    restart_wk_m_s2: np.ndarray
    iterations: np.ndarray
    messages: list[list[str]]
    max_stroke_m: np.ndarray
    terminated: np.ndarray
    time_s: np.ndarray
    total_time_s: float
    evaluations: np.ndarray
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def rollout(self) -> Rollout:
        """The best runs as a :class:`~capsule_env.evaluation.episodes.Rollout` (current mode), for
        :func:`capsule_env.evaluation.episodes.episode_metrics` like any controller's."""
        return Rollout(self.signals, self.dt_s, self.terminated.copy(), "current")

    @property
    def spread_m_s2(self) -> np.ndarray:
        """(E,) max - min over the searched starts of the Wk each reached (m/s^2): how much
        the local search's answer depends on where it starts."""
        return np.nanmax(self.final_wk_m_s2, axis=1) - np.nanmin(self.final_wk_m_s2, axis=1)

    @property
    def restart_gain_m_s2(self) -> np.ndarray:
        """(E,) how much the restart rounds lowered the best of the searches and the starts'
        own sequences (m/s^2, >= 0)."""
        before = np.minimum(np.nanmin(self.final_wk_m_s2, axis=1), self.start_wk_m_s2.min(axis=1))
        return before - self.wk_rms_body_acc_m_s2

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary: per-episode rows and means (units in the keys)."""
        rows = []
        for k, seed in enumerate(self.seeds):
            mine = [(n, j) for j, n in enumerate(self.start_names) if self.searched[k, j]]
            named = lambda values, cast=float, mine=mine: {  # noqa: E731 - searched starts
                n: cast(values[j]) for n, j in mine
            }
            rows.append({
                "seed": seed,
                "wk_oracle_m_s2": float(self.wk_rms_body_acc_m_s2[k]),
                "start_wk_m_s2": dict(zip(self.start_names, map(float, self.start_wk_m_s2[k]))),
                "final_wk_m_s2": named(self.final_wk_m_s2[k]),
                "restart_wk_m_s2": [float(v) for v in self.restart_wk_m_s2[k]],
                "spread_over_starts_m_s2": float(self.spread_m_s2[k]),
                "restart_gain_m_s2": float(self.restart_gain_m_s2[k]),
                "best_start": self.best_start[k],
                "best_stage": self.best_stage[k],
                "iterations": named(self.iterations[k], int),
                "max_stroke_m": float(self.max_stroke_m[k]),
                "mean_current_a": float(np.mean(self.currents_a[k])),
                "terminated": bool(self.terminated[k]),
                "evaluations": int(self.evaluations[k]),
                "time_s": float(self.time_s[k]),
            })  # fmt: skip
        return {
            "seeds": list(self.seeds),
            "env_kwargs": dict(self.env_kwargs),
            "options": dict(self.options),
            "wk_oracle_mean_m_s2": float(np.mean(self.wk_rms_body_acc_m_s2)),
            "spread_over_starts_mean_m_s2": float(np.mean(self.spread_m_s2)),
            "restart_gain_mean_m_s2": float(np.mean(self.restart_gain_m_s2)),
            "best_starts": list(self.best_start),
            "total_time_s": float(self.total_time_s),
            "episodes_detail": rows,
        }


def applied_currents(rollout: Rollout, delay_steps: int) -> np.ndarray:
    """The currents a controller applied to the plant (E, T), from its recorded commands: the
    env applies the command of step ``t - delay_steps`` at step ``t`` (0 before). A start for
    :func:`clairvoyant_bound` (``starts=[applied_currents(...)]``)."""
    delay = check_integer("delay_steps", delay_steps, 0, 100)
    commands = np.asarray(rollout.signals["current_command_a"], dtype=float)
    applied = np.zeros_like(commands)
    applied[:, delay:] = commands[:, : commands.shape[1] - delay]
    return applied


# ------------------------------------------------------------------------------ the search
def _check_arguments(
    env_kwargs: Any, seeds: Any, options: dict[str, Any]
) -> tuple[dict[str, Any], tuple[int, ...]]:
    """The env arguments (with the evaluation's guideway seed by default) and the seeds.
    ``TypeError`` for an argument of the wrong type (a bool is not a number here),
    ``ValueError`` for a value out of range; both name the argument."""
    if env_kwargs is None:
        env_kwargs = {}
    if not isinstance(env_kwargs, Mapping):
        raise TypeError(f"env_kwargs must be a mapping of env arguments, got {env_kwargs!r}")
    for name in _OWN_ARGUMENTS:
        if name in env_kwargs:
            raise ValueError(f"env_kwargs must not set {name!r}: clairvoyant_bound sets it")
    if isinstance(seeds, (str, bytes)) or not isinstance(seeds, (Sequence, np.ndarray)):
        raise TypeError(f"seeds must be a non-empty sequence of integers, got {seeds!r}")
    if len(seeds) == 0:
        raise ValueError("seeds must be a non-empty sequence of integers, got an empty one")
    checked = tuple(check_seed(f"seeds[{k}]", s) for k, s in enumerate(seeds))
    check_positive("episode_length_s", options["episode_length_s"])
    check_integer("max_iter", options["max_iter"], 1, 1_000_000)
    check_integer("restarts", options["restarts"], 0, 100)
    check_integer("smooth_steps", options["smooth_steps"], 1, 1_000_000)
    check_integer("random_seed", options["random_seed"], 0, 2**63 - 1)
    check_integer("searched_candidates", options["searched_candidates"], 0, 1_000_000)
    check_positive("tol", options["tol"])
    if options["max_stroke_m"] is not None:
        check_positive("max_stroke_m", options["max_stroke_m"])
    check_nonnegative("stroke_penalty", options["stroke_penalty"])
    return {"guideway_seed": EVALUATION_GUIDEWAY_SEED, **env_kwargs}, checked


class _Search:
    """L-BFGS-B searches on the episodes' search plants, in lockstep (:class:`Lockstep`); the
    objective of episode ``k`` is scaled by its Wk at zero current and the currents by
    ``i_max`` (both searched quantities near 1)."""

    def __init__(
        self, episodes: OracleEpisodes, objective: RideObjective, max_iter: int, tol: float
    ) -> None:
        self.episodes, self.objective = episodes, objective
        n_ep, n_steps = episodes.n_episodes, episodes.n_steps
        _, out = episodes.run(np.arange(n_ep), np.zeros((n_ep, n_steps)))
        self.scale = np.maximum(objective.wk(out[:, :, OUT_BODY_ACC]), 1e-12)
        self.evaluations = np.zeros(n_ep, dtype=np.int64)
        self.options = {"maxiter": max_iter, "ftol": tol, "gtol": tol}

    def _evaluate(self, lane_episode: np.ndarray, batch: dict[int, np.ndarray]) -> dict:
        ep, i_max = self.episodes, self.episodes.i_max
        lanes = sorted(batch)
        eps = lane_episode[lanes]
        u = np.stack([np.clip(batch[lane], 0.0, 1.0) * i_max for lane in lanes])
        states, outputs = ep.run(eps, u)
        out = {}
        for j, lane in enumerate(lanes):
            k = eps[j]
            self.evaluations[k] += 1
            acc = outputs[j, :, OUT_BODY_ACC]
            value, _, d_acc, d_state = self.objective.value_and_derivatives(
                acc, states[j], ep.columns
            )
            grad = adjoint_gradient(*ep.linearise(k, states[j], acc, u[j]), d_acc, d_state)
            out[lane] = (value / self.scale[k], grad * (i_max / self.scale[k]))
        return out

    def env_wk(self, lanes: np.ndarray, currents: np.ndarray) -> np.ndarray:
        """Wk of currents (L, T) on episodes ``lanes`` (L,) with the env's own substeps."""
        outputs = self.episodes.run(lanes, currents, substeps="env")[1]
        return self.objective.wk(outputs[:, :, OUT_BODY_ACC])

    def ends(self, found: list[Any]) -> np.ndarray:
        """The currents (L, T) (A) where the searches ``found`` (:meth:`optimise`) ended."""
        return np.stack([np.clip(r.x, 0.0, 1.0) * self.episodes.i_max for r in found])

    def optimise(self, lane_episode: np.ndarray, currents: np.ndarray) -> list[Any]:
        """One search per lane (episode ``lane_episode[j]`` from currents ``currents[j]``);
        returns scipy's results, their ``x`` in units of ``i_max``."""
        lane_episode = np.asarray(lane_episode)

        def search(x0: np.ndarray) -> Callable:
            return lambda fun: minimize(
                fun, x0, jac=True, method="L-BFGS-B", bounds=Bounds(0.0, 1.0),
                options=self.options,
            )  # fmt: skip

        searches = {j: search(currents[j] / self.episodes.i_max) for j in range(len(currents))}
        found = Lockstep(lambda batch: self._evaluate(lane_episode, batch)).run(searches)
        return [found[j] for j in range(len(currents))]


def _smooth(currents: np.ndarray, steps: int, i_max: float) -> np.ndarray:
    """Moving average over ``steps`` control steps (edges: the nearest values repeated)."""
    if steps <= 1:
        return currents.copy()
    pad = np.pad(currents, ((0, 0), (steps // 2, steps - 1 - steps // 2)), mode="edge")
    kernel = np.full(steps, 1.0 / steps)
    smoothed = np.stack([np.convolve(row, kernel, mode="valid") for row in pad])
    return np.clip(smoothed, 0.0, i_max)


def clairvoyant_bound(
    env_kwargs: Mapping[str, Any] | None = None,
    seeds: Sequence[int] = EVALUATION_SEEDS,
    episode_length_s: float = 10.0,
    *,
    starts: Sequence[Any] = DEFAULT_STARTS,
    max_iter: int = 150,
    tol: float = 1e-9,
    restarts: int = 1,
    smooth_steps: int = 5,
    max_stroke_m: float | None = None,
    stroke_penalty: float = 1000.0,
    random_seed: int = 0,
    candidates: Mapping[str, Any] | None = None,
    searched_candidates: int = 1,
) -> OracleResult:
    """The lowest Wk-weighted RMS body acceleration a multi-start local search finds for a
    clairvoyant controller, per episode: the applied coil-current sequence ``u_t`` in
    ``[0, i_max]`` that the search ends at, knowing the whole guideway, setting the current
    applied to the plant directly (no noise, no delay, no inverse model; the coil lag, where the
    setting has one, stays: it is physics). An upper bound on the clairvoyant optimum, a lower
    bound on nothing: the name is historical.

    Parameters
    ----------
    env_kwargs
        The env's arguments (``setting``, ``damper``, ``vehicle_randomization``,
        ``control_rate_hz``...; ``guideway_seed`` defaults to
        :data:`~capsule_env.evaluation.episodes.EVALUATION_GUIDEWAY_SEED`). Arguments that only shape the
        controller's side (action mode, observation, noise, delay) change nothing here; the
        ``sim`` plant is the model ``inverse_model`` names (default Bi-exponential).
    seeds
        Episode ``k`` is the single env seeded ``seeds[k]`` (as
        :func:`capsule_env.evaluation.episodes.run_episodes` runs ``seed + k``); default 1000..1009.
    episode_length_s
        Episode length (s): a number > 0, long enough for the metrics' spectra
        (:func:`capsule_env.evaluation.episodes.check_episode_length`).
    starts
        The search's starts: names of :data:`START_NAMES`, constant currents (A), or
        current arrays, (T,) or (E, T) (e.g. :func:`applied_currents` of a controller's
        rollout). Each episode is searched from each start.
    max_iter
        L-BFGS-B iterations per search.
    tol
        L-BFGS-B's ``ftol`` on the objective relative to its value at zero current, and
        its ``gtol`` on the projected gradient of that relative objective per ``i_max``.
    restarts
        Rounds after the starts, each restarting one search per episode from the best
        sequence so far smoothed by a moving average over ``smooth_steps`` control steps
        (which frees the steps L-BFGS-B holds at a bound); a round's result is kept only
        where it is better.
    max_stroke_m
        Stroke beyond which the quadratic penalty acts (m); default the env's
        ``stroke_limit_m``, the bump stop where the env ends an episode.
    stroke_penalty
        The penalty's weight (m/s^2; 0 switches the constraint off): the search
        minimises ``Wk + stroke_penalty * mean_t(max(0, |s_t| - max_stroke_m) /
        max_stroke_m)^2``. An exterior penalty: a run may still overshoot slightly (see
        ``max_stroke_m`` and ``terminated`` in the result).
    random_seed
        Seed of the ``"random"`` start.
    candidates
        Named applied-current sequences, (T,) or (E, T) each (A), e.g. each evaluated
        controller's :func:`applied_currents` on these episodes (``evaluate.py --oracle``
        gives every controller on the oracle's plant). Each is replayed on every episode and
        kept where it is the lowest of all, so the oracle is never above a candidate's own Wk
        on the env's plant; per episode the ``searched_candidates`` of lowest own Wk are also
        searched from (like ``starts``).
    searched_candidates
        How many candidates each episode is searched from (0: none; each costs about as
        much as one start).

    Returns
    -------
    OracleResult
        Every figure measured on the env's own plant. How far from the global optimum: see
        :mod:`capsule_env.oracle`.

    Raises
    ------
    TypeError
        An argument of the wrong type, e.g. ``episode_length_s="1"`` or ``True`` (a bool is not
        a number here), ``max_iter=2.0``, ``seeds=5``, ``env_kwargs=[...]``; the message names
        the argument and what it accepts.
    ValueError
        A value out of range (``episode_length_s=0`` or too short for the metrics'
        spectra, ``max_iter=0``, an empty ``seeds``, an unknown start, a candidate named like
        a start or of the wrong shape, ``searched_candidates=-1``, an env argument the
        env refuses, ``env_kwargs`` setting ``episode_length_s`` or ``num_envs``); the message
        names the argument and its accepted range. An unknown env argument raises
        :class:`~capsule_env.common.validation.UnexpectedArgumentError`, both a ``TypeError`` and a
        ``ValueError``.
    """
    options = {
        "episode_length_s": episode_length_s, "max_iter": max_iter, "tol": tol,
        "restarts": restarts, "smooth_steps": smooth_steps, "max_stroke_m": max_stroke_m,
        "stroke_penalty": stroke_penalty, "random_seed": random_seed,
        "searched_candidates": searched_candidates,
    }  # fmt: skip
    env_args, seeds = _check_arguments(env_kwargs, seeds, options)
    t_start = time.perf_counter()
    episodes = OracleEpisodes(env_args, seeds, episode_length_s)
    check_episode_length(episode_length_s, episodes.dt_s)
    limit = episodes.config.stroke_limit_m if max_stroke_m is None else float(max_stroke_m)
    options["max_stroke_m"] = limit
    objective = RideObjective(episodes.n_steps, episodes.dt_s, limit, stroke_penalty)
    names, start_u = named_starts(episodes, starts, random_seed)
    own_names, own_u = candidate_starts(episodes, candidates, names)
    options["candidates"] = list(own_names)
    n_named, names = len(names), [*names, *own_names]
    start_u = np.concatenate([start_u, own_u])
    search = _Search(episodes, objective, int(max_iter), float(tol))
    found = _from_starts(search, start_u, n_named, int(searched_candidates))
    best, best_wk, best_index, stage = found.best()
    restart_wk = np.zeros((episodes.n_episodes, restarts))
    lanes = np.arange(episodes.n_episodes)
    for r in range(restarts):
        ends = search.ends(search.optimise(lanes, _smooth(best, smooth_steps, episodes.i_max)))
        restart_wk[:, r] = search.env_wk(lanes, ends)
        better = restart_wk[:, r] < best_wk
        best[better], best_wk[better] = ends[better], restart_wk[better, r]
        stage[better] = "restart"

    states, outputs = episodes.run(lanes, best, substeps="env")
    signals = _signals(states, outputs, best)
    total = time.perf_counter() - t_start
    stroke = np.max(np.abs(signals["stroke_m"]), axis=1)
    return OracleResult(
        seeds=seeds,
        env_kwargs=env_args,
        dt_s=episodes.dt_s,
        currents_a=best,
        signals=signals,
        wk_rms_body_acc_m_s2=objective.wk(signals["car_body_acceleration_m_s2"]),
        start_names=tuple(names),
        start_wk_m_s2=found.start_wk,
        final_wk_m_s2=found.final_wk,
        searched=found.searched,
        best_start=tuple(names[j] for j in best_index),
        best_stage=tuple(str(v) for v in stage),
        restart_wk_m_s2=restart_wk,
        iterations=found.iterations,
        messages=found.messages,
        max_stroke_m=stroke,
        terminated=stroke > episodes.config.stroke_limit_m,
        time_s=total * search.evaluations / max(int(search.evaluations.sum()), 1),
        total_time_s=total,
        evaluations=search.evaluations.copy(),
        options=options,
    )


@dataclass
class _Searched:
    """What the searches from the starts found (``S`` starts, ``E`` episodes, ``T`` steps):
    the starts' currents and their ends, (S, E, T) (a start not searched from ends where it
    began), and :class:`OracleResult`'s per-start fields."""

    start_u: np.ndarray
    end_u: np.ndarray
    start_wk: np.ndarray
    final_wk: np.ndarray
    searched: np.ndarray
    iterations: np.ndarray
    messages: list[list[str]]

    def best(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per episode the lowest Wk of every search's end and every start's own sequence:
        ``(currents (E, T), Wk (E,), the start's index (E,), stage (E,))`` (stage
        ``"search"`` or ``"own sequence"``; a tie goes to the search)."""
        episodes = np.arange(self.start_wk.shape[0])
        reached = np.where(self.searched, self.final_wk, np.inf)
        by_search, by_own = np.argmin(reached, axis=1), np.argmin(self.start_wk, axis=1)
        own = self.start_wk[episodes, by_own] < reached[episodes, by_search]
        index = np.where(own, by_own, by_search)
        currents = np.where(
            own[:, None], self.start_u[by_own, episodes], self.end_u[by_search, episodes]
        )
        wk = np.where(own, self.start_wk[episodes, by_own], reached[episodes, by_search])
        return currents, wk, index, np.where(own, "own sequence", "search").astype(object)


def _from_starts(
    search: _Search, start_u: np.ndarray, n_starts: int, per_episode: int
) -> _Searched:
    """Measure every start's own sequence (``start_u`` (S, E, T), the first ``n_starts`` the
    ``starts``, the rest candidates) on the env's plant, then search each episode from the
    starts :func:`~capsule_env.oracle.starts.searched_starts` picks, all in lockstep."""
    n_all, n_ep, n_steps = start_u.shape
    lanes = np.tile(np.arange(n_ep), n_all)  # lane s * E + k: start s on episode k
    start_wk = search.env_wk(lanes, start_u.reshape(-1, n_steps)).reshape(n_all, n_ep).T
    searched = searched_starts(start_wk, n_starts, per_episode)
    pairs = np.argwhere(searched.T)  # rows (s, k), start-major
    found = search.optimise(pairs[:, 1], start_u[pairs[:, 0], pairs[:, 1]])
    end_u = start_u.copy()
    end_u[pairs[:, 0], pairs[:, 1]] = search.ends(found)
    final_wk = np.full((n_ep, n_all), np.nan)
    final_wk[pairs[:, 1], pairs[:, 0]] = search.env_wk(pairs[:, 1], end_u[pairs[:, 0], pairs[:, 1]])
    iterations = np.zeros((n_ep, n_all), dtype=np.int64)
    messages = [["not searched"] * n_all for _ in range(n_ep)]
    for (s, k), result in zip(pairs, found):
        iterations[k, s] = result.nit
        messages[k][s] = str(result.message)
    return _Searched(start_u, end_u, start_wk, final_wk, searched, iterations, messages)


def _signals(states: np.ndarray, outputs: np.ndarray, currents: np.ndarray) -> dict:
    """The evaluation's recorded signals (``RECORDED``) of runs, as the env writes them."""
    after = states[:, 1:]
    signals = {
        "car_body_displacement_m": after[..., BODY_DISP],
        "bogie_displacement_m": after[..., BOGIE_DISP],
        "car_body_acceleration_m_s2": outputs[..., OUT_BODY_ACC],
        "stroke_m": after[..., BODY_DISP] - after[..., BOGIE_DISP],
        "stroke_rate_m_s": after[..., BODY_VEL] - after[..., BOGIE_VEL],
        "damper_force_n": outputs[..., OUT_FORCE],
        "desired_force_n": np.zeros_like(currents),
        "current_command_a": currents.copy(),
        "coil_current_a": after[..., COIL_CURRENT],
        "guideway_elevation_m": outputs[..., OUT_GUIDEWAY],
    }
    assert set(signals) == set(RECORDED)
    return {name: np.ascontiguousarray(signals[name]) for name in RECORDED}
