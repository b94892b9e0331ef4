"""metadata.json says whether the operator's name was given or is the OS login."""

from __future__ import annotations

import getpass
import json


def test_the_run_records_where_the_operator_name_came_from(small_plan, tmp_path, cli):
    for name, extra in (("login", []), ("named", ["--operator", "A. Tester"])):
        done = cli("acquire", "--plan", str(small_plan), "--fake", "--yes", "--quiet",
                   "--out", str(tmp_path / name), "--time-scale", "200", *extra)
        assert done.returncode == 0, done.stderr
    login = json.loads((tmp_path / "login" / "metadata.json").read_text())
    named = json.loads((tmp_path / "named" / "metadata.json").read_text())
    assert login["operator"] == getpass.getuser()
    assert login["operator_source"] == "OS user (no --operator given)"
    assert (named["operator"], named["operator_source"]) == ("A. Tester", "--operator")
