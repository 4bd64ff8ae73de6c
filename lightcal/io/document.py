"""Reading JSON / YAML documents with errors that name the file and line.

A document is bounded before anything reads it further: lists and mappings nest at most
`MAX_DEPTH` levels, YAML aliases (`*a`) repeat at most `MAX_ALIAS_VALUES` values, and a
YAML alias may not contain itself. The check takes time linear in the parsed document:
YAML shares an aliased list or mapping (it is built once), so the check visits each
shared one once and adds up expanded sizes from memoised sizes. An "alias bomb" (`a: &a
[x, x, ...]`, `b: &b [*a, *a, ...]`, ...) expands to billions of values from a few
lines; walking it as a tree would take minutes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from lightcal.errors import InputError
from lightcal.io.text_files import read_text


def read_document(path: Path, *, what: str, as_json: bool, empty: str | None = None) -> Any:
    """Read and parse a JSON (as_json) or YAML file.

    Args:
        path: the file.
        what: what it is, for messages ("project file", "board file").
        as_json: parse as JSON, else YAML.
        empty: if given, an all-blank file raises InputError with this message.

    Raises:
        InputError: missing, unreadable, empty (when `empty`) or unparsable; the message
            names the file and, for syntax errors, the line.
    """
    text = read_text(path, what)
    if empty is not None and not text.strip():
        raise InputError(path, empty)
    try:
        data = json.loads(text) if as_json else yaml.safe_load(text)
    except RecursionError:
        raise InputError(path, f"the {what} is nested too deeply to be read") from None
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON: {exc.msg}", line=exc.lineno) from exc
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or exc
        raise InputError(path, f"not valid YAML: {problem}", line=line) from exc
    check_bounds(data, path=path, what=what)
    return data


MAX_DEPTH = 64
"""The deepest nesting of lists and mappings a document may have (projects use about 6)."""

MAX_ALIAS_VALUES = 100_000
"""The most values YAML aliases may repeat: the values of the document expanded (every
alias replaced by a copy of what it names) less those written once. Project and board
files use a few anchors for a few dozen values; an alias bomb repeats billions."""

_SATURATED = 2**62
"""Expanded sizes stop growing here (an alias bomb's would have thousands of digits)."""


def check_bounds(data: Any, *, path: Path, what: str) -> None:
    """Refuse a parsed document too deep, repeating too much through YAML aliases or
    containing itself, in time linear in its distinct lists and mappings.

    Args:
        data: the parsed document (lists, dicts and scalars; YAML aliases make shared or
            self-containing lists and dicts).
        path: the file, for messages.
        what: what it is, for messages ("project file").

    Raises:
        InputError: naming the file and what was expected.
    """
    measure = measure_document(data)
    if measure.cyclic:
        raise InputError(
            path, f"the {what} contains itself through a YAML alias: expected a plain {what}"
        )
    if measure.depth > MAX_DEPTH:
        raise InputError(path, f"the {what} is nested more than {MAX_DEPTH} levels deep")
    if measure.repeated > MAX_ALIAS_VALUES:
        raise InputError(
            path,
            f"the {what} has too many YAML aliases (they repeat over {MAX_ALIAS_VALUES:,} "
            f"values): expected a plain {what}",
        )


@dataclass(frozen=True)
class DocumentMeasure:
    """The shape of a parsed document, as `measure_document` finds it.

    Attributes:
        depth: the deepest nesting of lists and mappings (0 for a scalar).
        expanded: values in the document with every alias expanded (the root counts
            one; saturates at 2**62).
        written: values in the document counting each shared list or mapping once.
        repeated: `expanded - written`, the values YAML aliases repeat (0 for JSON).
        cyclic: a list or mapping contains itself (a YAML alias inside its anchor).
        steps: lists and mappings visited (each once): the work done.
    """

    depth: int
    expanded: int
    written: int
    cyclic: bool
    steps: int

    @property
    def repeated(self) -> int:
        return self.expanded - self.written


def measure_document(data: Any) -> DocumentMeasure:
    """Depth and sizes of a parsed document, visiting each distinct list/dict once.

    Iterative (no recursion), memoised by `id` (`data` keeps every list/dict alive, so ids
    stay unique): a list or dict that YAML aliases share is measured once and its depth and
    expanded size reused.
    """
    memo: dict[int, tuple[int, int]] = {}  # id -> (depth, expanded size)
    on_path: set[int] = set()  # the lists/dicts being measured: a cycle comes back to one
    written = 1
    stack: list[tuple[Any, bool]] = [(data, False)]
    while stack:
        item, children_done = stack.pop()
        children = _children(item)
        if children is None:
            continue
        key = id(item)
        if children_done:
            on_path.discard(key)
            depth, size = 0, 1
            for child in children:
                child_depth, child_size = memo.get(id(child), (0, 1))
                depth = max(depth, child_depth)
                size = min(size + child_size, _SATURATED)
            memo[key] = (depth + 1, size)
            continue
        if key in memo:
            continue
        if key in on_path:
            return DocumentMeasure(
                depth=0, expanded=_SATURATED, written=written, cyclic=True, steps=len(memo)
            )
        on_path.add(key)
        written += len(children)
        stack.append((item, True))
        stack.extend((child, False) for child in children if id(child) not in memo)
    depth, expanded = memo.get(id(data), (0, 1))
    return DocumentMeasure(
        depth=depth, expanded=expanded, written=written, cyclic=False, steps=len(memo)
    )


def _children(item: Any) -> list[Any] | None:
    """The values of a dict or list (keys are scalars), None for a scalar."""
    if isinstance(item, dict):
        return list(item.values())
    if isinstance(item, list):
        return item
    return None
