"""The package never uses its own deprecated names (issue 40: plant/reference_solver.py imported
``damper_eval`` through the moved-name shim of ``capsule_env.dampers`` and so raised its own
DeprecationWarning). Every module is imported in a fresh interpreter with the package's
deprecation warnings as errors."""

from __future__ import annotations

import pkgutil
import subprocess
import sys
from pathlib import Path

import capsule_env

ROOT = Path(__file__).resolve().parents[1]


def test_no_module_of_the_package_triggers_its_own_deprecation_warning():
    names = [m.name for m in pkgutil.walk_packages(capsule_env.__path__, "capsule_env.")
             if not m.name.endswith("__main__")]  # fmt: skip
    code = (
        "import importlib, sys, warnings\n"
        "warnings.filterwarnings('error', category=DeprecationWarning, module=r'capsule_env')\n"
        "for name in sys.argv[1:]:\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except ImportError as exc:\n"  # an optional extra (ray, rliable, ...) not installed
        "        if 'capsule_env' in str(exc):\n"
        "            raise\n"
    )
    done = subprocess.run([sys.executable, "-c", code, *names], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert "capsule_env.plant.reference_solver" in names


def test_the_reference_solver_runs_with_deprecation_warnings_as_errors():
    """Imported and used (a short open-loop run, each damper kind's path) with every
    DeprecationWarning an error, as a user's ``-W error::DeprecationWarning`` would have it."""
    code = (
        "import warnings\n"
        "warnings.simplefilter('error', DeprecationWarning)\n"
        "import numpy as np\n"
        "from capsule_env.dampers import BiExponentialDamper, BoucWenDamper\n"
        "from capsule_env.guideway import GuidewayParams, make_profile\n"
        "from capsule_env.plant.reference_solver import simulate_variable_step\n"
        "gw = GuidewayParams()\n"
        "profile = make_profile(gw, 0.1, seed=3)\n"
        "for damper in (BiExponentialDamper(), BoucWenDamper()):\n"
        "    out = simulate_variable_step(damper, profile, gw.spacing_m, gw.speed_mps, 1.0, 0.05)\n"
        "    assert np.isfinite(out['car_body_displacement_m']).all()\n"
        "    print(damper.name, int(out['nfev']))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert len(done.stdout.strip().splitlines()) == 2, done.stdout
