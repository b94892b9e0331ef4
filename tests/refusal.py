"""The bad-input corpus's one assertion: a refusal is one line, an exit code, nothing written.

:func:`assert_refused` runs ``campaign`` in this process (``campaign.cli.main``)
and checks, for one bad input:

* the exit status (2 for bad input, 1 for a runtime failure);
* stderr is one line, starts with ``error:`` and contains the expected text;
* no traceback and no warning (a leaked ``RuntimeWarning`` is a defect);
* every file and directory under the watched paths is unchanged: same names,
  same bytes, links pointing where they did; a watched path that did not exist (an
  ``--out``) still does not.

The tree helpers (:func:`tree`, :func:`snapshot`, :func:`outside_dir`) serve the
tests that check a command never writes through a link as well.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from pathlib import Path

from campaign.cli import main


def entry_state(p: Path) -> str:
    """What one entry is: ``"dir"``, the SHA-256 of a file's bytes, or for a symbolic link
    ``"-> TARGET"`` with the state of what it points to (``missing`` when dangling)."""
    if p.is_symlink():
        target = os.readlink(p)
        pointed = ("missing" if not p.exists() else "dir" if p.is_dir()
                   else hashlib.sha256(p.read_bytes()).hexdigest())
        return f"-> {target}: {pointed}"
    return "dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest()


def tree(path: Path) -> dict[str, str]:
    """{name relative to ``path``: :func:`entry_state`} of every entry of a tree, the root
    (``"."``) included; links are not followed into. {} when ``path`` does not exist."""
    path = Path(path)
    if not os.path.lexists(path):
        return {}
    items = [path, *sorted(path.rglob("*"))] if path.is_dir() and not path.is_symlink() \
        else [path]
    return {str(p.relative_to(path)): entry_state(p) for p in items}


def snapshot(paths) -> dict:
    """{path: None (absent) | :func:`tree` of it} of each path of ``paths``."""
    return {str(root): tree(root) if os.path.lexists(root) else None for root in map(Path, paths)}


def outside_dir(tmp_path: Path) -> Path:
    """A directory outside every output, for links to point to: ``victim.txt`` and an empty
    ``dir``; a refusal must leave it as it was."""
    d = Path(tmp_path) / "outside"
    (d / "dir").mkdir(parents=True)
    (d / "victim.txt").write_text("not yours\n")
    return d


def assert_refused(capsys, args: list[str], message: str, *, watch=(), code: int = 2) -> str:
    """Run ``campaign args``; assert a clean refusal (see module docstring); return stderr."""
    capsys.readouterr()
    before = snapshot(watch)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        status = main([str(a) for a in args])
    out = capsys.readouterr()
    err = out.err.strip()
    assert status == code, (status, err, out.out[-2000:])
    assert "Traceback" not in out.err and "Traceback" not in out.out
    assert err.startswith("error:") and "\n" not in err, err
    assert message in err, err
    assert not [w for w in caught if issubclass(w.category, (RuntimeWarning, UserWarning))], \
        [str(w.message) for w in caught]
    assert snapshot(watch) == before, "a refused command changed or left files"
    return err
