"""Sphinx configuration of the capsule-env documentation.

Build (from the repository root, with the ``docs`` extra installed)::

    sphinx-build -W --keep-going -b html docs docs/_build/html

Markdown pages are read by MyST; the API reference is built from the docstrings by autodoc
(numpy-style sections through napoleon), so the package and its controllers (``capsule_env.agents``, the checkout's ``agents/``) must be
importable (the ``dev`` extra installs torch and stable-baselines3 for ``capsule_env.agents.learning.sb3_policy``).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # evaluate.py and train.py live at the root, beside capsule_env/

import capsule_env  # noqa: E402

project = "capsule-env"
author = "capsule-env contributors"
copyright = "capsule-env contributors, MIT licence"
release = capsule_env.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]

# MyST: $...$ math, ``:::`` fences, and anchors for headings down to ### so that pages can
# link to each other's sections ([text](env.md#observation-sets)).
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

# autodoc: members in source order, with the signature's type hints in the description.
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}
# Our docstrings are numpy-style; the Google style stays on for the docstrings our classes
# inherit from Gymnasium and stable-baselines3 (``Env.step``, ``VecEnv.step_async``, ...).
napoleon_google_docstring = True
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# "Attributes" sections as fields of the class, not as separate entries that would clash with
# the properties of the same name that autodoc documents.
napoleon_use_ivar = True

html_theme = "furo"
html_title = f"capsule-env {release}"
# docs/_static/custom.css: wide tables fit (smaller text, wrapping cells) or scroll visibly.
html_static_path = ["_static"]
html_css_files = ["custom.css"]


# ---- Gymnasium-style env docstrings ---------------------------------------------------------
# Gymnasium writes an env's class docstring with Markdown structure (``## Action Space``
# headings, pipe tables) and RST inline markup; Gymnasium's own site renders them that way.
# autodoc reads RST, where ``## x`` is a paragraph and ``| a | b |`` a line block, so the env
# classes' headings become rubrics and their pipe tables list-tables before autodoc parses them.
# Nothing else is changed, and only in subclasses of Gymnasium's Env and VectorEnv.

_MD_HEADING = re.compile(r"^(\s*)#{2,6} (.+?)\s*$")
_MD_TABLE_RULE = re.compile(r"^\s*\|[\s:|-]+\|\s*$")


def _markdown_structure_to_rst(lines: list[str]) -> list[str]:
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        heading = _MD_HEADING.match(line)
        if heading:
            out += [f"{heading[1]}.. rubric:: {heading[2]}", ""]
            i += 1
            continue
        if (
            line.lstrip().startswith("|")
            and i + 1 < len(lines)
            and _MD_TABLE_RULE.match(lines[i + 1])
        ):
            indent = line[: len(line) - len(line.lstrip())]
            out += [f"{indent}.. list-table::", f"{indent}   :header-rows: 1", ""]
            j = i
            while j < len(lines) and lines[j].lstrip().startswith("|"):
                if j != i + 1:  # the |---|---| rule
                    cells = [c.strip() for c in lines[j].strip().strip("|").split("|")]
                    out += [
                        f"{indent}   {'* -' if k == 0 else '  -'} {cell}"
                        for k, cell in enumerate(cells)
                    ]
                j += 1
            out.append("")
            i = j
            continue
        out.append(line)
        i += 1
    return out


def _gymnasium_docstring(app, what, name, obj, options, lines):
    from gymnasium import Env
    from gymnasium.vector import VectorEnv

    if what == "class" and isinstance(obj, type) and issubclass(obj, (Env, VectorEnv)):
        lines[:] = _markdown_structure_to_rst(lines)


# ---- the house shorthand of numpy-style entries ----------------------------------------------
# Most docstrings here write a Parameters/Attributes/Returns entry as ``name : description`` on
# one line (the unit inside the description), where numpy style puts the *type* after the colon.
# Napoleon would print those descriptions as types. An entry whose text after `` : `` does not
# look like a type (``float``, ``numpy.ndarray``, ``float or None``, ``Foo, optional``) is
# rewritten to the numpy form ``name`` + indented description; true numpy entries are left as
# they are.

_FIELD_SECTIONS = {"Parameters", "Other Parameters", "Attributes", "Returns", "Yields"}
_ENTRY = re.compile(r"^(?P<name>[^\s:][^:]*?) : (?P<rest>.+)$")
_TYPE = re.compile(r"^[\w.]+(\[[^\]]*\])?((, | or | of )[\w.]+(\[[^\]]*\])?)*(, optional)?$")


def _shorthand_entries_to_numpy(lines: list[str]) -> list[str]:
    out: list[str] = []
    section = None
    for i, line in enumerate(lines):
        following = lines[i + 1].strip() if i + 1 < len(lines) else ""
        if line.strip() and following and set(following) == {"-"}:
            section = line.strip()
        entry = _ENTRY.match(line)
        if section in _FIELD_SECTIONS and entry and not _TYPE.match(entry["rest"].strip()):
            out += [entry["name"], f"    {entry['rest']}"]
        else:
            out.append(line)
    return out


def _house_shorthand(app, what, name, obj, options, lines):
    lines[:] = _shorthand_entries_to_numpy(lines)


# ---- one-line attribute comments -------------------------------------------------------------
# Napoleon reads the first line of an attribute's or property's docstring as ``type: text``
# (Google style), so ``#: Mode bands (Hz) of the default plant: first (body) and second ...``
# would print "Mode bands (Hz) of the default plant" as a type. Those docstrings are kept as
# written: no attribute docstring here starts with a type.

_ATTRIBUTE_DOCSTRINGS: dict[str, list[str]] = {}


def _keep_attribute_docstring(app, what, name, obj, options, lines):
    if what in ("attribute", "data", "property"):
        _ATTRIBUTE_DOCSTRINGS[name] = list(lines)


def _restore_attribute_docstring(app, what, name, obj, options, lines):
    original = _ATTRIBUTE_DOCSTRINGS.pop(name, None)
    if original is not None and any(line.startswith(":type:") for line in lines):
        lines[:] = original


def setup(app):
    app.connect("autodoc-process-docstring", _keep_attribute_docstring, priority=300)
    app.connect("autodoc-process-docstring", _restore_attribute_docstring, priority=600)
    app.connect("autodoc-process-docstring", _house_shorthand, priority=400)
    # before napoleon (priority 500), so that it reads the converted docstring
    app.connect("autodoc-process-docstring", _gymnasium_docstring, priority=400)
