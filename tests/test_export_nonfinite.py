"""The export's rule for a non-finite observation, as a rig builds and feeds the files.

A residual policy's C ``capsule_policy`` gives the residual 0 on a row holding a NaN or inf
(:mod:`capsule_env.export.c_export`). Rigs often build with ``-ffast-math`` (``-Ofast``), under
which the compiler may assume every float finite and drop C99's ``isfinite``: the rule must hold
there too.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import NO_SB3

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, SB3Policy  # noqa: E402

from capsule_env.export import export_policy  # noqa: E402
from capsule_env.export.c_build import C_FLAGS, CPolicy, build_shared, c_compiler  # noqa: E402

NAME = "residual-ppo-mpc"


@pytest.mark.parametrize("flag", ["-ffast-math", "-Ofast"])
def test_the_c_residual_is_0_on_a_non_finite_row_under_fast_math(flag, tmp_path):
    if c_compiler() is None:
        pytest.skip("no C compiler on this machine (cc, gcc, clang or $CC)")
    files = export_policy(NAME, tmp_path / "out", "c")
    lib = CPolicy(build_shared(files[f"{NAME}.c"], tmp_path, (*C_FLAGS, flag)), 9)
    obs = np.zeros((5, 9), np.float32)
    obs[:, 2] = np.linspace(-0.01, 0.01, 5)  # strokes: the network's residual is not 0 there
    obs[1, 2], obs[2, 0], obs[3, 8] = np.nan, np.inf, -np.inf
    bad = ~np.all(np.isfinite(obs), axis=1)
    network = SB3Policy.load(PRETRAINED_DIR / f"{NAME}.zip")
    expected, _ = network.predict(obs[~bad], deterministic=True)
    assert np.all(np.abs(expected) > 1e-3)  # a dropped rule would not give 0 by chance
    got = lib.policy(obs)
    assert np.all(got[bad] == 0.0), got[bad]
    np.testing.assert_allclose(got[~bad], expected, rtol=0, atol=1e-4)

