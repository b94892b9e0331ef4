"""metadata.json says whether the operator's name was given or is the OS login."""

from __future__ import annotations

import getpass
import json

from campaign.cli import main


def test_the_run_records_where_the_operator_name_came_from(kr240_plan, make_variant,
                                                           tmp_path):
    # the command line in this process (the option's parsing and the record are the same
    # as in a process of its own; the subprocess CLI runs are tests/acquire/test_resume.py's);
    # one test is enough for metadata.json
    plan = make_variant(kr240_plan, tmp_path / "plan", tests=1, repeats=1)
    for name, extra in (("login", []), ("named", ["--operator", "A. Tester"])):
        assert main(["acquire", "--plan", str(plan), "--fake", "--yes", "--quiet",
                     "--out", str(tmp_path / name), "--time-scale", "200", *extra]) == 0
    login = json.loads((tmp_path / "login" / "metadata.json").read_text())
    named = json.loads((tmp_path / "named" / "metadata.json").read_text())
    assert login["operator"] == getpass.getuser()
    assert login["operator_source"] == "OS user (no --operator given)"
    assert (named["operator"], named["operator_source"]) == ("A. Tester", "--operator")
