"""Reading JSON / YAML documents with errors that name the file and line."""

from __future__ import annotations

import json
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
    if _depth_exceeds(data, MAX_DEPTH):
        raise InputError(path, f"the {what} is nested more than {MAX_DEPTH} levels deep")
    return data


MAX_DEPTH = 64
"""The deepest nesting of lists and mappings a document may have (projects use about 6)."""


def _depth_exceeds(data: Any, limit: int) -> bool:
    """Whether lists/dicts in `data` nest deeper than `limit` (iteratively: no recursion)."""
    stack = [(data, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children = list(item.values())
        elif isinstance(item, list):
            children = item
        else:
            continue
        if depth > limit:
            return True
        stack.extend((child, depth + 1) for child in children)
    return False
