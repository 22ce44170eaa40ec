"""Package discovery only (everything else is in pyproject.toml).

setuptools' ``find`` in pyproject.toml cannot combine a discovered tree with the two folders
that ``package-dir`` maps into it (``agents/`` -> ``capsule_env.agents``, ``hyperparams/`` ->
``capsule_env.hyperparams``), so the union is made here: every folder under ``capsule_env/``
(data folders such as ``pretrained/`` without an ``__init__.py`` too) is found, none is
listed by hand.
"""

from setuptools import find_namespace_packages, setup

setup(
    packages=find_namespace_packages(
        include=["capsule_env", "capsule_env.*"], exclude=["*.__pycache__", "*.__pycache__.*"]
    )
    + ["capsule_env.agents", "capsule_env.hyperparams"]
)
