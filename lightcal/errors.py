"""Errors raised at the boundary when an input is wrong.

Every error names the input (file, field, line) and what was expected. They are
`ValueError` subclasses so library users can catch them generically; the CLI and the
app catch `LightcalError` once and print its message as one line.
"""

from __future__ import annotations

from pathlib import Path


class LightcalError(ValueError):
    """Base class for every user-facing input error of lightcal."""


class InputError(LightcalError):
    """An input (file, field, argument) is missing, malformed or out of range.

    Args:
        source: What was being read: a file path, a field name or an argument name.
        message: What is wrong and what was expected.
        line: 1-based line number in `source`, when it is a text file.
    """

    def __init__(self, source: str | Path, message: str, *, line: int | None = None) -> None:
        self.source = str(source)
        self.line = line
        self.detail = message
        where = self.source if line is None else f"{self.source}:{line}"
        super().__init__(f"{where}: {message}")
