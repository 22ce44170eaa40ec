"""The certified floor's ``seeds`` take what the package's other seed lists take
(``clairvoyant_bound``'s: a list, tuple, range or 1-D numpy array of integers, each checked as
the env's ``reset(seed=...)`` checks a seed, in ``[0, 2**63)``), and refuse the rest naming
``seeds`` and the range."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.bounds import check_floor
from capsule_env.engine.config import check_seed

SIM = {"setting": "sim"}


@pytest.mark.parametrize(
    "seeds",
    [np.arange(1000, 1003), np.array([1000, 1001, 1002], dtype=np.uint32),
     [np.int64(1000), np.int32(1001), 1002]],
)  # fmt: skip
def test_numpy_integer_seeds_run_the_same_episodes_as_plain_ones(seeds):
    _, plain_seeds, _ = check_floor(SIM, [1000, 1001, 1002], 0.1)
    episodes, checked, _ = check_floor(SIM, seeds, 0.1)
    assert checked == plain_seeds == (1000, 1001, 1002)
    assert all(type(s) is int for s in checked)
    assert episodes.seeds == (1000, 1001, 1002)


@pytest.mark.parametrize("seed", [True, 2**63, 2**64, -1, 1.0, np.float64(3.0), np.bool_(True)])
def test_a_seed_the_env_refuses_is_refused_naming_seeds_and_the_range(seed):
    with pytest.raises((TypeError, ValueError)):
        check_seed("seed", seed)  # the env's own check refuses it too
    with pytest.raises((TypeError, ValueError), match=r"seeds\[1\] must be .*\[0, 2\*\*63\)"):
        check_floor(SIM, [1000, seed], 0.1)


@pytest.mark.parametrize(
    "seeds, error",
    [(np.int64(3), TypeError), (3, TypeError), ("12", TypeError), (np.array([[1, 2]]), TypeError),
     (np.array([1.0, 2.0]), TypeError), ([], ValueError), (np.arange(0), ValueError)],
)  # fmt: skip
def test_seeds_that_are_not_a_list_of_seeds_are_refused_by_name(seeds, error):
    with pytest.raises(error, match=r"seeds.*\[0, 2\*\*63\)"):
        check_floor(SIM, seeds, 0.1)


def test_evaluate_floor_check_takes_a_numpy_seed_range():
    from capsule_env.evaluation.floor_block import check_floor_settings

    check_floor_settings({}, ["sim"], np.arange(1000, 1002), 0.1)  # refused with TypeError before
    with pytest.raises(ValueError, match=r"--floor in the sim setting: seeds\[0\] .*2\*\*63"):
        check_floor_settings({}, ["sim"], np.array([-1, 0]), 0.1)
