"""An export as CVAT hands it over: a zip archive or the folder it unpacks to, read the same way.

Names are POSIX paths relative to the export's root. An export whose files all sit under one top
folder (a zip of the unpacked folder, or a folder holding the unpacked one) is read from inside
that folder, so these layouts all match; not when that folder is ``annotations/`` (a COCO export
saved without images).
"""

from __future__ import annotations

import zipfile
from pathlib import Path, PurePosixPath

__all__ = ["ExportArchive"]


class ExportArchive:
    """Read-only files of a zip or folder export. Use as a context manager (closes the zip).

    Args:
        path: a ``.zip`` file or a folder.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._zip: zipfile.ZipFile | None = None
        if self.path.is_dir():
            names = sorted(p.relative_to(self.path).as_posix() for p in self.path.rglob("*") if p.is_file())
            self._prefix = _wrapper(names)
            self._names = [n[len(self._prefix):] for n in names]
        elif self.path.is_file():
            try:
                self._zip = zipfile.ZipFile(self.path)
            except zipfile.BadZipFile as e:
                raise ValueError(f"{self.path}: not a zip archive ({e})") from None
            names = sorted(n for n in self._zip.namelist() if not n.endswith("/"))
            self._prefix = _wrapper(names)
            self._names = [n[len(self._prefix):] for n in names]
        else:
            raise FileNotFoundError(f"export not found: {self.path}")
        self._set = set(self._names)

    def names(self) -> list[str]:
        """Every file's name, sorted."""
        return list(self._names)

    def exists(self, name: str) -> bool:
        return _norm(name) in self._set

    def read_bytes(self, name: str) -> bytes:
        """The file's bytes; FileNotFoundError naming the export and the file when it is not there."""
        n = _norm(name)
        if n not in self._set:
            raise FileNotFoundError(f"{self.path}: no file {n}")
        if self._zip is not None:
            return self._zip.read(self._prefix + n)
        return (self.path / (self._prefix + n)).read_bytes()

    def read_text(self, name: str) -> str:
        return self.read_bytes(name).decode("utf-8-sig")

    def where(self, name: str) -> str:
        """How an error message names the file: ``export.zip!obj_train_data/x.txt`` or a folder path."""
        n = _norm(name)
        return f"{self.path}!{self._prefix}{n}" if self._zip is not None else str(self.path / (self._prefix + n))

    def close(self) -> None:
        if self._zip is not None:
            self._zip.close()
            self._zip = None

    def __enter__(self) -> "ExportArchive":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _norm(name: str) -> str:
    return PurePosixPath(name.replace("\\", "/")).as_posix().lstrip("/")


def _wrapper(names: list[str]) -> str:
    """``"top/"`` when every name is under one folder ``top`` that is not part of an export, else ``""``."""
    tops = {n.split("/", 1)[0] for n in names}
    wrapped = len(tops) == 1 and all("/" in n for n in names) and not _is_export_root(names)
    return f"{tops.pop()}/" if wrapped else ""


def _is_export_root(names: list[str]) -> bool:
    """The names already start at an export's root (YOLO's obj.names, COCO's annotations/)."""
    return "obj.names" in names or any(n.startswith("annotations/") for n in names)
