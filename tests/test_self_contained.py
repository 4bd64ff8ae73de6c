"""The project explains itself: nothing in it points at documents outside the repository."""

from __future__ import annotations

import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_no_reference_to_documents_outside_the_repository() -> None:
    files = subprocess.run(
        ["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    offenders = []
    for name in files:
        path = REPO / name
        if path.suffix not in {".py", ".md", ".toml", ".sh", ".yaml", ".yml", ".txt"}:
            continue
        if name == "CHANGELOG.md" or name == Path(__file__).relative_to(REPO).as_posix():
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        for needle in ("MODEL.md", "../shared", "shared/docs"):
            if needle in text:
                offenders.append(f"{name}: {needle}")
    assert offenders == [], offenders
    assert (REPO / "docs" / "model.md").is_file()
