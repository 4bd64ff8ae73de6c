"""Marker masks written out of sight, moved into `masks/` only when the project is complete.

`lightcal init` writes one mask per accepted image. Written straight into `masks/`, a run
that stops part-way (an error in a later step, a project that does not load, Ctrl-C)
would leave a half-filled folder behind, which then refuses the corrected re-run ("the
folder is not empty"). `MaskStaging` writes the masks into a hidden folder beside
`masks/` (`.masks-<random>.tmp`, removed on every exit), `publish` moves them in, keeping
each file it replaces, and leaving the `with` block without `commit` puts everything back
as it was: the files this run added removed, the files it replaced restored, `masks/`
removed when this run created it. Nothing that existed before the run is removed.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType

__all__ = ["MaskStaging"]

_BACKUP = "replaced"
"""Subfolder of the staging folder keeping the files `publish` replaced."""


class MaskStaging:
    """A hidden staging folder for the masks of one run (a context manager).

    Args:
        masks_dir: The folder the masks end up in (`masks/` beside the project); its
            parent must exist.
    """

    def __init__(self, masks_dir: Path) -> None:
        self.masks_dir = Path(masks_dir)
        self._staging: Path | None = None
        self._created = False
        self._added: list[str] = []
        self._replaced: list[str] = []
        self._committed = False

    @property
    def folder(self) -> Path:
        """The staging folder (exists inside the `with` block)."""
        if self._staging is None:
            raise RuntimeError("MaskStaging used outside its with block")
        return self._staging

    def __enter__(self) -> MaskStaging:
        self._staging = Path(
            tempfile.mkdtemp(
                prefix=f".{self.masks_dir.name}-", suffix=".tmp", dir=self.masks_dir.parent
            )
        )
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        try:
            if not self._committed:
                self._roll_back()
        finally:
            if self._staging is not None:
                shutil.rmtree(self._staging, ignore_errors=True)
                self._staging = None

    def publish(self, filenames: Sequence[str]) -> None:
        """Move the staged files `filenames` into `masks_dir` (created when missing).

        A file of the same name already there is kept aside, restored unless `commit`
        follows. On any failure (including Ctrl-C) everything moved so far is put back.
        """
        backup = self.folder / _BACKUP
        backup.mkdir(exist_ok=True)
        try:
            if not self.masks_dir.is_dir():
                self.masks_dir.mkdir()
                self._created = True
            for name in filenames:
                target = self.masks_dir / name
                if target.exists() or target.is_symlink():
                    target.replace(backup / name)
                    self._replaced.append(name)
                (self.folder / name).replace(target)
                self._added.append(name)
        except BaseException:
            self._roll_back()
            raise

    def commit(self) -> None:
        """The project is written: the published masks stay, the replaced ones go."""
        self._committed = True

    def _roll_back(self) -> None:
        """Undo `publish`: remove what it added, restore what it replaced."""
        for name in self._added:
            with contextlib.suppress(OSError):
                (self.masks_dir / name).unlink()
        for name in self._replaced:
            with contextlib.suppress(OSError):
                (self.folder / _BACKUP / name).replace(self.masks_dir / name)
        if self._created:
            with contextlib.suppress(OSError):
                self.masks_dir.rmdir()  # only when empty: never a file of another run
        self._added, self._replaced, self._created = [], [], False
