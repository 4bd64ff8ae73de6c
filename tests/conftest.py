"""Fixtures shared by several test modules."""

from __future__ import annotations

from pathlib import Path

import pytest

from lightcal.cli.main import main


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 4-view, 96 x 72 `lightcal synth` dataset (one per test module: tests may add
    files to it, and must remove them)."""
    folder = tmp_path_factory.mktemp("tiny") / "data"
    argv = ["synth", str(folder), "--views", "4", "--width", "96", "--height", "72", "--quiet"]
    assert main(argv) == 0
    return folder
