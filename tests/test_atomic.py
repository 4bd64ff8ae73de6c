"""Atomic writes: all or nothing, the old file survives any failure, no temp file left."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from lightcal.io.atomic import atomic_write_bytes, atomic_write_text


def _entries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_write_new_and_replace(tmp_path: Path) -> None:
    target = tmp_path / "result.json"
    atomic_write_text(target, '{"a": 1}\n')
    assert target.read_text() == '{"a": 1}\n'
    atomic_write_bytes(target, b"\x00\x01binary")
    assert target.read_bytes() == b"\x00\x01binary"
    atomic_write_bytes(target, (chunk for chunk in (b"one ", b"two")))
    assert target.read_bytes() == b"one two"
    atomic_write_text(target, "é\n", encoding="latin-1")
    assert target.read_bytes() == b"\xe9\n"
    assert _entries(tmp_path) == ["result.json"]


def test_generator_raising_mid_write_keeps_old_file(tmp_path: Path) -> None:
    target = tmp_path / "result.txt"
    target.write_text("old content")

    def chunks() -> Iterator[bytes]:
        yield b"new content, first half"
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError, match="disk on fire"):
        atomic_write_bytes(target, chunks())
    assert target.read_text() == "old content"
    assert _entries(tmp_path) == ["result.txt"]


def test_failing_replace_keeps_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "result.txt"
    target.write_text("old content")

    def broken_replace(src: object, dst: object) -> None:
        raise OSError("replace failed")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="replace failed"):
        atomic_write_text(target, "new content")
    assert target.read_text() == "old content"
    assert _entries(tmp_path) == ["result.txt"]


def test_interrupt_keeps_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "result.txt"
    target.write_text("old content")

    def interrupted_fsync(fd: int) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", interrupted_fsync)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_text(target, "new content")
    assert target.read_text() == "old content"
    assert _entries(tmp_path) == ["result.txt"]


def test_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        atomic_write_text(tmp_path / "no" / "such" / "file.txt", "x")
    assert _entries(tmp_path) == []


def test_existing_permissions_are_kept(tmp_path: Path) -> None:
    target = tmp_path / "script.sh"
    target.write_text("old")
    target.chmod(0o754)
    atomic_write_text(target, "new")
    assert stat.S_IMODE(target.stat().st_mode) == 0o754
    assert target.read_text() == "new"


def test_new_file_follows_umask(tmp_path: Path) -> None:
    previous = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "new.txt", "x")
    finally:
        os.umask(previous)
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == 0o640
