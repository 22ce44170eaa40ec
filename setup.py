"""Package discovery only (everything else is in pyproject.toml).

setuptools' ``find`` in pyproject.toml cannot combine a discovered tree with the two folders
that ``package-dir`` maps into it (``agents/`` -> ``capsule_env.agents``, ``hyperparams/`` ->
``capsule_env.hyperparams``), so the union is made here: every folder under ``capsule_env/``
and under ``agents/`` (data folders such as ``pretrained/`` without an ``__init__.py`` too) is
found, none is listed by hand.
"""

from setuptools import find_namespace_packages, setup

_NOT_CACHES = ["*.__pycache__", "*.__pycache__.*", "__pycache__", "__pycache__.*"]

setup(
    packages=find_namespace_packages(include=["capsule_env", "capsule_env.*"], exclude=_NOT_CACHES)
    + ["capsule_env.agents", "capsule_env.hyperparams"]
    # agents/'s own folders (controllers/, learning/): found under it, installed under the name
    + [
        f"capsule_env.agents.{p}"
        for p in find_namespace_packages(where="agents", exclude=_NOT_CACHES)
    ]
)
