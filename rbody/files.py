"""Writing files so that a failed or interrupted write never leaves a file (or a folder) half written.

Every file rbody and its validation package write (baselines, reports, figures, CSVs, models,
trajectories) is written to a temporary name in the same folder and renamed into place with
os.replace, which is atomic on one file system: a reader sees the old file or the new one, never a
truncated mix, and a write that fails (a full disk, an exception half-way, a killed process) leaves
the old file as it was.

    write_atomic(path, text_or_bytes)        the whole content at once
    with atomic_path(path) as temporary:     for writers that take a path (savefig, np.savez, to_csv)
    with atomic_open(path, "w") as f:        for writers that take an open file (csv.writer, json.dump)
    with replaced_folder(folder) as staging: a folder written whole (a report), swapped in at the end

A process killed between the temporary write and the rename leaves the temporary behind: a hidden name
(".<name>.<random>.tmp<suffix>", or a ".<folder>.<random>.new"/".old" folder). Readers of a folder skip hidden
names (is_temporary), and stale_temporaries / remove_stale_temporaries find and remove those older than
STALE_SECONDS (a live write lasts milliseconds), so that the next run cleans up after an interrupted one.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import tempfile
import time
from pathlib import Path
from typing import IO, Iterator

STALE_SECONDS = 60.0  # a temporary left this long by write_atomic or replaced_folder is an interrupted write's
_TEMPORARY = re.compile(r"^\..+\.[A-Za-z0-9_]+\.(tmp.*|new|old)$")  # the names _temporary_name and mkdtemp give


def _temporary_name(path: Path) -> Path:
    """A fresh name beside `path` (same folder, hence the same file system), keeping its suffix so that
    writers that pick a format from it (savefig, np.savez) write the same format."""
    # The name shortened to 40 characters: a temporary name must not pass the file system's limit (255)
    # where the file's own name does not.
    handle, name = tempfile.mkstemp(prefix=f".{path.name[:40]}.", suffix=f".tmp{path.suffix[:16]}", dir=path.parent)
    os.close(handle)
    return Path(name)


def is_temporary(path: str | os.PathLike) -> bool:
    """Whether `path` is named as this module's temporaries are (hidden, with a random part and .tmp*, .new or
    .old): never to be read as a result."""
    return bool(_TEMPORARY.match(Path(path).name))


def stale_temporaries(folder: str | os.PathLike, older_than: float = STALE_SECONDS) -> list[Path]:
    """The temporaries in `folder` (is_temporary) last modified more than `older_than` seconds ago."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    now = time.time()
    found = []
    for entry in folder.iterdir():
        try:
            if is_temporary(entry) and now - entry.lstat().st_mtime > older_than:
                found.append(entry)
        except OSError:
            continue
    return sorted(found)


def remove_stale_temporaries(folder: str | os.PathLike, older_than: float = STALE_SECONDS) -> list[Path]:
    """Remove stale_temporaries(folder) (files and folders); returns what was removed."""
    removed = []
    for entry in stale_temporaries(folder, older_than):
        with contextlib.suppress(OSError):
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
            removed.append(entry)
    return removed


def write_atomic(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write `data` (text as UTF-8, or bytes) to `path` through a temporary file renamed into place."""
    path = Path(path)
    with atomic_path(path) as temporary:
        if isinstance(data, bytes):
            temporary.write_bytes(data)
        elif isinstance(data, str):
            temporary.write_text(data, encoding="utf-8")
        else:
            raise ValueError(f"data of type {type(data).__name__}: expected str or bytes")
    return path


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside `path`; when the block ends without an exception, flush it to disk and
    rename it to `path` (os.replace); otherwise remove it and leave `path` untouched."""
    path = Path(path)
    temporary = _temporary_name(path)
    try:
        yield temporary
        if temporary.exists():
            with open(temporary, "rb+") as written:
                os.fsync(written.fileno())
            mode = 0o666 & ~_umask()
            os.chmod(temporary, mode)  # mkstemp makes 0600; a plain open() would have given 0666 & ~umask
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", **kwargs) -> Iterator[IO]:
    """open() for writing ("w" or "wb", with open's keywords), through a temporary file renamed into place."""
    if mode not in ("w", "wb", "wt"):
        raise ValueError(f"mode={mode!r}: expected 'w', 'wt' or 'wb' (a file written whole)")
    with atomic_path(path) as temporary:
        if "b" not in mode:
            kwargs.setdefault("encoding", "utf-8")
        with open(temporary, mode, **kwargs) as handle:
            yield handle


@contextlib.contextmanager
def replaced_folder(folder: str | os.PathLike, *, keep_others: bool = True) -> Iterator[Path]:
    """Yield an empty staging folder beside `folder`; when the block ends without an exception, the staging
    folder takes the place of `folder` (the old one is renamed aside, then removed), so that what the block
    wrote is in `folder` all old or all new, never half of each. On an exception the staging folder is
    removed and `folder` is left as it was. keep_others: entries of the old folder that the block did not
    write (another command's report in the same folder, e.g. report/bench/) are moved into the new one after
    the swap (were the process killed just then, they are in the hidden .old folder beside it)."""
    folder = Path(folder).resolve()
    here = Path.cwd().resolve()
    if folder == here or folder in here.parents or folder.parent == folder:
        # The current folder (or one holding it, or /) cannot be swapped: its files are still written one by
        # one through temporary names, but the folder is then not replaced whole.
        folder.mkdir(parents=True, exist_ok=True)
        yield folder
        return
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{folder.name[:40]}.", suffix=".new", dir=folder.parent))
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    os.chmod(staging, 0o777 & ~_umask())
    if folder.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{folder.name[:40]}.", suffix=".old", dir=folder.parent))
        os.replace(folder, old / folder.name)  # aside, on the same file system
        try:
            os.replace(staging, folder)
        except BaseException:
            os.replace(old / folder.name, folder)  # put the old one back
            shutil.rmtree(staging, ignore_errors=True)
            raise
        if keep_others:
            for entry in (old / folder.name).iterdir():
                if not (folder / entry.name).exists():
                    os.replace(entry, folder / entry.name)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(staging, folder)


class UnwritableFolder(ValueError):
    """A folder that cannot be created or written into (the message names it and says why)."""


def check_writable_folder(folder: str | os.PathLike) -> Path:
    """`folder` checked writable without creating it (a command that then refuses its other inputs leaves
    nothing behind): a file made and removed in the folder, or, where it does not exist yet, in its nearest
    existing ancestor, which must be a folder. UnwritableFolder (a ValueError) naming the folder and the
    reason otherwise. Commands call this before any work."""
    folder = Path(folder)
    existing = folder
    try:
        while not os.path.lexists(existing) and existing != existing.parent:  # lexists: False, not an error,
            existing = existing.parent                                        # for a name too long
        if not existing.is_dir():
            raise NotADirectoryError(f"{str(existing)!r} is not a folder")
        handle, name = tempfile.mkstemp(prefix=".write-check.", dir=existing)
        os.close(handle)
        os.unlink(name)
        longest = os.pathconf(existing, "PC_NAME_MAX")
        for part in folder.relative_to(existing).parts if existing != folder else ():
            if len(os.fsencode(part)) > longest:
                raise OSError(errno.ENAMETOOLONG, f"the name {part[:20]!r}... has {len(os.fsencode(part))} bytes, "
                                                  f"beyond the file system's {longest}")
    except OSError as error:
        raise UnwritableFolder(f"cannot write into {str(folder)!r}: {error.strerror or error}") from None
    return folder


def _umask() -> int:
    current = os.umask(0)
    os.umask(current)
    return current
