"""``VecEnv.set_options`` on the two SB3 VecEnvs: the envs take no reset option, so a non-empty
one is refused by name when it is set, not dropped at the next reset."""

from __future__ import annotations

import numpy as np
import pytest

from capsule_env.envs.declared_sb3 import DeclaredSB3VecEnv
from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

HALF = {"vehicle": "half_car", "setting": "hils", "observation": "measured"}


def _make(kind: str, num_envs: int = 2):
    if kind == "half":
        return DeclaredSB3VecEnv(num_envs, **HALF)
    return CapsuleSuspensionSB3VecEnv(num_envs)


@pytest.mark.parametrize("kind", ["half", "quarter"])
@pytest.mark.parametrize("options", [{"reset_mask": [True, False]}, [{}, {"speed_kmh": 600}]])
def test_a_reset_option_is_refused_by_name_when_set(kind, options):
    venv = _make(kind)
    with pytest.raises(ValueError, match=r"unknown reset option\(s\).*accepted: none"):
        venv.set_options(options)
    venv.reset()  # nothing was kept for the next reset: it resets as ever


@pytest.mark.parametrize("kind", ["half", "quarter"])
@pytest.mark.parametrize("options", ["reset_mask", [{}], [{}, {}, {}], [{}, "x"]])
def test_options_of_another_shape_are_refused(kind, options):
    venv = _make(kind)
    with pytest.raises(TypeError, match="options"):
        venv.set_options(options)


@pytest.mark.parametrize("kind", ["half", "quarter"])
def test_no_options_are_accepted_and_change_nothing(kind):
    plain, optioned = _make(kind), _make(kind)
    for venv in (plain, optioned):
        venv.seed(5)
    optioned.set_options(None)
    optioned.set_options({})
    optioned.set_options([{}, {}])
    assert np.array_equal(plain.reset(), optioned.reset())
