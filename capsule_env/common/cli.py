"""What every command line of the package shares.

- :class:`ArgumentParser`: argparse's parser whose usage errors are one line on stderr (no
  usage block, no traceback) and exit status 2, the project's rule for scripts;
- a bridge from a dataclass of arguments to argparse (:func:`add_dataclass_options`,
  :func:`dataclass_values`): each field an option ``--field-name`` with its type, its choices
  and, as its help, the string literal written under the field (CleanRL / tyro style);
- the env arguments of a command line: ``--env KEY=VALUE`` items (:func:`parse_env_item`) and
  a ``--env-kwargs`` object (:func:`parse_env_kwargs`), values JSON or Python literals
  (:func:`parse_literal`), never evaluated.

The commands (``evaluate.py``, ``train.py``, ``python -m capsule_env.sweep``,
``python -m capsule_env.identification.cli``, ``python -m capsule_env.agents.controllers.tuning``) build on it; the
library proper never parses a command line.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import json
import sys
import textwrap
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

__all__ = [
    "ArgumentParser",
    "integer",
    "nonempty_path",
    "exits_on_interrupt",
    "field_docs",
    "add_dataclass_options",
    "dataclass_values",
    "parse_literal",
    "parse_env_item",
    "parse_env_kwargs",
]


class ArgumentParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (no usage block), exit 2."""

    def error(self, message: str) -> NoReturn:
        """Print ``PROG: error: MESSAGE`` on stderr and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message}\n")


def integer(text: str) -> int:
    """An integer option's value, also written like ``2e6``; ``ArgumentTypeError`` otherwise.
    Digits are read exactly (a seed near 2**63 is not rounded through a float)."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not value.is_integer():
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}")
    return int(value)


def nonempty_path(text: str) -> Path:
    """A file or folder option's value as a ``Path``; ``ArgumentTypeError`` for an empty one
    (``Path("")`` is the current folder: ``--plots ''`` wrote the figures there)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"an empty path: give a file or folder name, got {text!r}")
    return Path(text)


def exits_on_interrupt(prog: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorate a command's ``main(argv)``: a Ctrl-C ends it with one line on stderr and exit
    status 130 instead of a ``KeyboardInterrupt`` traceback of some 20 to 120 lines (its
    saves are atomic: a file is complete or absent)."""

    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def wrapped(*args: Any, **kwargs: Any) -> int:
            try:
                return main(*args, **kwargs)
            except KeyboardInterrupt:
                print(f"\n{prog}: interrupted; the files it wrote are complete, the rest "
                      "were not written", file=sys.stderr)  # fmt: skip
                return 130

        return wrapped

    return wrap


# ----------------------------------------------------------------------------- dataclasses
def field_docs(cls: type) -> dict[str, str]:
    """The string literal under each field of the dataclass ``cls``, whitespace collapsed
    (``{}`` where the source cannot be read, as in a frozen program)."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError):  # no source: no help texts
        return {}
    node = tree.body[0]
    if not isinstance(node, ast.ClassDef):
        return {}
    docs = {}
    for field_node, after in zip(node.body, node.body[1:]):
        if (
            isinstance(field_node, ast.AnnAssign)
            and isinstance(field_node.target, ast.Name)
            and isinstance(after, ast.Expr)
            and isinstance(after.value, ast.Constant)
            and isinstance(after.value.value, str)
        ):
            docs[field_node.target.id] = " ".join(after.value.value.split())
    return docs


def _field_default(f: dataclasses.Field[Any]) -> Any:
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return f.default


def _add_field(
    parser: argparse.ArgumentParser,
    f: dataclasses.Field[Any],
    kind: Any,
    help_text: str,
    suppress: bool = False,
) -> None:
    """``--name`` for the dataclass field ``f`` of type ``kind``: ``bool`` a ``--name`` /
    ``--no-name`` pair, ``Literal[...]`` its choices, ``list[str]`` a repeatable option,
    ``dict`` a JSON text (for the caller to read after argparse), int/float/str (maybe
    optional) a value; the default is added to the help unless it says one. ``suppress``: no
    default (the namespace then holds only the options given)."""
    origin, default = typing.get_origin(kind), _field_default(f)
    if "default" not in help_text and kind is not bool and origin is not list:
        help_text = f"{help_text} (default: {default})"
    options: dict[str, Any] = {"default": default, "help": help_text}
    if kind is bool:
        options["action"] = argparse.BooleanOptionalAction
    elif origin is typing.Literal:
        options["choices"] = typing.get_args(kind)
    elif origin is list:
        options.update(action="append", metavar="KEY=VALUE")
    elif kind is dict:
        options.update(default="{}", metavar="JSON")
    else:
        types = set(typing.get_args(kind)) or {kind}
        options["type"] = integer if int in types else float if float in types else str
    if suppress:
        options["default"] = argparse.SUPPRESS
    parser.add_argument("--" + f.name.replace("_", "-"), **options)


def _cli_fields(cls: type) -> list[dataclasses.Field[Any]]:
    """The fields of ``cls`` that are options (not marked ``metadata={"cli": False}``)."""
    return [f for f in dataclasses.fields(cls) if f.metadata.get("cli", True)]


def add_dataclass_options(
    parser: argparse.ArgumentParser, cls: type, suppress: bool = False
) -> None:
    """One option ``--field-name`` per field of the dataclass ``cls`` (see :func:`_add_field`
    for the types understood; a field with ``metadata={"cli": False}`` is none), its help the
    string literal under the field; ``suppress``: without defaults, to see what was given."""
    docs, hints = field_docs(cls), typing.get_type_hints(cls)
    for f in _cli_fields(cls):
        _add_field(parser, f, hints[f.name], docs.get(f.name, ""), suppress)


def dataclass_values(namespace: argparse.Namespace, cls: type) -> dict[str, Any]:
    """The parsed options of :func:`add_dataclass_options`, by field name of ``cls``."""
    return {f.name: getattr(namespace, f.name) for f in _cli_fields(cls)}


# ----------------------------------------------------------------------------- env arguments
def parse_literal(text: str) -> Any:
    """``text`` as JSON, else as a Python literal (:func:`ast.literal_eval`); raises
    ``ValueError`` when it is neither."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        pass
    try:
        return ast.literal_eval(text.strip())
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        raise ValueError(f"not JSON or a Python literal: {text!r}") from None


def parse_env_item(item: str) -> tuple[str, Any]:
    """``--env KEY=VALUE``: ``(KEY, VALUE)``, VALUE read by :func:`parse_literal`, or kept as
    a string when it is not a literal (``--env setting=sim``); ``ValueError`` without ``=``
    or a key."""
    key, sep, text = item.partition("=")
    if not sep or not key.strip():
        raise ValueError(f"--env expects KEY=VALUE, got {item!r}")
    try:
        return key.strip(), parse_literal(text)
    except ValueError:
        return key.strip(), text


def parse_env_kwargs(text: str) -> dict[str, Any]:
    """``--env-kwargs``: a JSON object or a Python dict literal; ``ValueError`` otherwise."""
    try:
        value = parse_literal(text)
    except ValueError as exc:
        raise ValueError(f"--env-kwargs: {exc}") from None
    if not isinstance(value, dict):
        raise ValueError(f"--env-kwargs must be a JSON object (a dict), got {text!r}")
    return value
