"""The bad-input corpus's one assertion: a refusal is one line, an exit code, nothing written.

:func:`assert_refused` runs ``campaign`` in this process (``campaign.cli.main``)
and checks, for one bad input:

* the exit status (2 for bad input, 1 for a runtime failure);
* stderr is one line, starts with ``error:`` and contains the expected text;
* no traceback and no warning (a leaked ``RuntimeWarning`` is a defect);
* every file and directory under the watched paths is unchanged: same names,
  same bytes; a watched path that did not exist (an ``--out``) still does not.
"""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path

from campaign.cli import main


def snapshot(paths) -> dict:
    """{path: None (absent) | "dir" | sha256 of the bytes} of every path under ``paths``."""
    state: dict = {}
    for root in map(Path, paths):
        if not root.exists() and not root.is_symlink():
            state[str(root)] = None
            continue
        items = [root, *sorted(root.rglob("*"))] if root.is_dir() else [root]
        for p in items:
            state[str(p)] = ("dir" if p.is_dir() else
                             hashlib.sha256(p.read_bytes()).hexdigest())
    return state


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
