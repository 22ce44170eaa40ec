"""The installed package, as ``pip install 'capsule-env[rl]'`` gives it (a wheel, not this
checkout): its files, its import names, its commands, the shipped policies and hyperparameters
found from inside it, and a read-only installation (numba's cache moved, with one warning)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = {
    "capsule-evaluate",
    "capsule-train",
    "capsule-identify",
    "capsule-sweep",
    "capsule-export",
    "capsule-datasets",
}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built from this checkout (no network: the venv's setuptools)."""
    out = tmp_path_factory.mktemp("dist")
    # from a copy: pip builds in the source folder, and a stale build/ there could be packed
    source = tmp_path_factory.mktemp("source") / "capsule-env"
    shutil.copytree(ROOT, source, ignore=shutil.ignore_patterns(
        ".git", ".venv", "build", "*.egg-info", "__pycache__", "_build", "runs", "out"))  # fmt: skip
    cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
           "-w", str(out), str(source)]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    (path,) = out.glob("capsule_env-*.whl")
    return path


@pytest.fixture(scope="module")
def site(wheel, tmp_path_factory) -> Path:
    """The wheel installed by pip into a venv of its own; returns its site-packages.

    The venv sees this interpreter's installed dependencies (numpy, numba, torch, ...) through
    a ``.pth`` line naming their site-packages: a path line does not run the ``.pth`` files of
    the folder it names, so the checkout's editable install (its ``__editable__`` finder) stays
    off, and only what the wheel holds can be imported as ``capsule_env`` (issue 40: the
    unpacked wheel lacked ``capsule_env.dampers`` and the editable finder hid it)."""
    venv = tmp_path_factory.mktemp("venv") / "env"
    done = subprocess.run([sys.executable, "-m", "venv", str(venv)], capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    python = venv / "bin" / "python"
    code = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    packages = Path(subprocess.run([str(python), "-c", code], capture_output=True, text=True,
                                   check=True).stdout.strip())  # fmt: skip
    outer = [p for p in sys.path if p.endswith("site-packages") and Path(p).is_dir()]
    (packages / "outer_dependencies.pth").write_text("\n".join(outer) + "\n")
    install = [str(python), "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel)]
    done = subprocess.run(install, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return packages


def _python(site: Path) -> Path:
    """The venv interpreter whose site-packages ``site`` is (venv/lib/pythonX.Y/site-packages)."""
    return site.parents[2] / "bin" / "python"


def run_installed(site: Path, code: str, tmp_path: Path, **env: str):
    """``python -c code`` in the wheel's venv, outside the checkout, nothing on PYTHONPATH."""
    environ = {**os.environ, "MPLBACKEND": "Agg", **env}
    environ.pop("PYTHONPATH", None)
    return subprocess.run([str(_python(site)), "-c", textwrap.dedent(code)], cwd=tmp_path,
                          env=environ, capture_output=True, text=True, timeout=600)  # fmt: skip


def test_the_venv_imports_the_wheel_not_the_checkout(site, tmp_path):
    done = run_installed(site, "import capsule_env; print(capsule_env.__file__)", tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert Path(done.stdout.strip()).is_relative_to(site), done.stdout


def test_every_package_of_the_checkout_is_in_the_wheel(wheel):
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    for init in (ROOT / "capsule_env").rglob("__init__.py"):
        rel = init.relative_to(ROOT).as_posix()
        assert rel in names, f"{rel} is not in the wheel"
    for init in (ROOT / "agents").rglob("__init__.py"):  # installed as capsule_env.agents
        rel = "capsule_env/" + init.relative_to(ROOT).as_posix()
        assert rel in names, f"{rel} is not in the wheel (issue 41: agents/controllers/ was not)"
    assert not any(n.startswith(("tests/", "benchmarks/", "experiments/", "docs/")) for n in names)


def test_the_installed_evaluate_command_evaluates(site, tmp_path):
    command = site.parents[2] / "bin" / "capsule-evaluate"
    environ = {**os.environ, "MPLBACKEND": "Agg"}
    environ.pop("PYTHONPATH", None)
    done = subprocess.run([str(command), "--setting", "sim", "--episodes", "1",
                           "--episode-length", "0.5", "--controllers", "skyhook-biexp",
                           "--no-shipped-policy"], cwd=tmp_path, env=environ,
                          capture_output=True, text=True, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert "skyhook-biexp" in done.stdout


def test_the_wheel_installs_one_top_level_name_with_its_data_and_commands(wheel):
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
        entry_points = next(n for n in names if n.endswith("entry_points.txt"))
        scripts = zf.read(entry_points).decode()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"capsule_env"}  # no generic 'agents' beside it
    for needed in ("capsule_env/agents/__init__.py", "capsule_env/agents/controllers/tuned_gains.json",
                   "capsule_env/hyperparams/ppo.yml", "capsule_env/evaluation/evaluate.py",
                   "capsule_env/agents/learning/train.py", "capsule_env/pretrained/ppo-measured.zip",
                   "capsule_env/pretrained/ppo-measured.vecnormalize.pkl"):  # fmt: skip
        assert needed in names, needed
    for script in SCRIPTS:
        assert f"{script} = capsule_env." in scripts, script


def test_the_installed_package_finds_its_policies_and_hyperparameters(site, tmp_path):
    pytest.importorskip("stable_baselines3", reason="the rl extra is not installed")
    code = """
        import importlib.util, json
        import capsule_env, capsule_env.agents
        from capsule_env.agents.learning.sb3_policy import shipped_policies, shipped_policy_paths
        from capsule_env.agents.learning.training import HYPERPARAMS_DIR
        from capsule_env.agents.learning.hyperparams import load_hyperparams
        paths = shipped_policy_paths()
        print(json.dumps({
            "package": capsule_env.__file__, "agents": capsule_env.agents.__file__,
            "policies": paths, "names": sorted(shipped_policies()),
            "ppo_timesteps": load_hyperparams(HYPERPARAMS_DIR / "ppo.yml")["n_timesteps"],
            "bare_agents": importlib.util.find_spec("agents") is not None,
        }))
    """
    done = run_installed(site, code, tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(got["package"]).is_relative_to(site) and Path(got["agents"]).is_relative_to(site)
    assert len(got["policies"]) >= 3
    assert all(Path(p).is_relative_to(site) for p in got["policies"])
    assert {"ppo-hils", "ppo-measured", "ppo-preview"} <= set(got["names"])
    assert float(got["ppo_timesteps"]) > 0
    assert not got["bare_agents"]


def test_the_installed_package_reads_its_tuned_gains_from_inside_it(site, tmp_path):
    """A missing tuned_gains.json reads as ``{}`` (every law on its reconstructed defaults), so
    the file is checked where the installed package looks for it, not only in the wheel."""
    code = """
        import json
        from capsule_env.agents.controllers.tuned import TUNED_GAINS_PATH, load_tuned
        print(json.dumps({"path": str(TUNED_GAINS_PATH), "exists": TUNED_GAINS_PATH.is_file(),
                          "controllers": sorted(load_tuned().get("controllers", {}))}))
    """
    done = run_installed(site, code, tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(got["path"]).is_relative_to(site) and got["exists"], got["path"]
    assert "lqr-clipped-biexp" in got["controllers"], got["controllers"]


def test_the_installed_evaluate_script_prints_its_help(site, tmp_path):
    environ = {**os.environ, "MPLBACKEND": "Agg"}
    environ.pop("PYTHONPATH", None)
    done = subprocess.run([str(site.parents[2] / "bin" / "capsule-evaluate"), "--help"],
                          cwd=tmp_path, env=environ, capture_output=True, text=True,
                          timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert "--controllers" in done.stdout and "--episodes" in done.stdout


@pytest.mark.parametrize(
    "module", ["capsule_env.evaluation.evaluate", "capsule_env.agents.learning.train"]
)
def test_the_installed_commands_run(site, tmp_path, module):
    if module == "capsule_env.agents.learning.train":
        pytest.importorskip("stable_baselines3", reason="the rl extra is not installed")
    done = run_installed(site, f"import runpy, sys; sys.argv = ['{module}', '--help']; "
                         f"runpy.run_module('{module}', run_name='__main__', alter_sys=True)", tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert "--episodes" in done.stdout or "--total-timesteps" in done.stdout


def test_a_read_only_installation_caches_its_kernels_in_a_temporary_folder(site, tmp_path):
    """Neither the package's folder nor the home folder can be written (simulated: numba's
    writability check fails everywhere but the temporary folder, as it would for a user
    without rights there; the tests may run as root, for whom chmod proves nothing). Today's
    numba raises 'cannot cache function ...: no locator available' at import."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    code = f"""
        import os, runpy, sys, tempfile, warnings
        from numba.core import caching
        base = getattr(caching, "_CacheLocator")
        writable = os.path.realpath({str(tmp)!r})
        original = base.ensure_cache_path
        def read_only(self):
            if not os.path.realpath(self.get_cache_path()).startswith(writable):
                raise PermissionError(13, "read-only", self.get_cache_path())
            original(self)
        base.ensure_cache_path = read_only
        warnings.simplefilter("always")
        with warnings.catch_warnings(record=True) as seen:
            import capsule_env.envs  # noqa
        from capsule_env._jit import NumbaCacheWarning, fallback_cache_dir
        ours = [w for w in seen if issubclass(w.category, NumbaCacheWarning)]
        assert len(ours) == 1, [str(w.message) for w in seen]
        assert "NUMBA_CACHE_DIR" in str(ours[0].message)
        sys.argv = ["evaluate.py", "--setting", "sim", "--episodes", "1", "--episode-length",
                    "0.5", "--controllers", "skyhook-biexp", "--no-shipped-policy"]
        try:
            runpy.run_module("capsule_env.evaluation.evaluate", run_name="__main__", alter_sys=True)
        except SystemExit as exc:
            assert exc.code in (0, None), exc.code
        cached = list(fallback_cache_dir().rglob("*.nbi"))
        assert cached, "nothing was cached in the fallback folder"
        print("cached", len(cached))
    """
    env = {"TMPDIR": str(tmp), "NUMBA_CACHE_DIR": ""}
    done = run_installed(site, code, tmp_path, **env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "skyhook-biexp" in done.stdout and "cached" in done.stdout


def test_a_writable_installation_warns_nothing(site, tmp_path):
    code = """
        import warnings
        warnings.simplefilter("error")
        import capsule_env
        from numba.core import config
        print("cache dir", repr(config.CACHE_DIR))
    """
    done = run_installed(site, code, tmp_path, NUMBA_CACHE_DIR="")
    assert done.returncode == 0, done.stderr[-3000:]
    assert "cache dir ''" in done.stdout


#: The top layer: the commands, which put the controllers and the env together.
COMMANDS = (
    "evaluation/evaluate.py",
    "evaluation/tables.py",
    "evaluation/half_car.py",  # the half-car task's evaluation (a command) and its figure
    "evaluation/half_car_preview.py",  # the preview variant's, on half_car.py's
    "evaluation/half_car_figure.py",
    "sweep/",
    "export/",
    "datasets/",
)  # + evaluate.py's tables
#: Their modules, which nothing below them imports.
UPPER = ("capsule_env.agents", "capsule_env.evaluation.evaluate", "capsule_env.evaluation.tables",
         "capsule_env.evaluation.half_car", "capsule_env.evaluation.half_car_preview")  # fmt: skip


def test_the_library_never_imports_the_controllers_or_the_scripts():
    """Imports run one way: the env and the physics (capsule_env) <- the controllers
    (capsule_env.agents) <- the commands (capsule_env.evaluation.evaluate, train, the sweep)."""
    import ast

    package = ROOT / "capsule_env"
    offenders = []
    for path in package.rglob("*.py"):
        rel = path.relative_to(package).as_posix()
        if rel.startswith((*COMMANDS, "agents/")):  # agents/: a link in a test checkout
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            for name in names:
                if name.split(".")[0] in ("agents", "evaluate", "train") or any(
                    name == u or name.startswith(u + ".") for u in UPPER
                ):
                    offenders.append(f"{rel}: {name}")
    assert not offenders, offenders
