"""Argument types shared by the subcommands (argparse `type=` callables).

`path_arg` is `Path` for a command-line path, except that an empty string is refused:
`Path("")` is the current folder, so `--out ""` (an unset shell variable) would write
into it, or name it in a message about something else.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def path_arg(text: str) -> Path:
    """A path given on the command line; argparse's error for an empty one."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a path, got {text!r}")
    return Path(text)
