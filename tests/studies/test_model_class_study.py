"""The model-class study's table (tests/studies/model_class_study.py): its numbers from
known outcomes, and the docs block it replaces."""

from __future__ import annotations

import numpy as np

from analysis.identification.studies.model_classes import Outcome

from . import model_class_study as st


def _o(chosen, accepted, covered, total, ho, kerr):
    return Outcome(chosen, "links", accepted, covered, total, ho, np.array(kerr, float))


def test_row_counts_what_it_says():
    out = [_o("links", True, 19, 20, 1.0, [0.01] * 6),
           _o("joints", False, 10, 20, 2.0, [0.03] * 6),
           _o("links", True, 20, 20, 0.9, [0.02] * 6),
           _o("links", True, 20, 20, 0.7, [-0.01] * 6)]
    row = st.row("all", out)
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[:4] == ["all effects", "4", "75 %", "75 % (links)"]
    assert cells[4] == "86.2 %"            # 69 of 80 intervals
    assert cells[5] == "0.950; 50 %"       # median of 0.7, 0.9, 1.0, 2.0; two in range
    assert cells[6].startswith("+1.5 +1.5")  # median of 1, 3, 2, -1 %


def test_write_docs_replaces_only_its_block(tmp_path):
    doc = tmp_path / "identification.md"
    doc.write_text(f"before\n{st.BEGIN}\nold table\n{st.END}\nafter\n")
    st.write_docs(["| a |", "| b |"], doc)
    text = doc.read_text()
    assert text.startswith("before\n") and text.endswith("after\n")
    assert "old table" not in text and "| a |\n| b |\n" + st.END in text
    assert st.HEADER in text


def test_shards_joined_give_the_row_of_all_their_campaigns(tmp_path):
    import json
    from dataclasses import asdict

    out = [_o("links", True, 19, 20, 1.0, [0.01] * 6),
           _o("joints", False, 10, 20, 2.0, [0.03] * 6),
           _o("links", True, 20, 20, 0.9, [0.02] * 6),
           _o("links", True, 20, 20, 0.7, [-0.01] * 6)]
    paths = [tmp_path / "a.jsonl", tmp_path / "b.jsonl"]
    for i, o in enumerate(out):  # as run(..., jsonl) writes them, two shards
        with paths[i % 2].open("a") as fh:
            fh.write(json.dumps({"lab": "all", "seed": i, **asdict(o),
                                 "k_error": o.k_error.tolist()}) + "\n")
    assert st.rows_from(paths) == [st.row("all", out[0::2] + out[1::2])]
    assert st.rows_from(paths)[0] == st.row("all", out)  # order does not matter


def test_a_design_gets_its_own_row(tmp_path):
    import json
    from dataclasses import asdict

    out = [_o("links", True, 19, 20, 1.0, [0.01] * 6),
           _o("joints", False, 10, 20, 2.0, [0.03] * 6)]
    path = tmp_path / "a.jsonl"
    with path.open("a") as fh:
        for i, (o, design) in enumerate(zip(out, (None, "plan X"), strict=True)):
            extra = {} if design is None else {"design": design}
            fh.write(json.dumps({"lab": "all", "seed": i, **extra, **asdict(o),
                                 "k_error": o.k_error.tolist()}) + "\n")
    rows = st.rows_from([path])
    assert rows == [st.row("all", out[:1]), st.row("all", out[1:], "plan X")]
    assert rows[1].startswith("| all effects, plan X | 1 | 0 % |")


RESULTS = st.Path(__file__).parent / "results"
PLAN = RESULTS / "plan_shop_compensator+links"


def test_the_plan_design_is_plan_csv_with_its_repeats():
    """The committed plan (campaign plan --model compensator+links on the shop protocol):
    5 tests x 3 repeats, angles of plan.csv in rad, the load cases' wrenches, no preload."""
    import pandas as pd

    from analysis.identification.studies import model_classes as mc

    d = mc.plan_design(PLAN)
    df = pd.read_csv(PLAN / "plan.csv")
    assert d.q.shape == (15, 6) and d.label == "planner's design (5 tests x 3 repeats)"
    assert np.allclose(np.degrees(d.q[::3]), df[[f"q{j}_model_deg" for j in range(1, 7)]])
    assert list(d.pose) == [p for p in ("P1", "P2", "P3", "P4", "P5") for _ in range(3)]
    # test 1 is eq22: w_eff = [0, 2200 N, 2200 N, 200 N m, 200 N m, 0]
    assert np.array_equal(d.w[0], [0, 2200, 2200, 200, 200, 0])
    assert np.array_equal(d.w_ref, np.zeros((15, 6)))


def test_a_fixed_design_seed_moves_only_the_noise():
    from analysis.identification.studies import model_classes as mc

    robot, lab, k, loads, noise = mc.shop_lab()
    d = mc.plan_design(PLAN)
    (t1, d1), (t2, d2) = (mc.simulate(robot, lab, k, loads, 12, noise, s, d) for s in (1, 2))
    assert np.array_equal(t1.q, d.q) and np.array_equal(t2.q, d.q)
    assert np.array_equal(d1, d2)                  # same tests, same physics
    assert not np.allclose(t1.d, t2.d)              # different noise
    # the noise is the declared one: about 37 um per translation (36 equations)
    s = np.std(np.concatenate([t1.d - d1, t2.d - d2])[:, :3]) / noise.displacement_sigma[0]
    assert 0.6 < s < 1.4


def test_the_docs_table_is_the_committed_campaigns():
    """docs/identification.md's rows are those of the campaigns' JSON lines kept in
    tests/studies/results (sampled poses: 100 all-effects seeds 100-199, 100 clean seeds
    0-99; the planner's designs, its own 13 tests and the protocol's 5: the same seeds;
    a 12-test variant: all-effects seeds 100-199)."""
    import json

    res = RESULTS
    files = [res / "model_class_all_100-199.jsonl", res / "model_class_clean_0-99.jsonl",
             res / "model_class_planner13_all_100-199.jsonl",
             res / "model_class_planner13_clean_0-99.jsonl",
             res / "model_class_planner_all_100-199.jsonl",
             res / "model_class_planner_clean_0-99.jsonl",
             res / "model_class_planner12_all_100-199.jsonl"]
    seeds = [[json.loads(line)["seed"] for line in f.read_text().splitlines()] for f in files]
    assert seeds == [list(range(100, 200)), list(range(100))] * 3 + [list(range(100, 200))]
    docs = st.DOCS.read_text()
    block = docs.split(st.BEGIN)[1].split(st.END)[0]
    for row in st.rows_from(files):
        assert row in block
