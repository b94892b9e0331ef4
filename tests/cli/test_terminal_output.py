"""Text for a person at an 80-column terminal: wrapped at word boundaries with hanging
indentation, numbers in one format (k in kN m/rad, no '-0', round-off shown as 0)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from campaign.cli import main
from campaign.cli.terminal import text_width, wrap_text

ROOT = Path(__file__).resolve().parents[2]


def _words(text: str) -> list[str]:
    return text.split()


def _fits(text: str, width: int = 80) -> bool:
    """Every line within ``width``, or a single word (a long path is never split)."""
    return all(len(line) <= width or len(line.split()) == 1 for line in text.splitlines())


def test_wrap_text_breaks_at_spaces_with_a_hanging_indent():
    line = ("  candidates: 10000 drawn, 9824 pass the thresholds; rejected: outside limits "
            "or margins 0, 1/kappa_F below threshold 176, K_C not negligible 0")
    wrapped = wrap_text(line, 40)
    rows = wrapped.splitlines()
    assert len(rows) > 2 and all(len(r) <= 40 for r in rows)
    assert rows[0].startswith("  candidates:")
    assert all(r.startswith("    ") and not r.startswith("     ") for r in rows[1:])
    assert _words(wrapped) == _words(line)  # no word split, none lost
    assert wrap_text(line, None) == line
    assert wrap_text("short\n\nlines", 40) == "short\n\nlines"
    # a word longer than the line stays whole
    assert "  /a/very/long/path/that/is/longer/than/the/line" in wrap_text(
        "wrote /a/very/long/path/that/is/longer/than/the/line to disk", 20).splitlines()


def test_text_width_follows_the_terminal_else_columns(monkeypatch):
    class Pipe:
        def isatty(self):
            return False

    monkeypatch.delenv("COLUMNS", raising=False)
    assert text_width(Pipe()) is None
    monkeypatch.setenv("COLUMNS", "80")
    assert text_width(Pipe()) == 80


def test_plan_summary_wraps_at_words_at_80_columns(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["plan", "--protocol", str(ROOT / "protocols" / "kr240-2.toml"), "--out",
                 str(tmp_path / "plan"), "--no-figure"]) == 0
    out = capsys.readouterr().out
    assert _fits(out)
    whole = (tmp_path / "plan" / "summary.txt").read_text()
    # the same words in the same order: nothing split mid-word ("1.12|5 %", "m|argins")
    assert _words(out)[: len(_words(whole))] == _words(whole)
    assert "  margins 0" in out or "margins 0" in out.splitlines()[2]
    rows = [line.split() for line in out.splitlines() if re.match(r"\s+[1-6]\s+\d", line)]
    assert len(rows) == 6
    assert float(rows[0][1]) == pytest.approx(1409.8)  # k prior in kN m/rad
    assert "kN m/rad" in out and "mdeg" not in out
    encoder = re.search(r"encoders ([0-9.]+) urad", " ".join(out.split()))
    assert encoder and float(encoder.group(1)) == pytest.approx(np.radians(0.289e-3) * 1e6,
                                                                rel=0.01)


def test_an_error_is_one_line_in_a_pipe_and_wrapped_on_an_80_column_terminal(tmp_path):
    """Through a pseudo-terminal of 80 columns the error wraps at spaces; piped, one line."""
    import fcntl
    import os
    import pty
    import struct
    import subprocess
    import sys
    import termios

    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "x").write_text("")
    cmd = [sys.executable, "-m", "campaign", "plan", "--protocol",
           str(ROOT / "protocols" / "kr240-2.toml"), "--out", str(tmp_path / "out")]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("COLUMNS", None)
    piped = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=60)
    assert piped.returncode == 2
    message = piped.stderr.strip()
    assert len(message.splitlines()) == 1 and len(message) > 80
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    proc = subprocess.run(cmd, stdin=slave, stdout=slave, stderr=slave, env=env, timeout=60)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    shown = b"".join(chunks).decode().replace("\r\n", "\n").strip()
    assert proc.returncode == 2
    lines = shown.splitlines()
    assert len(lines) > 1 and all(len(line) <= 80 for line in lines)
    assert shown.split() == message.split()  # the same words, none cut in two


def _stiffness(capsys, monkeypatch, *extra):
    monkeypatch.setenv("COLUMNS", "80")
    code = main(["stiffness", "--robot", "kr240-2", "--q", "0,30,10,45,45,45", *extra])
    out = capsys.readouterr().out
    assert code == 0
    return out


def test_stiffness_text_one_number_format_and_the_default_wrench_said(capsys, monkeypatch):
    out = _stiffness(capsys, monkeypatch)
    assert _fits(out)
    flat = " ".join(out.split())
    # the default wrench is named with its values
    assert "w = [2200, 2200, 2200] N, [400, 400, 400] N m at P, base frame (default: the " \
           "paper's worst case" in flat
    # k in kN m/rad, as robots, analyze and compare show it
    assert "k = [1409.8, 400.76, 935.28, 360.00, 370.00, 380.00] kN m/rad" in flat
    assert "N m/rad;" not in flat and "1409800" not in flat
    # no signed zero, no round-off residue: K_C's last column is exactly 0 here (joint 6
    # turns about the tool point), J's zeros are zeros
    assert not re.search(r"-0(\.0+)?(e[+-]?0+)?(\s|$|,|\])", out)
    assert not re.search(r"e-1[0-9]", out)
    kc = out.split("K_C (kN m/rad)")[1].splitlines()[1:7]
    assert [row.split()[-1] for row in kc] == ["0"] * 6
    # no 16-digit floats anywhere
    assert not re.search(r"\d\.\d{9,}", out)
    data = json.loads(_stiffness(capsys, monkeypatch, "--json"))
    kc_json = np.array(data["K_C_Nm_per_rad"])
    np.testing.assert_allclose([float(row.split()[0]) for row in kc], kc_json[:, 0] / 1e3,
                               rtol=1e-4)
    assert data["wrench_source"].startswith("default: the paper's worst case")
    assert data["joint_stiffness_source"] == "the model's nominal values"


def test_stiffness_json_keys_carry_their_units(capsys, monkeypatch):
    data = json.loads(_stiffness(capsys, monkeypatch, "--json"))
    # every numeric entry's key ends with its unit, except K_X's mixed blocks, which are
    # named in "units" (as in results.json)
    unit_suffix = re.compile(r"_(m_rad|m_rad_per_rad|Nm_per_rad|N_Nm|rad|mm|deg)$")
    for key, value in data.items():
        if isinstance(value, (list, float, int)) and not isinstance(value, bool):
            assert unit_suffix.search(key) or key in ("K_X", "K_X_without_K_C"), key
    for old in ("J", "K_C", "deflection", "deflection_nonlinear", "deflection_without_K_C"):
        assert old not in data
    assert set(data["units"]) >= {"J_m_rad_per_rad", "K_C_Nm_per_rad", "K_X"}


def test_robots_prints_the_files_own_text_literally_and_k_in_one_format(tmp_path, capsys,
                                                                        monkeypatch):
    text = (ROOT / "analysis" / "data" / "robots" / "kr240-2.toml").read_text()
    text = text.replace('stiffness = "Dumas et al. 2011 Table 2:',
                        'stiffness = "[bold]see [stiffness] and [tool][/bold] Dumas et al. '
                        '2011 Table 2:')
    robot = tmp_path / "[lab] kr240.toml"
    robot.write_text(text)
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["robots", str(robot)]) == 0
    out = capsys.readouterr().out
    flat = " ".join(out.split())
    assert "source stiffness: [bold]see [stiffness] and [tool][/bold] Dumas et al." in flat
    # the file's path (printed literally, markup and all) is folded at 80 columns where
    # its length (the temporary directory's, e.g. an xdist worker's) makes it fall
    assert f"{tmp_path}/[lab]kr240.toml".replace(" ", "") in "".join(out.split())
    assert _fits(out)
    rows = [line.split("│") for line in out.splitlines() if line.startswith("│")]
    assert [row[5].strip() for row in rows] == ["1409.8", "400.76", "935.28", "360.00",
                                                "370.00", "380.00"]
    # continuation lines of a source hang under their label
    lines = out.splitlines()
    i = next(n for n, line in enumerate(lines) if line.startswith("source geometry:"))
    assert lines[i + 1].startswith("  ") and not lines[i + 1].startswith("   ")
