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
