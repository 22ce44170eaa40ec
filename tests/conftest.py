"""Values shared by several test files (``from conftest import ...``).

The model values are typed in from docs/model.md, independently of the code's defaults: a test
that compares the code with them checks the code against the document, not against itself.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

ENV_ID = "CapsuleSuspension-v0"

DT = 0.005  # s: the control interval (200 Hz), also the sample interval of recorded signals
SPEED = 225.0  # m/s (810 km/h)
I_MAX = 1.5  # A: the coil's largest current

# docs/model.md section 2: car body and bogie masses, secondary (air spring) and levitation
# stiffnesses, the passive damper's damping.
M_C, M_B, K_S, K_P, C_S = 6000.0, 2400.0, 4.95e5, 2.25e6, 1.5e4

# docs/model.md section 4.2: the reference (Spencer) damper, Spencer's published values x 5 in
# force with u = 1.5 V/A * i; coefficients ``<name>a + <name>b * i``, coil lag 1 / eta.
SPENCER = dict(
    c0a=1.05e4,
    c0b=2.625e3,
    c1a=1.415e5,
    c1b=2.2125e3,
    aa=7.0e4,
    ab=5.2125e5,
    k0=2.345e4,
    k1=2.5e3,
    x0=0.0,
    g=3.63e6,
    b=3.63e6,
    A=301.0,
    eta=190.0,
)

# Env arguments that cover the action modes, settings, inverse models and observations.
ENV_COMBOS = [
    {"action_mode": "force", "setting": "sim"},
    {"action_mode": "force", "setting": "hils"},
    {"action_mode": "current", "setting": "sim"},
    {"action_mode": "current", "setting": "hils"},
    {"action_mode": "force", "setting": "sim", "inverse_model": "csdc"},
    {"action_mode": "force", "setting": "hils", "inverse_model": "tanh"},
    {"observation": "full_state", "setting": "hils"},
    {"observation": "measured", "setting": "hils"},
    {"observation": "measured", "setting": "sim", "action_mode": "current"},
    {"observation": "measured", "setting": "hils", "preview_points": 4},
    {"observation": "measured", "setting": "hils", "reward_acceleration_filter": "wk"},
]

# Skip reasons of the tests that need the optional ``rl`` extra (pytest.importorskip).
RL_EXTRA = "optional, in the rl extra: pip install 'capsule-env[rl]'"
NO_SB3 = f"stable-baselines3 is not installed ({RL_EXTRA})"
NO_YAML = f"PyYAML is not installed ({RL_EXTRA})"


def load_script(relative_path: str) -> ModuleType:
    """A script of the repository (``experiments/...py``) imported as a module, to call its
    functions."""
    path = Path(__file__).resolve().parents[1] / relative_path
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


NO_RAY = (
    "Ray Tune is not installed (optional, in the scale extra: pip install 'capsule-env[scale]')"
)


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray for the module (2 CPUs), shut down after it (the sweep's Ray tests)."""
    ray = pytest.importorskip("ray", reason=NO_RAY)
    pytest.importorskip("ray.tune", reason=NO_RAY)
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=2, include_dashboard=False)
    yield ray
    if started:
        ray.shutdown()


def residual_copy(folder: Path, source: str, law: str, name: str) -> Path:
    """The shipped residual policy ``source``'s files copied into ``folder`` as ``res.*``, its
    metadata's law set to ``law`` (scale 0.5) and its name to ``name``; returns the ``.zip``."""
    import json
    import shutil

    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR

    for suffix in (".zip", ".vecnormalize.pkl"):
        shutil.copy(PRETRAINED_DIR / f"{source}{suffix}", folder / f"res{suffix}")
    meta = json.loads((PRETRAINED_DIR / f"{source}.json").read_text())
    meta.update(name=name, residual={"law": law, "scale": 0.5})
    (folder / "res.json").write_text(json.dumps(meta))
    return folder / "res.zip"


class ResidualRig:
    """What a rig runs for a residual policy: ``law``'s action plus ``scale`` times the
    ``network``'s residual, combined as the export's contract states (in double precision,
    clipped to [-1, 1], then float32); the law restarts where an episode does."""

    def __init__(self, law, network, scale: float) -> None:
        self.law, self.network, self.scale = law, network, scale

    def predict(self, obs, episode_start=None):
        import numpy as np

        base = self.law.predict(obs, episode_start=episode_start)[0]
        residual = self.network.predict(obs.astype(np.float32), deterministic=True)[0]
        total = np.clip(np.float64(base) + self.scale * np.float64(residual), -1.0, 1.0)
        return total.astype(np.float32), None


def check_mpc_block(card: dict, cls: type) -> dict:
    """Assert that a contract's ``residual.base_law`` records every argument of ``cls``'s
    constructor, each with its units, and that the MPC's model assumes the env the residual was
    trained in (the contract's control period, delay, coil lag, force scale); the block."""
    import inspect

    block = card["residual"]["base_law"]
    assert block["rig_solves_qp"] is True and card["residual"]["rig_provides_law"] is True
    signature = inspect.signature(cls.__init__).parameters
    assert set(block["constructor"]) == set(signature) - {"self"}
    assert set(block["units"]) == set(block["constructor"])
    args = block["constructor"]
    assert args["dt_s"] == card["control"]["period_s"]
    assert args["delay_steps"] == card["control"]["delay_steps"]
    assert args["coil_time_constant_s"] == card["control"]["coil_time_constant_s"]
    assert args["max_force_n"] == card["action"]["max_force_n"]
    return block
