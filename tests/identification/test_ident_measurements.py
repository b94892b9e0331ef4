"""The public CSV import format: units, validation messages naming line and column."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.errors import InputError
from analysis.identification.measurements import (
    CSV_COLUMNS,
    read_csv,
    table_from_arrays,
    to_arrays,
    to_csv_frame,
)


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
    from analysis.identification.measurements import _read_numeric, from_csv_frame

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
