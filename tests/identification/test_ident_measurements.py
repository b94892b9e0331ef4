"""The public CSV import format: units, validation messages naming line and column."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.errors import InputError
from analysis.identification.io.columns import CSV_COLUMNS
from analysis.identification.io.csv_reader import read_csv
from analysis.identification.io.measurements import table_from_arrays, to_arrays, to_csv_frame


def _frame(rows: int = 3) -> pd.DataFrame:
    data = {"pose": [f"P{i}" for i in range(rows)]}
    for j in range(1, 7):
        data[f"q{j}_deg"] = [10.0 * j + i for i in range(rows)]
    for c, v in zip(["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"],
                    [0, 2200, 2200, 200, 200, 0], strict=True):
        data[c] = [float(v)] * rows
    for c in ["dx_mm", "dy_mm", "dz_mm"]:
        data[c] = [1.5] * rows
    for c in ["rx_mrad", "ry_mrad", "rz_mrad"]:
        data[c] = [0.25] * rows
    return pd.DataFrame(data)


def _write(tmp_path, frame: pd.DataFrame, text_edit=None):
    path = tmp_path / "tests.csv"
    frame.to_csv(path, index=False)
    if text_edit:
        path.write_text(text_edit(path.read_text()))
    return path


def test_units_are_converted_to_si(tmp_path):
    table = read_csv(_write(tmp_path, _frame()))
    t = to_arrays(table)
    assert t.q[0, 0] == pytest.approx(np.radians(10.0), rel=1e-15)
    assert t.d[0, 0] == pytest.approx(1.5e-3, rel=1e-15)
    assert t.d[0, 3] == pytest.approx(0.25e-3, rel=1e-15)
    assert t.w[0, 1] == 2200.0
    assert list(t.line) == [2, 3, 4]
    back = to_csv_frame(table)
    np.testing.assert_allclose(back[CSV_COLUMNS[1:]].to_numpy(float),
                               _frame()[CSV_COLUMNS[1:]].to_numpy(float), rtol=1e-14)


def test_extra_columns_are_ignored_and_rotations_may_be_empty(tmp_path):
    f = _frame()
    f["operator_note"] = "x"
    for c in ["rx_mrad", "ry_mrad", "rz_mrad"]:
        f[c] = np.nan
    t = to_arrays(read_csv(_write(tmp_path, f)))
    assert not t.has_rotations
    assert t.measured[:, :3].all() and not t.measured[:, 3:].any()


def test_missing_columns_are_listed(tmp_path):
    f = _frame().drop(columns=["q3_deg", "mz_Nm"])
    with pytest.raises(InputError, match=r"missing column\(s\) q3_deg, mz_Nm"):
        read_csv(_write(tmp_path, f))


def test_non_numeric_cell_names_line_and_column(tmp_path):
    f = _frame().astype({"dy_mm": object})
    f.loc[1, "dy_mm"] = "1,5"
    with pytest.raises(InputError, match=r"line 3, column dy_mm: '1,5' is not a number"):
        read_csv(_write(tmp_path, f))


@pytest.mark.parametrize("cell", ["", "NaN", "nan", "inf"])
def test_empty_nan_or_infinite_required_cell(tmp_path, cell):
    f = _frame().astype({"q5_deg": object})
    f.loc[2, "q5_deg"] = cell
    with pytest.raises(InputError, match=r"line 4, column q5_deg: (is empty or NaN|is not "
                                         r"finite)"):
        read_csv(_write(tmp_path, f))


def test_partial_rotation_is_refused(tmp_path):
    f = _frame()
    f.loc[0, "ry_mrad"] = np.nan
    with pytest.raises(InputError, match=r"line 2, column ry_mrad: a rotation is either"):
        read_csv(_write(tmp_path, f))


def test_zero_wrench_names_the_row(tmp_path):
    f = _frame()
    f.loc[1, ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]] = 0.0
    with pytest.raises(InputError, match=r"line 3, columns fx_N.*mz_Nm: zero wrench"):
        read_csv(_write(tmp_path, f))


def test_empty_pose_label_and_empty_file(tmp_path):
    f = _frame().astype({"pose": object})
    f.loc[0, "pose"] = ""
    with pytest.raises(InputError, match=r"line 2, column pose: empty pose label"):
        read_csv(_write(tmp_path, f))
    path = tmp_path / "header.csv"
    path.write_text(",".join(CSV_COLUMNS) + "\n")
    with pytest.raises(InputError, match="no tests"):
        read_csv(path)
    with pytest.raises(InputError, match="not found"):
        read_csv(tmp_path / "nope.csv")


def test_tidy_table_from_arrays_validates_rows():
    q = np.zeros((2, 6))
    w = np.array([[0, 0, 100.0, 0, 0, 0], [0, 0, 0, 0, 0, 0]])
    d = np.zeros((2, 6))
    with pytest.raises(InputError, match=r"row 1, columns fx_N.*zero wrench"):
        to_arrays(table_from_arrays(["a", "b"], q, w, d))


@pytest.mark.parametrize("rotations", ["full", "empty", "nan-text"])
def test_numeric_fast_path_equals_the_text_path(tmp_path, rotations):
    """read_csv's C-parsed path gives the table of the cell-by-cell text path, bit for bit."""
    from analysis.identification.io.csv_reader import _read_numeric, from_csv_frame

    rng = np.random.default_rng(3)
    f = _frame(7)
    f[CSV_COLUMNS[1:]] = f[CSV_COLUMNS[1:]].to_numpy() + rng.normal(size=(7, 18))
    f["pose"] = [" NaN", "P1 ", "P1", "x", "7", "P5", "P6"]  # labels stay text
    edit = None
    if rotations == "empty":
        f[["rx_mrad", "ry_mrad", "rz_mrad"]] = np.nan
    elif rotations == "nan-text":
        f.loc[2, ["rx_mrad", "ry_mrad", "rz_mrad"]] = np.nan
        edit = lambda text: text.replace(",,,\n", ",NaN, nan,NAN\n")  # noqa: E731
    path = _write(tmp_path, f, edit)
    assert _read_numeric(path) is not None  # the fast path is taken
    fast = read_csv(path)
    text = from_csv_frame(pd.read_csv(path, dtype=str, skipinitialspace=True,
                                      keep_default_na=False), where=str(path))
    pd.testing.assert_frame_equal(fast, text)


def _same_tests(a, b) -> None:
    """Two TestArrays hold the same tests, bit for bit."""
    for name in ("q", "w", "d", "measured", "line"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        # the same memory order too: the fits' sums then add alike, to the last bit
        assert x.flags.f_contiguous == y.flags.f_contiguous, name
        assert np.ascontiguousarray(x).tobytes() == np.ascontiguousarray(y).tobytes(), name
    assert a.pose.dtype == b.pose.dtype == object
    assert a.pose.tolist() == b.pose.tolist()


def _text(rows, header=",".join(CSV_COLUMNS)) -> str:
    return header + "\n" + "\n".join(rows) + "\n"


def _row(pose="P1", q=(10, 20, 30, 40, 50, 60), w=(0, 2200, 2200, 200, 200, 0),
         d=(1.5, -2.25, 0.125), r=(0.25, -0.5, 1e-3)) -> str:
    return ",".join([pose, *map(str, (*q, *w, *d)), *map(str, r)])


@pytest.mark.parametrize("case", ["plain", "spaces", "nan-text", "quoted", "extra-columns",
                                  "header-spaces", "crlf", "blank-line", "exponents"])
def test_arrow_reader_equals_the_table_route(tmp_path, case):
    """read_test_arrays gives to_arrays(read_csv) bit for bit, whether Arrow reads the file
    (plain numbers) or it falls back to the text path (spaces around cells)."""
    from analysis.identification.io.csv_reader import _read_arrow, read_test_arrays

    rng = np.random.default_rng(7)
    rows = []
    for i in range(40):
        q = np.round(rng.uniform(-90, 90, 6), 9)
        w = rng.normal(size=6) * 1e3
        d = rng.normal(size=3)
        r = rng.normal(size=3) if i % 3 else ("", "", "")
        rows.append(_row(f"P{i // 4}", q, w, d, r))
    header = ",".join(CSV_COLUMNS)
    arrow = True
    if case == "spaces":
        rows = [r.replace(",", ", ") for r in rows]
        rows[3] = " P0 " + rows[3][2:]
        arrow = False  # Arrow takes no spaces around numbers: the pandas paths read it
    elif case == "nan-text":
        rows[0] = rows[0].rsplit(",", 3)[0] + ",NaN,nan,NAN"
    elif case == "quoted":
        rows[5] = '"P,1"' + rows[5][2:]
    elif case == "extra-columns":
        header = "note," + header + ",operator"
        rows = [f'"x, y",{r},anna' for r in rows]
    elif case == "header-spaces":
        header = ", ".join(CSV_COLUMNS)
        rows = [r for r in rows]
    elif case == "crlf":
        pass
    elif case == "blank-line":
        rows.insert(10, "")
    elif case == "exponents":
        rows[1] = _row("P0", w=("1e3", "2.2E3", "-5e+2", "2e-1", "0.", ".5"))
    text = _text(rows, header)
    path = tmp_path / "tests.csv"
    if case == "crlf":
        path.write_bytes(text.replace("\n", "\r\n").encode())
    else:
        path.write_text(text)
    assert (_read_arrow(path) is not None) == arrow
    new = read_test_arrays(path)
    _same_tests(new, to_arrays(read_csv(path)))
    # equal labels share one string object (8 bytes a test, not a string each)
    first = {}
    for p in new.pose:
        assert first.setdefault(p, p) is p
    if case == "quoted":
        assert new.pose[5] == "P,1"


@pytest.mark.parametrize("edit, message", [
    (lambda r: r.__setitem__(2, _row(q=(10, 20, "1,5", 40, 50, 60))),
     r"cannot read as CSV: .*Expected 19 fields in line 4, saw 20"),
    (lambda r: r.__setitem__(2, _row(q=(10, 20, "abc", 40, 50, 60))),
     r"line 4, column q3_deg: 'abc' is not a number"),
    (lambda r: r.__setitem__(1, _row(q=(10, 20, 30, "", 50, 60))),
     r"line 3, column q4_deg: is empty or NaN"),
    (lambda r: r.__setitem__(1, _row(q=(10, 20, 30, "nan", 50, 60))),
     r"line 3, column q4_deg: is empty or NaN"),
    (lambda r: r.__setitem__(4, _row(d=(1, "inf", 2))), r"line 6, column dy_mm: is not finite"),
    (lambda r: r.__setitem__(4, _row(d=(1, "-inf", 2))), r"line 6, column dy_mm: is not fin"),
    (lambda r: r.__setitem__(4, _row(r=(1, "inf", 2))), r"line 6, column ry_mrad: is not fin"),
    (lambda r: r.__setitem__(3, _row(r=(1, "", 2))), r"line 5, column ry_mrad: a rotation"),
    (lambda r: r.__setitem__(3, _row(r=("nan", "", 2))),
     r"line 5, column rx_mrad, ry_mrad: a rotation"),
    (lambda r: r.__setitem__(2, _row(w=(0, 0, 0, 0, 0, 0))), r"line 4, columns fx_N.*zero wr"),
    (lambda r: r.__setitem__(2, _row(q=(10, 20, 30, 40, 50, 7000))),
     r"line 4, column q6_deg: 7000 is beyond any plausible value"),
    (lambda r: r.__setitem__(2, _row(w=(2e7, 0, 0, 0, 0, 0))),
     r"line 4, column fx_N: 2e\+07 is beyond"),
    (lambda r: r.__setitem__(2, _row(pose=" ")), r"line 4, column pose: empty pose label"),
    (lambda r: r.__setitem__(2, _row(pose="nan")), r"line 4, column pose: empty pose label"),
    (lambda r: r.__setitem__(2, _row() + ",extra"), r"cannot read as CSV: .*line 4, saw 20"),
    (lambda r: r.__setitem__(2, ",".join(_row().split(",")[:-1])), r"line 4, column rz_mrad"),
    (lambda r: r.clear(), r"no tests: the file has a header but no rows"),
    (lambda r: r.__setitem__(2, _row(q=(10, 20, 30, 40, 50, "-nan"))), r"line 4, column q6"),
])
def test_arrow_reader_refuses_as_the_table_route(tmp_path, edit, message):
    """Every refusal of read_csv, with its message (file, line, column), from read_test_arrays
    too: the checks run on the arrays, or the text path names the cell."""
    from analysis.identification.io.csv_reader import read_test_arrays

    rows = [_row(f"P{i}") for i in range(6)]
    edit(rows)
    path = tmp_path / "tests.csv"
    path.write_text(_text(rows))
    with pytest.raises(InputError) as old:
        read_csv(path)
    with pytest.raises(InputError, match=message) as new:
        read_test_arrays(path)
    assert str(new.value) == str(old.value)
    assert str(path) in str(new.value)


def test_arrow_reader_header_problems(tmp_path):
    from analysis.identification.io.csv_reader import read_test_arrays

    path = tmp_path / "tests.csv"
    path.write_text(_text([_row()], header=",".join(c for c in CSV_COLUMNS if c != "dz_mm")))
    with pytest.raises(InputError, match=r"missing column\(s\) dz_mm"):
        read_test_arrays(path)
    with pytest.raises(InputError, match="not found"):
        read_test_arrays(tmp_path / "nope.csv")
    path.write_bytes(b"\xff\xfe" + _text([_row()]).encode("utf-16-le"))
    with pytest.raises(InputError) as new:
        read_test_arrays(path)
    with pytest.raises(InputError) as old:
        read_csv(path)
    assert str(new.value) == str(old.value)


@pytest.mark.parametrize("row, message", [
    (_row(q=(10, 20, 30, "", 50, 60)), r"line 4, column q4_deg: is empty or NaN"),
    (_row(r=(1, "NaN", 2)), r"line 4, column ry_mrad: a rotation"),
    (_row(w=(0, 0, 0, 0, 0, 0)), r"line 4, columns fx_N.*zero wrench"),
    (_row(d=(1, 2, 2e4)), r"line 4, column dz_mm: 20000 is beyond any plausible"),
    (_row(pose='""'), r"line 4, column pose: empty pose label"),
])
def test_arrow_path_checks_the_arrays(tmp_path, row, message):
    """Files Arrow reads are checked on the arrays (not handed to the text path)."""
    from analysis.identification.io.csv_reader import _read_arrow

    rows = [_row(f"P{i}") for i in range(6)]
    rows[2] = row
    path = tmp_path / "tests.csv"
    path.write_text(_text(rows))
    with pytest.raises(InputError, match=message):
        _read_arrow(path)
