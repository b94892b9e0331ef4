"""The Plan view's protocol form: every key of the reader's schema, round trips, messages.

The form's fields are compared with the keys of the protocol reader's own JSON schema
(walked here independently of the form's generator); each shipped protocol goes
through the form (load, save) and reads back equal; a bad value of a key shows the
command line's own message for the same file edited by hand, beside that key's field.
The page test fills non-default keys (a driver address, a new load case...), plans,
and compares the saved protocol, the poses, the se and the zone map's points with the
plan job run directly on the saved protocol.
"""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from tests.web.conftest import (
    TOKEN,  # noqa: F401  (the fixtures' token)
    post_followed,
)

SHIPPED = Path(__file__).parents[2] / "campaign" / "protocols"


def _schema_leaves(schema: dict, node: dict, path: str, out: set[str]) -> None:
    """Dotted leaf keys of a JSON schema (objects with properties are tables; the rows of
    a top-level array are ``[*]``, an array of tables inside a section is one leaf)."""
    if "$ref" in node:
        node = schema["$defs"][node["$ref"].split("/")[-1]]
    options = node.get("anyOf") or [node]
    objects = [o for o in options if "$ref" in o or "properties" in o]
    if objects:
        target = objects[0]
        if "$ref" in target:
            target = schema["$defs"][target["$ref"].split("/")[-1]]
        for name, sub in target["properties"].items():
            _schema_leaves(schema, sub, f"{path}.{name}" if path else name, out)
        return
    arrays = [o for o in options if o.get("type") == "array" and "$ref" in o.get("items", {})]
    maps = [o for o in options if o.get("type") == "object"
            and "$ref" in (o.get("additionalProperties") or {})]
    if arrays and "." in path:  # rows inside a section: one field, an inline TOML array
        out.add(path)
    elif arrays:
        _schema_leaves(schema, arrays[0]["items"], f"{path}[*]", out)
    elif maps:
        _schema_leaves(schema, maps[0]["additionalProperties"], f"{path}.*", out)
    else:
        out.add(path)


def test_the_form_has_a_field_for_every_key_of_the_reader():
    from campaign.protocol import Protocol
    from campaign.web.protocol_form import REFLECTORS, form_fields

    schema = Protocol.model_json_schema()
    leaves: set[str] = set()
    _schema_leaves(schema, schema, "", leaves)
    keys = {f.key for f in form_fields()}
    assert len(leaves) >= 60
    assert leaves == keys - {f"instruments.*.{REFLECTORS}"}
    # and the one key the reader reads inside options (Protocol.reflectors)
    assert f"instruments.*.{REFLECTORS}" in keys


@pytest.mark.parametrize("name", sorted(p.name for p in SHIPPED.glob("*.toml")))
def test_shipped_protocols_round_trip_through_the_form(client, workspace, name):
    from campaign.protocol import load_protocol

    form = client.get("/api/plan/form", params={"source": name}).json()
    r = client.post("/api/plan/save", json={"source": name, "values": form["values"],
                                            "complete": True, "name": "rt"})
    assert r.status_code == 200, r.text
    saved = workspace / r.json()["protocol"]
    assert saved.name == "rt.toml"
    want, got = load_protocol(SHIPPED / name), load_protocol(saved)
    assert got.model_dump() == want.model_dump()
    assert got.reflectors() == want.reflectors()
    assert (got.wrenches() == want.wrenches()).all()
    # and the saved file fills the form with the same values
    again = client.get("/api/plan/form", params={"source": "protocols/rt.toml"}).json()
    assert again["values"] == form["values"]


def test_a_plan_directorys_protocol_fills_the_form(client, workspace):
    """The workspace's protocol files are offered (a plan's copy too) and fill the form."""
    listed = client.get("/api/plan/protocols").json()
    assert "plan/protocol.toml" in listed["workspace"]
    got = client.get("/api/plan/form", params={"source": "plan/protocol.toml"}).json()
    want = client.get("/api/plan/form", params={"source": "kr240-2.toml"}).json()
    assert got["values"] == want["values"] and len(got["values"]) == 56
    assert got["values"]["load_cases[3].name"] == "eq22-down"
    assert got["values"]["instruments.pose.noise.rotation_urad"] == "20"
    bad = client.get("/api/plan/form", params={"source": "plan/plan.csv"})
    assert bad.status_code == 400 and bad.json()["field"] == "source"


def _cli_message(tmp_path: Path, line: str, bad: str) -> str:
    """What ``campaign plan`` says of kr240-2.toml with ``line`` replaced, without FILE:LINE."""
    from analysis.errors import InputError
    from campaign.jobs.plan import PlanOptions, run

    text = (SHIPPED / "kr240-2.toml").read_text()
    assert text.count(line) == 1
    p = tmp_path / "cli" / "x.toml"
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text.replace(line, bad))
    with pytest.raises(InputError) as err:
        run(PlanOptions(protocol=p, out=tmp_path / "cli" / "out", candidates=100))
    return _without_place(str(err.value))


def _without_place(text: str) -> str:
    return re.sub(r"^[^:]*\.toml(:\d+)?: ", "", text)


CASES = [  # field, text typed, the line of kr240-2.toml, the same change by hand
    ("load_cases[1].force_N", "0, -2200, 9e9", "force_N = [0, -2200, 2200]",
     "force_N = [0, -2200, 9e9]"),
    ("instruments.pose.driver", "emscom", 'driver = "emscon"', 'driver = "emscom"'),
    ("instruments.robot.address", "socket://192.168.1.20:x",
     'address = "socket://192.168.1.20:7000"', 'address = "socket://192.168.1.20:x"'),
    ("instruments.force_torque.calibration_date", "2026-13-45", "mount_rpy_deg = [0, 0, 0]",
     'calibration_date = "2026-13-45"\nmount_rpy_deg = [0, 0, 0]'),
    ("sampling.fixed_deg", "{ q1 = 0, q4 = 45, q5 = 45, q6 = 999 }",
     "fixed_deg = { q1 = 0, q4 = 45, q5 = 45, q6 = 45 }",
     "fixed_deg = { q1 = 0, q4 = 45, q5 = 45, q6 = 999 }"),
    ("thresholds.min_pose_separation_deg", "-1", "max_v_r_deg = 0.025",
     "max_v_r_deg = 0.025\nmin_pose_separation_deg = -1"),
    ("fake_lab.seed", "-1", "seed = 1", "seed = -1"),
    ("load_cases[2]", None, 'name = "eq22-x"\nmethod = "cable-pulley"',
     'name = "eq22-x"\nmethod = "hanging-mass"'),
]


@pytest.mark.parametrize("key,typed,line,bad", CASES, ids=[c[0] for c in CASES])
def test_a_bad_value_gets_the_cli_message_beside_its_field(client, tmp_path, key, typed,
                                                          line, bad):
    # a check of a whole row is named by the row (its block on the page)
    values = {key: typed} if typed else {"load_cases[2].method": "hanging-mass"}
    r = post_followed(client, "/api/plan/run", json={"values": values, "candidates": 100})
    assert r.status_code == 400, r.text
    d = r.json()
    assert d["field"] == key, d
    assert _without_place(d["detail"]) == _cli_message(tmp_path, line, bad)
    assert [p["field"] for p in d["problems"]] == [key]


def test_rows_are_renumbered_and_bad_tables_named(client, workspace):
    from campaign.protocol import load_protocol

    form = client.get("/api/plan/form").json()["values"]
    # drop load case 2 of 4 (indices 0..3 -> 0, 2, 3): the saved rows are renumbered
    values = {k: v for k, v in form.items() if not k.startswith("load_cases[1].")}
    r = client.post("/api/plan/save", json={"values": values, "complete": True, "name": "rn"})
    assert r.status_code == 200, r.text
    got = load_protocol(workspace / "protocols" / "rn.toml")
    assert [c.name for c in got.load_cases] == ["eq22", "eq22-x", "eq22-down"]
    r = client.post("/api/plan/save", json={"values": {"sampling.fixed_deg": "{ q1 = "},
                                            "name": "rn"})
    assert r.status_code == 400 and r.json()["field"] == "sampling.fixed_deg"
    r = client.post("/api/plan/save", json={"values": {"campaign.nope": "1"}, "name": "rn"})
    assert r.status_code == 400 and "not a key" in r.json()["detail"]
    r = client.post("/api/plan/save", json={"values": {"instruments.a b.driver": "ur"},
                                            "name": "rn"})
    assert r.status_code == 400


# ---- the page ----

@pytest.fixture
def plan_page(server, open_url):
    page = open_url(server)
    page.wait_for_function("() => document.body.dataset.planview === 'ready'", timeout=30_000)
    page.click("#tab-plan")
    return page


def test_page_fills_keys_plans_and_shows_the_jobs_numbers(plan_page, workspace, tmp_path):
    from campaign.jobs.plan import PlanOptions, run
    from campaign.protocol import load_protocol

    page = plan_page
    page.fill("#pf-campaign-tests", "6")
    page.fill("#pf-campaign-repeats", "2")
    page.fill("#pf-instruments-robot-address", "socket://127.0.0.1:7001")
    page.fill("#pf-instruments-pose-serial", "LT-4711")
    page.fill("#pf-instruments-pose-calibration_date", "2026-03-14")
    page.fill("#pf-thresholds-min_pose_separation_deg", "4")
    page.fill("#pf-sampling-fixed_deg", "{ q1 = 0, q4 = 30, q5 = 45, q6 = 45 }")
    # keep two of the four load cases, then add a third one
    page.click("#pv-sec-load_cases .pv-block[data-row='3'] .pv-remove")
    page.click("#pv-sec-load_cases .pv-block[data-row='2'] .pv-remove")
    assert page.locator("#pv-sec-load_cases .pv-block").count() == 2
    page.click("#pv-sec-load_cases > .pv-add")
    page.fill("#pf-load_cases-2-name", "push-z")
    page.select_option("#pf-load_cases-2-method", "push")
    page.fill("#pf-load_cases-2-force_N", "0, 0, 1500")
    page.fill("#pf-load_cases-2-moment_N_m", "100, 0, 0")
    page.fill("#plan-candidates", "400")
    page.click("#plan-run")
    page.wait_for_function("() => ['done', 'error'].includes(document.body.dataset.plan)",
                           timeout=60_000)
    assert page.evaluate("() => document.body.dataset.plan") == "done", \
        page.locator("#plan-error").inner_text()
    # the saved protocol holds the values typed
    saved = load_protocol(workspace / "protocols" / "plan-gui.toml")
    assert (saved.campaign.tests, saved.campaign.repeats) == (6, 2)
    assert saved.instruments["robot"].address == "socket://127.0.0.1:7001"
    assert saved.instruments["pose"].serial == "LT-4711"
    assert str(saved.instruments["pose"].calibration_date) == "2026-03-14"
    assert saved.thresholds.min_pose_separation_deg == 4.0
    assert saved.sampling.fixed_deg == {"q1": 0, "q4": 30, "q5": 45, "q6": 45}
    assert [c.name for c in saved.load_cases] == ["eq22", "eq22-mirror-y", "push-z"]
    assert saved.load_cases[2].wrench().tolist() == [0, 0, 1500, 100, 0, 0]
    # the plan job, run directly on the saved protocol, gives the page's poses and se
    direct = run(PlanOptions(protocol=workspace / "protocols" / "plan-gui.toml",
                             out=tmp_path / "direct", candidates=400, seed=0,
                             map_points=True))
    plan = pd.read_csv(tmp_path / "direct" / "plan.csv")
    assert plan.equals(pd.read_csv(workspace / "plans" / "plan-gui" / "plan.csv"))
    rows = page.locator("#plan-rows tbody tr")
    assert rows.count() == len(plan) == 6
    for i, r in plan.iterrows():
        cells = rows.nth(i).locator("td")
        assert int(cells.nth(0).inner_text()) == r["test"]
        assert cells.nth(3).inner_text() == r["load_case"]
        q = [float(v) for v in cells.nth(4).inner_text().split(",")]
        assert q == pytest.approx([r[f"q{j}_model_deg"] for j in range(1, 7)], abs=6e-4)
    se_plot = page.evaluate("() => pv.plots['plan-se-fig'].data")
    for j, y, y_rnd in zip(direct.summary["predicted_standard_errors"], se_plot[1],
                           se_plot[2], strict=True):
        assert y == j["se_design_percent"] and y_rnd == j["se_random_percent"]
        assert float(page.locator(f"#plan-se-k{j['joint']} td.se-pct").inner_text()) == \
            pytest.approx(j["se_design_percent"], abs=6e-4)
    assert se_plot[3] == [5] * 6  # the target line, % of k
    # the zone map's points: every candidate, the random design and the chosen poses
    counts = page.evaluate("() => pv.plots['plan-map-fig'].data.slice(1).map("
                           "s => s.filter(v => v !== null).length)")
    c = direct.summary["candidates"]
    assert counts == [c["poses_passing"], c["drawn"] - c["poses_passing"],
                      len(direct.map["random"]["q2_deg"]), direct.summary["poses"]]
    chosen = page.evaluate("() => { const d = pv.plots['plan-map-fig'].data;"
                           " return d[0].map((x, i) => [x, d[4][i]]).filter(p => p[1] !== null); }")
    want = sorted(zip(plan.drop_duplicates("pose")["q2_model_deg"],
                      plan.drop_duplicates("pose")["q3_model_deg"], strict=True))
    # hovering a chosen pose names it, its tests and its angles (those of plan.csv)
    page.locator("#plan-map-fig").scroll_into_view_if_needed()
    x, y = page.evaluate("() => { const u = pv.plots['plan-map-fig'];"
                         " const m = pv.last.map; const r = u.over.getBoundingClientRect();"
                         " return [r.left + u.valToPos(m.chosen.q2_deg[0], 'x'),"
                         " r.top + u.valToPos(m.chosen.q3_deg[0], 'y')]; }")
    page.mouse.move(x, y)
    page.wait_for_function("() => document.getElementById('plan-map-hover').textContent"
                           ".startsWith('chosen pose')")
    first = plan[plan["pose"] == 1]
    hover = page.locator("#plan-map-hover").inner_text()
    assert hover.startswith(f"chosen pose 1, tests {', '.join(str(t) for t in first['test'])}:")
    shown = [float(v) for v in re.findall(r"= (-?[\d.]+) deg", hover)]
    assert shown == pytest.approx([first["q2_model_deg"].iloc[0], first["q3_model_deg"].iloc[0]],
                                  abs=6e-4)
    got = sorted(tuple(p) for p in chosen)
    assert len(got) == len(want) == direct.summary["poses"]
    for (x, y), (wx, wy) in zip(got, want, strict=True):  # plan.csv: 3 decimals
        assert (x, y) == pytest.approx((wx, wy), abs=6e-4)


def test_page_shows_each_message_beside_its_field(plan_page, tmp_path):
    page = plan_page
    page.fill("#pf-instruments-pose-driver", "emscom")
    page.click("#plan-save")
    page.wait_for_function("() => document.body.dataset.plan === 'error'", timeout=30_000)
    shown = page.locator("label[data-key='instruments.pose.driver'] .pv-msg").inner_text()
    assert _without_place(shown) == _cli_message(tmp_path, 'driver = "emscon"',
                                                 'driver = "emscom"')
    assert page.locator("#plan-error").inner_text() == ""
    page.fill("#pf-instruments-pose-driver", "emscon")
    page.fill("#pf-load_cases-1-force_N", "0, -2200, 9e9")
    page.click("#plan-save")
    page.wait_for_function("() => document.body.dataset.plan === 'error' && document"
                           ".querySelector(\"label[data-key='load_cases[1].force_N'] .pv-msg\")"
                           ".textContent !== ''", timeout=30_000)
    shown = page.locator("label[data-key='load_cases[1].force_N'] .pv-msg").inner_text()
    assert _without_place(shown) == _cli_message(tmp_path, "force_N = [0, -2200, 2200]",
                                                 "force_N = [0, -2200, 9e9]")
    assert page.locator("label[data-key='instruments.pose.driver'] .pv-msg").inner_text() == ""
    page.fill("#pf-load_cases-1-force_N", "0, -2200, 2200")
    page.click("#plan-save")
    page.wait_for_function("() => document.body.dataset.plan === 'saved'", timeout=30_000)
    assert page.locator("#plan-status").inner_text().startswith("saved protocols/plan-gui.toml")
    # the saved protocol is offered to start from, and fills the form with what was typed
    page.select_option("#plan-source", "protocols/plan-gui.toml")
    page.wait_for_function("() => document.getElementById('pf-instruments-pose-driver')"
                           " && document.getElementById('pf-load_cases-1-force_N').value"
                           " === '0, -2200, 2200'")
    assert page.input_value("#pf-instruments-pose-driver") == "emscon"
    assert page.input_value("#pf-campaign-tests") == "5"


def test_any_typed_text_is_saved_or_refused_never_a_500(client):
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    from campaign.web.protocol_form import field_keys

    form = client.get("/api/plan/form").json()["values"]
    keys = field_keys(form) + ["load_cases[7].name", "instruments.new.driver", "zones[0].name",
                               "instruments.pose.options.reflectors_mm", "campaign.x[1]"]
    texts = st.text(max_size=30) | st.sampled_from(
        ["{ a = 1 }", "{ q1 = [1, 2] }", "1e999", "9" * 5000, "2026-02-30", "[1, 2, 3]",
         "true", "-0", "{ P = [0, 0, 0], R1 = [1, 0, 0], R2 = [0, 1, 0] }", '"', "\x00"])

    @settings(max_examples=40, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(st.dictionaries(st.sampled_from(keys), texts, max_size=5), st.booleans())
    def call(values, complete):
        r = client.post("/api/plan/save", json={"values": values, "complete": complete,
                                                "name": "fz"})
        assert r.status_code in (200, 400, 422), r.text
        if r.status_code == 400:
            assert r.json()["detail"]

    call()
