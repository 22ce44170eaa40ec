"""The house of issue 26: a damper model is one module (or one ``register`` call), the plant
and the env run it without a line of kernel code naming it, the vehicle's equations are
written once, the compiler's machinery sits in ``capsule_env._jit``; issue 41: the layers
import nothing above them and no shim answers an old name.

The independent fact: a linear damper of coefficient ``c`` declared here, under a new name
and code, is the built-in ``passive`` damper with the same ``c``; its trajectories must be
those of ``passive`` bit for bit (the same arithmetic in the same order, compiled for another
model code)."""

from __future__ import annotations

import ast
import dataclasses
import importlib
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

import capsule_env
from capsule_env._jit import kernel_function
from capsule_env.dampers import DamperModel, DamperParamsBase, damper_force, make_damper, registry
from capsule_env.engine.layout import DAMPER_PARAM_NAMES
from capsule_env.engine.simulate import simulate
from capsule_env.envs import CapsuleSuspensionVectorEnv
from capsule_env.guideway import random_profile

PACKAGE = Path(capsule_env.__file__).parent
TOY_NAME, TOY_CODE, C = "toy_linear", 90, 1.1e4


@dataclasses.dataclass(frozen=True)
class ToyLinearDamper(DamperParamsBase):
    """``F = c v``, declared outside the package."""

    damping_n_s_per_m: float = C
    code: ClassVar[int] = TOY_CODE
    name: ClassVar[str] = TOY_NAME
    param_names: ClassVar[tuple[str, ...]] = ("damping_n_s_per_m",)


@kernel_function
def _toy_force(p, x, v, y, z, i, pre):
    return p[0] * v, 0.0


def _toy_linearise(p, i):
    zero = 0.0 * i
    return [(p[0] + zero, zero, zero, zero)]


TOY = DamperModel(
    name=TOY_NAME,
    code=TOY_CODE,
    params=ToyLinearDamper,
    param_names=ToyLinearDamper.param_names,
    force=_toy_force,
    linearise=_toy_linearise,
    uses_current=False,
)


@pytest.fixture
def toy():
    registry.register(TOY)
    yield TOY
    registry.unregister(TOY_NAME)


def test_a_registered_model_is_everywhere_a_model_is(toy):
    assert registry.model_named(TOY_NAME) is toy
    assert DAMPER_PARAM_NAMES[TOY_NAME] == ("damping_n_s_per_m",)
    damper = make_damper(TOY_NAME, damping_n_s_per_m=2.0e3)
    force, rates = damper_force(damper, [0.01, -0.02], [0.5, -0.25], 0.0)
    np.testing.assert_array_equal(force, [1.0e3, -0.5e3])  # c v, by hand
    np.testing.assert_array_equal(rates, 0.0)
    with pytest.raises(ValueError, match="must be new"):
        registry.register(dataclasses.replace(toy, name="another_name"))  # same code
    with pytest.raises(ValueError, match="built in"):
        registry.unregister("passive")


def test_registered_model_runs_the_plant_like_passive(toy):
    profile = random_profile(600.0, 0.25, seed=3)
    runs = {}
    for name in ("passive", TOY_NAME):
        damper = make_damper(name, damping_n_s_per_m=C)
        runs[name] = simulate(damper, profile, 0.25, 150.0, 0.0, duration_s=0.5, dt_s=0.002)
    assert runs["passive"].keys() == runs[TOY_NAME].keys()
    for key, value in runs["passive"].items():
        np.testing.assert_array_equal(runs[TOY_NAME][key], value, err_msg=key)
    assert np.ptp(runs["passive"]["damper_force_n"][1:]) > 10.0  # it did move


@pytest.mark.parametrize("num_envs", [1, 70])  # the serial kernel, and the threaded one
def test_registered_model_runs_the_env_like_passive(toy, num_envs):
    rollouts = {}
    for name in ("passive", TOY_NAME):
        env = CapsuleSuspensionVectorEnv(
            num_envs=num_envs, damper=name, damper_params={"damping_n_s_per_m": C},
            action_mode="current", episode_length_s=0.2,
        )  # fmt: skip
        obs = [env.reset(seed=7)[0].copy()]
        rng = np.random.default_rng(0)
        for _ in range(30):
            o, reward, _, _, info = env.step(rng.uniform(-1.0, 1.0, (num_envs, 1)))
            obs.append(np.concatenate([np.ravel(o), reward, info["damper_force_n"]]))
        rollouts[name] = obs
    for a, b in zip(rollouts["passive"], rollouts[TOY_NAME], strict=True):
        np.testing.assert_array_equal(a, b)


def _names_in(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    names |= {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    names |= {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
    return names


def test_no_kernel_source_names_a_damper_model():
    codes = {"PASSIVE", "REFERENCE", "BOUC_WEN", "TANH", "BI_EXPONENTIAL"}
    laws = {"spencer_force", "bouc_wen_force", "tanh_force", "bi_exponential_force"}
    files = [*sorted((PACKAGE / "plant").glob("*.py")), PACKAGE / "engine" / "kernels.py",
             PACKAGE / "dampers" / "dispatch.py", PACKAGE / "dampers" / "registry.py",
             PACKAGE / "dampers" / "inverse.py", PACKAGE / "engine" / "config.py"]  # fmt: skip
    for path in files:
        found = _names_in(path) & (codes | laws)
        assert not found, f"{path.relative_to(PACKAGE)} names {sorted(found)}"


def _imports(path: Path, package: str | None = None, *, in_functions: bool = False) -> set[str]:
    """Every module ``path`` imports, at any depth (in functions too; only there with
    ``in_functions``): ``from m import x``, ``import m``, ``from .m import x`` (resolved against
    ``package``, by default the file's own) and ``importlib.import_module("m")`` with a literal
    name."""
    if package is None:
        package = ".".join(path.parent.relative_to(PACKAGE.parent).parts)
    nodes = list(ast.walk(ast.parse(path.read_text())))
    if in_functions:
        functions = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)
        nodes = [n for f in nodes if isinstance(f, functions) for n in ast.walk(f)]
    found = set()
    for n in nodes:
        if isinstance(n, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - n.level + 1] if n.level else []
            found.add(".".join([*base, *([n.module] if n.module else [])]))
        elif isinstance(n, ast.Import):
            found |= {a.name for a in n.names}
        elif (isinstance(n, ast.Call) and getattr(n.func, "attr", getattr(n.func, "id", None))
              == "import_module" and n.args and isinstance(n.args[0], ast.Constant)):  # fmt: skip
            found.add(str(n.args[0].value))
    return found


def test_the_import_scanner_sees_every_form(tmp_path):
    """The layering rules below read :func:`_imports`; a rule is only as honest as the scanner
    (it read ``from m import x`` alone, so ``import numba.experimental.structref`` passed)."""
    source = tmp_path / "mod.py"
    source.write_text(
        "import importlib\n"
        "import numba.experimental.structref as structref\n"
        "from ..engine import kernels\n"
        "from . import rk4\n"
        "def f():\n"
        "    from capsule_env.envs import make\n"
        "    return importlib.import_module('capsule_env.engine.batch')\n"
    )
    assert _imports(source, package="capsule_env.plant") == {
        "importlib", "numba.experimental.structref", "capsule_env.engine",
        "capsule_env.plant", "capsule_env.envs", "capsule_env.engine.batch",
    }  # fmt: skip


def test_layering_of_the_house():
    # the damper models sit below the plant, the kernels, the env and the layout
    below = ("capsule_env._fastmath", "capsule_env.common.validation", "capsule_env._jit",
             "capsule_env.dampers.hysteresis", "capsule_env.dampers", "capsule_env.common.discover")  # fmt: skip
    for path in sorted((PACKAGE / "dampers").glob("*.py")):
        above = {
            m for m in _imports(path) if m.startswith("capsule_env") and not m.startswith(below)
        }
        assert not above, f"dampers/{path.name} imports {sorted(above)}"
    # the vehicle models sit below everything but the validation helpers
    for path in sorted((PACKAGE / "vehicles").glob("*.py")):
        above = {m for m in _imports(path) if m.startswith("capsule_env")
                 and not m.startswith(("capsule_env.common.validation", "capsule_env.common.discover",
                                       "capsule_env.vehicles"))}  # fmt: skip
        assert not above, f"vehicles/{path.name} imports {sorted(above)}"
    equations = {m for m in _imports(PACKAGE / "plant" / "equations.py") if "capsule_env" in m}
    assert equations <= {"capsule_env._jit"}  # the vehicle depends on no damper, no layout


def test_numba_machinery_only_in_jit():
    """Issue 41: numba's extension machinery (overload, intrinsic, StructRef, numba.core's
    internals) is imported by two modules only, at any depth. Allowed, and why:
    ``_jit.py``: the compiler's room (specialisation, the StructRef ``Bundle`` and its
    constructors, the cache locators in ``numba.core.caching``/``config``); ``_fastmath.py``:
    the LLVM intrinsics (``numba.extending.intrinsic``), which ``_jit`` itself imports.
    ``numba.core.errors`` (the public home of numba's warning and error classes, e.g. to
    filter ``NumbaIRAssumptionWarning``) is not machinery."""
    allowed = {"_jit.py", "_fastmath.py"}
    machinery = ("numba.extending", "numba.experimental", "numba.core")
    files = list(PACKAGE.rglob("*.py"))
    if not (PACKAGE / "agents").is_dir():  # the checkout: capsule_env.agents is agents/, beside
        files += (PACKAGE.parent / "agents").rglob("*.py")
    for path in files:
        if path.parent == PACKAGE and path.name in allowed:
            continue
        found = {m for m in _imports(path) if m.startswith(machinery)} - {"numba.core.errors"}
        assert not found, f"{path.relative_to(PACKAGE.parent)} imports {sorted(found)}"
    jit = _imports(PACKAGE / "_jit.py")
    assert {"numba.experimental", "numba.extending"} <= jit  # the rule is not vacuous


def test_the_plant_imports_nothing_above_it():
    """Issue 41: plant/simulate.py imported the kernel factory (inside its functions); the plant
    now reads only the layer below it and the packed layouts' table, at any depth."""
    above = ("capsule_env.engine", "capsule_env.envs", "capsule_env.evaluation",
             "capsule_env.agents", "capsule_env.oracle", "capsule_env.envelope",
             "capsule_env.sweep", "capsule_env.tasks")  # fmt: skip
    for folder in ("plant", "vehicles", "dampers", "guideway"):
        for path in sorted((PACKAGE / folder).glob("*.py")):
            found = {m for m in _imports(path) if m.startswith(above)} - {
                "capsule_env.engine.layout"
            }
            assert not found, f"{folder}/{path.name} imports {sorted(found)}"


def test_the_sweep_reads_the_learning_modules_through_one_door():
    """Issue 41: sweep/ imported agents' learning modules inside its functions (kinds.py and
    hyperparameters.py) and the oracle by name. The learning modules (the ``rl`` extra) are
    reached through sweep/_rl.py alone; the rest of the package is imported at module level,
    but for ``study`` in kinds.py (study imports kinds: a cycle)."""
    for path in sorted((PACKAGE / "sweep").glob("*.py")):
        if path.name == "_rl.py":
            continue
        learning = {m for m in _imports(path) if m.startswith("capsule_env.agents.learning")}
        assert not learning, f"sweep/{path.name} imports {sorted(learning)}"
        inner = {m for m in _imports(path, in_functions=True) if m.startswith("capsule_env")}
        allowed = {"capsule_env.sweep.study"} if path.name == "kinds.py" else set()
        assert inner <= allowed, (
            f"sweep/{path.name} imports {sorted(inner - allowed)} in a function"
        )
    # the reason for the door: the sweep, its gains and oracle kinds work without the rl extra
    code = (
        "import sys\n"
        "sys.modules['capsule_env.agents.learning'] = None\n"  # as if torch/SB3 were absent
        "from capsule_env.sweep import KINDS\n"
        "KINDS['gains'].accepted_keys(); KINDS['oracle'].unavailable()\n"
        "print(sorted(KINDS), 'torch' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["['gains',", "'oracle',", "'train']", "False"]


def test_every_builtin_model_is_one_module_with_its_model():
    for name in registry.DAMPER_NAMES:
        module = importlib.import_module(f"capsule_env.dampers.{name}")
        assert module.MODEL is registry.model_named(name)
        assert module.MODEL.params.param_names == module.MODEL.param_names


_DEPRECATION = {"DeprecationWarning", "PendingDeprecationWarning", "FutureWarning", "deprecated"}


def _called(node: ast.AST) -> str | None:
    target = node.func if isinstance(node, ast.Call) else node
    return getattr(target, "attr", getattr(target, "id", None))


def _shims(source: str) -> list[str]:
    """The deprecation shims in ``source``: a module-level ``__getattr__`` that warns (PEP 562
    old names), and any ``warn(...)`` of a deprecation category or ``@deprecated`` object."""
    tree = ast.parse(source)
    found = [f"line {f.lineno}: a module __getattr__ that warns" for f in tree.body
             if isinstance(f, ast.FunctionDef) and f.name == "__getattr__"
             and any(_called(n) == "warn" for n in ast.walk(f) if isinstance(n, ast.Call))]  # fmt: skip
    for n in ast.walk(tree):
        decorators = getattr(n, "decorator_list", [])
        if any(_called(d) == "deprecated" for d in decorators):
            found.append(f"line {n.lineno}: @deprecated")
        if isinstance(n, ast.Call) and _called(n) == "warn":
            names = {
                _called(x) for a in [*n.args, *(k.value for k in n.keywords)] for x in ast.walk(a)
            }
            if names & _DEPRECATION:
                found.append(f"line {n.lineno}: warns {sorted(names & _DEPRECATION)}")
    return found


def test_no_deprecation_shims():
    """Issue 41: the shims for an API nobody outside used are gone (dampers/compat.py, the
    module ``__getattr__`` of dampers and env_kernel, the ``floats`` properties of CapsuleBatch
    and EnvState): no module of the package answers an old name with a warning. A module
    ``__getattr__`` that imports lazily without a warning (identification's ``plot_fits``,
    matplotlib on first use) is not a shim."""
    offenders = {str(p.relative_to(PACKAGE)): found for p in PACKAGE.rglob("*.py")
                 if (found := _shims(p.read_text()))}  # fmt: skip
    assert not offenders, offenders
    assert not (PACKAGE / "dampers" / "compat.py").exists()
    # the checker sees the forms a shim takes (the text search it replaced missed the first)
    shim = (
        "import warnings\n"
        "def __getattr__(name):\n"
        "    warnings.warn(f'{name} moved', FutureWarning, stacklevel=2)\n"
        "class Batch:\n"
        "    @property\n"
        "    def floats(self):\n"
        "        warnings.warn('use params', category=DeprecationWarning)\n"
        "    @deprecated('use new')\n"
        "    def old(self): ...\n"
    )
    assert [line.split(":")[0] for line in _shims(shim)] == ["line 2", "line 9", "line 3", "line 7"]
    assert _shims("def __getattr__(name):\n    import matplotlib\n    return matplotlib\n") == []


def test_howto_damper_model_snippet_runs_as_a_script(tmp_path):
    """docs/howto-damper-model.md's registered model runs the env as the plant and as the
    inverted model (a user's script: a fresh folder, only the installed package)."""
    page = PACKAGE.parent / "docs" / "howto-damper-model.md"
    (snippet,) = re.findall(r"^```python\n(.*?)^```$", page.read_text(), flags=re.S | re.M)
    (tmp_path / "model.py").write_text(snippet)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    env.pop("PYTHONPATH", None)
    done = subprocess.run([sys.executable, "model.py"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    assert len(lines) == 2 and all("damper force" in line for line in lines)
    forces = [np.array(line.split("[")[-1].rstrip("]").split(), float) for line in lines]
    assert all(np.all(np.isfinite(f)) and np.ptp(f) > 1.0 for f in forces)
