"""``--help`` of every command read at 80 columns: no word lost to rich markup, option
names whole, descriptions in a column wide enough to read."""

from __future__ import annotations

import re

import pytest

from campaign.cli import main
from campaign.cli.app import LAZY_COMMANDS, load_command

WIDTH = 80
#: narrowest description column accepted in an options panel (characters)
MIN_DESCRIPTION = 30


def _plain(text: str) -> str:
    return re.sub(r"\x1b\[[0-9;]*m", "", text)


def _help(name: str, capsys, monkeypatch) -> str:
    monkeypatch.setenv("COLUMNS", str(WIDTH))
    monkeypatch.delenv("TERMINAL_WIDTH", raising=False)
    code = main([name, "--help"])
    out, _ = capsys.readouterr()
    assert code == 0
    return _plain(out)


def _words(text: str) -> set[str]:
    return set(re.findall(r"[A-Za-z][A-Za-z0-9_]*", text))


@pytest.mark.parametrize("name", sorted(LAZY_COMMANDS))
def test_help_keeps_every_word_at_80_columns(name, capsys, monkeypatch):
    text = _help(name, capsys, monkeypatch)
    command = load_command(name, LAZY_COMMANDS[name][0])
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= WIDTH
    assert "…" not in text, [line for line in lines if "…" in line]
    # every word of the docstring and of each shown option's help is on screen: rich
    # markup would have eaten '[tool]', '[fake_lab]', '[report]' and their neighbours
    shown = _words(text)
    texts = [command.help or ""] + [p.help or "" for p in command.params
                                    if getattr(p, "help", None) and not p.hidden]
    for help_text in texts:
        plain = help_text.replace("\\[", "[")
        missing = _words(plain) - shown
        assert not missing, (name, missing, plain)
        for tag in re.findall(r"\[[a-z_]+\]", plain):
            assert tag in text, (name, tag)


@pytest.mark.parametrize("name", sorted(LAZY_COMMANDS))
def test_options_panels_leave_a_readable_description_column(name, capsys, monkeypatch):
    text = _help(name, capsys, monkeypatch)
    command = load_command(name, LAZY_COMMANDS[name][0])
    # every option name whole, on the line where its row starts
    for param in command.params:
        if param.hidden:
            continue
        for opt in (*param.opts, *param.secondary_opts):
            if opt.startswith("--"):
                assert re.search(rf"(^|[\s,]){re.escape(opt)}(\s|,|$)", text, re.M), (name, opt)
    # the description column: continuation lines of a panel start there (the rightmost
    # start: a metavar folded onto a second line starts further left)
    for panel in re.findall(r"╭─ (.*?) ─+╮\n(.*?)╰", text, re.S):
        title, body = panel
        starts = []
        for line in body.splitlines():
            inner = line[1:-1]
            stripped = inner.lstrip()
            if stripped and not stripped.startswith(("-", "*")) and len(inner) - len(stripped) > 3:
                starts.append(len(inner) - len(stripped))
        if starts:
            width = WIDTH - 4 - max(starts)
            assert width >= MIN_DESCRIPTION, (name, title, width)


def test_markup_in_help_is_shown_literally(capsys, monkeypatch):
    text = _help("compensate", capsys, monkeypatch)
    flat = " ".join(re.sub(r"[│╭╮╰╯─]", " ", text).split())
    assert "Protocol whose [fake_lab] is simulated" in flat
    text = _help("stiffness", capsys, monkeypatch)
    flat = " ".join(re.sub(r"[│╭╮╰╯─]", " ", text).split())
    assert "as the protocol's [tool] xyz_mm" in flat
