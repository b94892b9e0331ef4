"""Messages that name the right thing: the argument at fault, the known names, what is missing.

Each case: exit 2, one line on stderr, no traceback, nothing written.
"""

from __future__ import annotations

import pytest

from campaign.cli import main

KNOWN = ("fanuc-s420f (also s-420f, s420f), irb6640 (also abb-irb6640, irb6640-185, "
         "irb6640-185-2.80), kr240-2 (also kr240, kuka-kr240-2), puma560 (also puma, "
         "puma-560), r2000ic (also fanuc-r2000ic, r-2000ic, r2000ic-165f), ur10e (also "
         "ur10-e), ur5e (also ur5-e)")

CASES = [
    (["robots", "kr24-2"], ["error: NAME (argument of campaign robots): unknown robot "
                            "'kr24-2' (did you mean kr240-2?)", KNOWN], ["--robot"]),
    (["robots", "kr24-2", "--json"], ["NAME (argument of campaign robots)", "kr240-2?"],
     ["--robot"]),
    (["robots", "zzz"], ["unknown robot 'zzz': expected a built-in name", KNOWN],
     ["did you mean", "--robot"]),
    (["stiffness", "--robot", "ur10", "--q", "0,0,0,0,0,0"],
     ["error: --robot: unknown robot 'ur10' (did you mean ur10e?)", KNOWN], []),
    (["acquire", "--plan", "TMP/noplan", "--out", "TMP/run", "--fake"],
     ["TMP/noplan: the plan directory does not exist"], ["no protocol"]),
    (["acquire", "--plan", "TMP/file.txt", "--out", "TMP/run", "--fake"],
     ["TMP/file.txt: not a directory"], ["no protocol"]),
    (["acquire", "--plan", "TMP/empty", "--out", "TMP/run", "--fake"],
     ["TMP/empty: no protocol.toml/.yaml in the plan directory"], []),
]


@pytest.mark.parametrize("args,expected,absent", CASES, ids=[" ".join(c[0][:2]) + str(i)
                                                              for i, c in enumerate(CASES)])
def test_message_names_the_argument(tmp_path, capsys, args, expected, absent):
    (tmp_path / "empty").mkdir()
    (tmp_path / "file.txt").write_text("x\n")
    before = sorted(p.name for p in tmp_path.rglob("*"))
    args = [a.replace("TMP", str(tmp_path)) for a in args]
    capsys.readouterr()
    assert main(args) == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for text in expected:
        assert text.replace("TMP", str(tmp_path)) in lines[0], lines[0]
    for text in absent:
        assert text not in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
