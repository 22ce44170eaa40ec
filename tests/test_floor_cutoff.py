"""experiments/floor_cutoff.py: the rate ranges under the objective cutoff hold every
trajectory the plant runs below the cutoff (a diagnostic that must not cut off the truth)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def cutoff():
    mp = pytest.MonkeyPatch()
    mp.syspath_prepend(str(ROOT / "experiments"))  # it imports floor_branch by name
    spec = importlib.util.spec_from_file_location(
        "floor_cutoff", ROOT / "experiments" / "floor_cutoff.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module
    mp.undo()


@pytest.fixture(scope="module")
def window():
    from capsule_env.bounds import evaluation_kwargs
    from capsule_env.bounds.lifted import lift_episode
    from capsule_env.bounds.relaxation import damper_envelope
    from capsule_env.bounds.stroke import StrokeBranchProblem, side_cuts
    from capsule_env.oracle.plant import OracleEpisodes

    ep = OracleEpisodes(evaluation_kwargs({"setting": "sim"}), [1000], 0.02)
    lifted, p = lift_episode(ep, 0), ep.damper_params[0]
    return (
        ep,
        lifted,
        StrokeBranchProblem(lifted, damper_envelope(ep.code, p), side_cuts(ep.code, p)),
    )


def _runs(cutoff, ep, lifted, problem):
    """(J, rates) of rollouts the plant runs: the oracle's currents, 0 A, the maximum current,
    random currents."""
    from capsule_env.bounds.relaxation import FORCE_SCALE_N

    rng = np.random.default_rng(3)
    currents = [cutoff._oracle_currents([1000], 0.02)[0][0], np.zeros(ep.n_steps), np.full(ep.n_steps, ep.i_max),
                rng.uniform(0.0, ep.i_max, ep.n_steps), rng.uniform(0.0, ep.i_max, ep.n_steps)]  # fmt: skip
    out = []
    for c in currents:
        forces = cutoff._rollout(lifted, ep, 0, c)
        out.append((problem.ride(forces / FORCE_SCALE_N), lifted.affine(lifted.v_rows, forces)))
    return out


def test_ranges_hold_every_run_below_the_cutoff(cutoff, window):
    ep, lifted, problem = window
    runs = _runs(cutoff, ep, lifted, problem)
    j_all = [j for j, _ in runs]
    cuts = (None, max(j_all) * 1.001, min(j_all) * 1.001)
    ranges = [cutoff.rate_intervals(problem, ub) for ub in cuts]
    for ub, (lo, hi) in zip(cuts, ranges):
        assert np.all(lo <= hi)
        # every run below the cutoff lies inside (none is cut off); 1e-7 m/s: the ranges are
        # Clarabel's optima (interior point, gaps ~1e-9), not exact, on any CPU
        for j, v in runs:
            if ub is None or j <= ub:
                assert np.all(lo <= v + 1e-7) and np.all(v <= hi + 1e-7)
    # a lower cutoff is a subset of trajectories: it never widens a range
    for (lo_a, hi_a), (lo_b, hi_b) in zip(ranges, ranges[1:]):
        assert np.all(lo_b >= lo_a - 1e-7) and np.all(hi_b <= hi_a + 1e-7)


def test_bad_cutoff_is_one_line(cutoff):
    with pytest.raises(SystemExit, match="--cutoff must be"):
        cutoff.main(["--cutoff", "0.5"])
