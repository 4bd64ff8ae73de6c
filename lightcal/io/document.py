"""Reading JSON / YAML documents with errors that name the file and line."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from lightcal.errors import InputError


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
    if not path.is_file():
        raise InputError(path, f"{what} not found")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot read the {what} ({exc})") from exc
    if empty is not None and not text.strip():
        raise InputError(path, empty)
    try:
        return json.loads(text) if as_json else yaml.safe_load(text)
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON: {exc.msg}", line=exc.lineno) from exc
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or exc
        raise InputError(path, f"not valid YAML: {problem}", line=line) from exc
