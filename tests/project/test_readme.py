"""The README's walk-through and docs/commands.md (every command, step by step) as a
newcomer runs them: their inputs ship, their outputs are git-ignored, their lists of
choices are the commands' own."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: the pages whose bash blocks are walk-throughs: each is run top to bottom on its own
WALKS = (ROOT / "README.md", ROOT / "docs" / "commands.md")


def _commands(pages=WALKS) -> list[list[str]]:
    """Every ``campaign ...`` command of the pages' bash blocks, continuation lines joined."""
    text = "\n".join(page.read_text() for page in pages)
    out = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = line.split("#")[0].strip()
            if line.startswith(("campaign ", ".venv/bin/campaign ")) or " campaign " in line:
                out.append(shlex.split(line[line.index("campaign"):]))
    return out


def _values(option: str) -> list[str]:
    return [cmd[i + 1] for cmd in _commands() for i, word in enumerate(cmd[:-1])
            if word == option]


def test_the_walk_through_activates_the_virtualenv():
    text = (ROOT / "README.md").read_text()
    step = text.split("## A campaign, step by step")[1].split("```bash")
    assert "source .venv/bin/activate" in step[1].splitlines()[1]


def test_the_inputs_the_readme_names_ship():
    for option in ("--path", "--protocol"):
        for value in _values(option):
            assert (ROOT / value).is_file(), (option, value)
    assert "examples/kr240-2_path.csv" in _values("--path")


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(),
                    reason="needs git and a git checkout (git check-ignore)")
def test_the_outputs_the_readme_writes_are_git_ignored():
    outputs = set(_values("--out")) | set(_values("--plot"))
    assert {"plan", "run", "ident", "rob", "place", "comp", "maps", "cmp.png"} <= outputs
    for value in sorted(outputs):
        probe = value if value.endswith(".png") else f"{value}/results.json"
        done = subprocess.run(["git", "check-ignore", "-q", probe], cwd=ROOT)
        assert done.returncode == 0, f"{value} is not git-ignored"


@pytest.mark.parametrize("page", WALKS, ids=lambda p: p.name)
def test_no_two_walk_through_commands_write_into_one_directory(page):
    """A command that writes into an earlier command's --out is refused (non-empty output):
    a walk-through, run top to bottom, must not do that unless it says --force or
    --resume."""
    text = page.read_text()
    alternatives = [shlex.split(line.split("#")[0].strip()) for line in text.splitlines()
                    if re.search(r"#\s*or\b", line)]  # "# or on the simulated lab"
    seen: dict[str, list[str]] = {}
    for cmd in _commands([page]):
        if "--force" in cmd or "--resume" in cmd or "--dry-run" in cmd or cmd in alternatives:
            continue
        for i, word in enumerate(cmd[:-1]):
            if word == "--out":
                seen.setdefault(cmd[i + 1], []).append(" ".join(cmd[:2]))
    shared = {out: who for out, who in seen.items() if len(who) > 1}
    assert not shared, f"commands writing into the same --out: {shared}"
    if page.name == "commands.md":
        assert "comp-verified" in seen  # the --verify-fake replay has its own directory


def test_the_listed_strategies_are_the_planners():
    from campaign.cli.terminal import Strategy
    from campaign.planning.planner import STRATEGIES

    text = " ".join((ROOT / "README.md").read_text().split())
    listed = re.search(r"--strategy ([a-z|-]+)`", text).group(1).split("|")
    assert listed == list(STRATEGIES) == [s.value for s in Strategy]
    assert "default `worst-joint`" in text


def test_the_sample_joint_path_is_accepted_by_compensate(tmp_path, capsys):
    from campaign.cli import main

    code = main(["compensate", "--robot", "kr240-2", "--path",
                 str(ROOT / "examples" / "kr240-2_path.csv"), "--out", str(tmp_path / "c"),
                 "--wrench", "0,1000,-1500,100,50,0"])
    assert code == 0, capsys.readouterr().err
    import json

    summary = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert summary["points"] == 30
    assert 1e-3 < summary["translation_m"]["before"]["max"] < 1e-2  # mm-scale deflection


def test_docs_open_for_users_not_with_notes_to_developers():
    """No page opens with (or keeps) a note meant for the project's own authors."""
    for page in sorted((ROOT / "docs").glob("*.md")):
        text = page.read_text()
        opening = "\n".join(text.splitlines()[:6])
        assert "Text for the README" not in opening, page.name
        for note in ("should list the", "schema's owner", "issue, unchanged", "TODO"):
            assert note not in text, (page.name, note)
    report = (ROOT / "docs" / "report.md").read_text().split("```")[0]
    assert "`campaign analyze` turns the measurements of a campaign" in report
