"""campaign compare's bad-input corpus: damaged results.json / model.toml, bad --plot.

Each case: exit 2, one line on stderr naming the file (or option) and the field, no
traceback, and no file changed or left behind.
"""

from __future__ import annotations

import hashlib
import json
import shutil

import pytest

from campaign.cli import main


def _tree(root) -> dict:
    return {str(p.relative_to(root)): (hashlib.sha256(p.read_bytes()).hexdigest()
                                       if p.is_file() else "dir")
            for p in sorted(root.rglob("*"))}


def _results(d) -> dict:
    return json.loads((d / "results.json").read_text())


def _set(field, value):
    def damage(b):
        doc = _results(b)
        doc[field] = value
        (b / "results.json").write_text(json.dumps(doc))
    return damage


def _write(name, data: bytes):
    def damage(b):
        (b / name).write_bytes(data)
    return damage


def _recode(name, encoding):
    def damage(b):
        text = (b / name).read_text()
        (b / name).write_bytes(text.replace("KUKA", "KUKA Roboter GmbH, Augsburg, é")
                               .encode(encoding))
    return damage


def _cov(value):
    def damage(b):
        doc = _results(b)
        doc["covariance_of_compliance"][0][0] = value
        (b / "results.json").write_text(json.dumps(doc))
    return damage


# (id, damage of B's directory, extra arguments (B_DIR replaced), file named, text expected)
CASES = [
    ("results-latin1", _recode("results.json", "latin-1"), [], "results.json", "not UTF-8"),
    ("results-utf16", _recode("results.json", "utf-16"), [], "results.json", "UTF-16"),
    ("results-utf16-no-bom", _recode("results.json", "utf-16-le"), [], "results.json",
     "UTF-16"),
    ("results-truncated", lambda b: (b / "results.json").write_text(
        (b / "results.json").read_text()[:500]), [], "results.json", "not JSON"),
    ("results-a-list", _write("results.json", b"[1, 2, 3]"), [], "results.json",
     "expected a JSON object"),
    ("model-garbage", _write("model.toml", b"\x00\x17 = = [[[ garbage"), [], "model.toml",
     "not a TOML file"),
    ("model-latin1", _recode("model.toml", "latin-1"), [], "model.toml", "not UTF-8"),
    ("model-joints-not-tables", _write("model.toml", b'joints = [1, 2]\n'), [], "model.toml",
     "joints: expected an array of tables"),
    ("k-as-strings", _set("joint_stiffness_Nm_per_rad", ["1.4e6"] * 6), [], "results.json",
     "joint_stiffness_Nm_per_rad[0]: expected a number"),
    ("k-five-values", _set("joint_stiffness_Nm_per_rad", [1.4e6] * 5), [], "results.json",
     "joint_stiffness_Nm_per_rad: 5 entries, expected 6"),
    ("k-not-a-list", _set("joint_stiffness_Nm_per_rad", 1.4e6), [], "results.json",
     "joint_stiffness_Nm_per_rad: expected a list"),
    ("k-negative", _set("joint_stiffness_Nm_per_rad", [-1.0] * 6), [], "results.json",
     "expected a positive number"),
    ("k-null-but-identified", _set("joint_stiffness_Nm_per_rad", [None] * 6), [],
     "results.json", "expected a positive number"),
    ("joint-7", _set("joints_identified", [1, 2, 3, 4, 5, 7]), [], "results.json",
     "joints_identified: 7 is not a joint number 1..6"),
    ("joint-0", _set("joints_identified", [0, 1, 2, 3, 4, 5]), [], "results.json",
     "joints_identified: 0 is not a joint number 1..6"),
    ("joint-twice", _set("joints_identified", [1, 1, 2, 3, 4, 5]), [], "results.json",
     "joints_identified: a joint is listed twice"),
    ("joints-text", _set("joints_identified", "1,2,3"), [], "results.json",
     "joints_identified: expected a non-empty list"),
    ("robot-missing", _set("robot", None), [], "results.json", "robot: expected"),
    ("cov-shape", _set("covariance_of_compliance", [[1e-18]]), [], "results.json",
     "covariance_of_compliance: expected a 6 x 6 matrix"),
    ("cov-string", _cov("1e-18"), [], "results.json",
     "covariance_of_compliance[0][0]: expected a number"),
    ("cov-nan", _cov(float("nan")), [], "results.json", "covariance_of_compliance: not finite"),
    ("cov-zero-variance", _cov(0.0), [], "results.json", "no usable estimate or variance"),
    ("tests-data-damaged", _set("tests_data", {"sha256": 5}), [], "results.json",
     "tests_data: expected sha256"),
    ("plot-missing-dir", None, ["--plot", "TMP/nowhere/c.png"], "--plot", "does not exist"),
    ("plot-onto-dir", None, ["--plot", "TMP"], "--plot", "is a directory: give a file name"),
    ("plot-onto-dir-png", None, ["--plot", "TMP/d.png"], "--plot", "is a directory"),
    ("plot-suffix", None, ["--plot", "TMP/c.txt"], "--plot", "expected a file name ending"),
    ("plot-symlink", None, ["--plot", "TMP/link.png"], "--plot", "symbolic link"),
    ("alpha-nan", None, ["--alpha", "nan"], "--alpha", "expected 0 < alpha < 1"),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_compare_refuses_bad_input_in_one_line(case, identified, tmp_path_factory, capsys):
    name, damage, extra, named, text = case
    root = tmp_path_factory.mktemp("bad")
    b = root / "b"
    shutil.copytree(identified, b)
    (root / "d.png").mkdir()
    (root / "link.png").symlink_to(root / "elsewhere.png")
    if damage is not None:
        damage(b)
    else:  # a good B whose results differ from A's (not a copy): only the option is at fault
        doc = _results(b)
        doc["joint_stiffness_Nm_per_rad"] = [1.01 * v for v in doc["joint_stiffness_Nm_per_rad"]]
        doc["tests_data"]["sha256"] = "0" * 64
        doc["tests_data"]["row_digests"] = []
        (b / "results.json").write_text(json.dumps(doc))
    before, before_a = _tree(root), _tree(identified)
    args = [a.replace("TMP", str(root)) for a in extra]
    capsys.readouterr()
    code = main(["compare", str(identified), str(b), *args])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ") and "Traceback" not in err
    assert named in lines[0] and text in lines[0], lines[0]
    assert _tree(root) == before and _tree(identified) == before_a
