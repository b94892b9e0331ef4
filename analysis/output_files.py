"""Writing a command's output files without following symbolic links.

Every command that writes (``analyze``, ``acquire``, ``plan``, ``place``, ``maps``,
``compensate``, ``robustness``, ``compare --plot``, ``demo``) writes through these
helpers, so a symbolic link planted in an output or run directory (or the
directory itself being one) is refused with one line naming it, and nothing
outside the directories a command was given is written.

A file is written to a temporary file of a unique name in its directory
(``O_CREAT | O_EXCL``: never through a link), then renamed over the target:
``rename`` replaces a link instead of following it, so even a link planted
between the check and the rename is not written through. The temporary file is
removed when the write fails (disk full, permissions).
"""

from __future__ import annotations

import fcntl
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from analysis.errors import InputError


class SymlinkRefused(InputError):
    """An output path (a file or a directory) is a symbolic link."""

    def __init__(self, path: Path | str) -> None:
        path = Path(path)
        try:
            target = f" (to {os.readlink(path)})"
        except OSError:
            target = ""
        super().__init__(f"is a symbolic link{target}; refusing to write through it: "
                         "remove the link or give another path", where=str(path))


def refuse_link(path: Path | str) -> None:
    """Raise :class:`SymlinkRefused` if ``path`` is a symbolic link (dangling or not)."""
    if os.path.islink(path):
        raise SymlinkRefused(path)


def refuse_links_in(directory: Path | str) -> None:
    """Refuse ``directory`` if it, or any entry directly in it, is a symbolic link."""
    directory = Path(directory)
    refuse_link(directory)
    try:
        entries = sorted(os.scandir(directory), key=lambda e: e.name)
    except (FileNotFoundError, NotADirectoryError):
        return
    for entry in entries:
        if entry.is_symlink():
            raise SymlinkRefused(entry.path)


def check_output_dir(out: Path | str, force: bool, where: str = "--out",
                     replaces: str = "overwrite its files") -> Path:
    """Check (without creating anything) that ``out`` may be used as an output directory.

    Refused: a symbolic link, an existing non-directory, a non-empty directory
    unless ``force`` (the message then says ``--force`` would ``replaces``), and
    with ``force`` a directory holding a symbolic link.
    """
    out = Path(out)
    refuse_link(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", where=str(out))
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise InputError(f"output directory exists and is not empty; choose another or "
                             f"add --force to {replaces}", where=f"{where} {out}")
        refuse_links_in(out)
    return out


def make_dir(path: Path | str) -> Path:
    """Create directory ``path`` (and its parents); refuse it when it is a symbolic link."""
    path = Path(path)
    refuse_link(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise InputError("exists and is not a directory", where=str(path)) from None
    except OSError as err:
        raise InputError(f"cannot create the output directory: {err.strerror or err}",
                         where=str(path)) from None
    return path


@contextmanager
def replacing(path: Path | str) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it over ``path``.

    For writers that take a file name (matplotlib, pandas, ...). The temporary
    name keeps the suffix of ``path`` (``.NAME.<random>.tmp.png``), for writers that
    choose the format from it. Refuses a ``path`` that is a symbolic link or a
    directory; the temporary file is removed if anything fails.
    """
    path = Path(path)
    refuse_link(path)
    if path.is_dir():
        raise InputError("is a directory; give a file name", where=str(path))
    if not path.parent.is_dir():
        raise InputError(f"directory {path.parent} does not exist", where=str(path))
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                                dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes(path: Path | str, data: bytes) -> Path:
    """Replace ``path`` by ``data`` (see :func:`replacing`)."""
    path = Path(path)
    with replacing(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
    return path


def write_text(path: Path | str, text: str, encoding: str = "utf-8") -> Path:
    """Replace ``path`` by ``text`` (see :func:`replacing`)."""
    return write_bytes(path, text.encode(encoding))


@contextmanager
def replaced_dir(out: Path | str, force: bool, where: str = "--out") -> Iterator[Path]:
    """Yield a new empty directory beside ``out`` that replaces ``out`` as a whole on success.

    ``out`` is refused when it is a symbolic link, or a non-empty directory
    without ``force``. The new directory (``.NAME.new-<random>``) is renamed to
    ``out`` once the body succeeds (the old ``out``, if any, is moved aside and
    removed), so nothing of an earlier output remains beside the new files; if
    the body fails, the new directory is removed and ``out`` is left as it was.
    The new directory is locked (``flock``) while the body runs: one left by a
    process killed meanwhile is removed by the next call, one in use is not.
    """
    out = check_output_dir(out, force, where, replaces="replace its contents")
    with created_dir(out.parent):  # parents this call creates go too if the body fails
        _remove_stale(out)
        try:
            new = Path(tempfile.mkdtemp(prefix=f".{out.name}.new-", dir=out.parent))
            os.chmod(new, 0o755)
            lock = os.open(new, os.O_RDONLY | os.O_DIRECTORY)
        except OSError as err:
            raise InputError(f"cannot create the output directory: {err.strerror or err}",
                             where=str(out)) from None
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
            yield new
            refuse_link(out)  # planted while the body ran
            if out.exists():
                old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
                os.rename(out, old)  # onto an empty directory: POSIX replaces it
                try:
                    os.rename(new, out)
                except OSError:
                    os.rename(old, out)  # put the earlier output back
                    raise
                shutil.rmtree(old, ignore_errors=True)
            else:
                os.rename(new, out)
        except BaseException:
            shutil.rmtree(new, ignore_errors=True)
            raise
        finally:
            os.close(lock)


def _remove_stale(out: Path) -> None:
    """Remove ``.NAME.new-*`` directories beside ``out`` whose writer is gone (lock free)."""
    for old in out.parent.glob(f".{out.name}.new-*"):
        try:
            fd = os.open(old, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue  # another process is writing it
        else:
            shutil.rmtree(old, ignore_errors=True)
        finally:
            os.close(fd)


def save_figure(fig, path: Path | str, **kwargs) -> Path:
    """``fig.savefig`` into ``path`` through :func:`replacing` (the suffix picks the format)."""
    path = Path(path)
    with replacing(path) as tmp:
        fig.savefig(tmp, **kwargs)
    return path


@contextmanager
def created_dir(out: Path | str) -> Iterator[Path]:
    """Create ``out`` (and parents); if the body fails, remove what this call created.

    A failed command then leaves no empty (or half-written) output directory
    behind; a directory that existed before is left in place.
    """
    out = Path(out)
    refuse_link(out)
    top = None
    for p in (out, *out.parents):
        if os.path.lexists(p):
            break
        top = p
    make_dir(out)
    try:
        yield out
    except BaseException:
        if top is not None:
            shutil.rmtree(top, ignore_errors=True)
        raise
