"""Fuzz of the GUI's API from its own OpenAPI document: no 500, nothing written.

Every operation of ``/openapi.json`` is called with bodies drawn from its request
schema (:func:`from_schema`: each property's types, enums and bounds, and values just
outside them) and with arbitrary JSON; the answer must be a
2xx or 4xx, and no file may appear or change outside the workspace (nor inside:
these routes only read). Bounded: the trials and tests maxima are lowered in the
schema the bodies are drawn from, so that one example costs milliseconds.
"""

from __future__ import annotations

import copy
import os
import re
import shutil
from pathlib import Path
from urllib.parse import quote

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

BOUNDS = {"trials": 40, "n_tests": 12}  # fuzz-time maxima (the API allows more)


def _resolve(node, components):
    if isinstance(node, dict):
        if "$ref" in node:
            return _resolve(components[node["$ref"].rsplit("/", 1)[-1]], components)
        return {k: _resolve(v, components) for k, v in node.items()}
    if isinstance(node, list):
        return [_resolve(v, components) for v in node]
    return node


def _operations(doc):
    comps = doc.get("components", {}).get("schemas", {})
    for path, ops in doc["paths"].items():
        for method, op in ops.items():
            body = op.get("requestBody", {}).get("content", {}).get("application/json")
            schema = None if body is None else _resolve(body["schema"], comps)
            if schema is not None:
                schema = copy.deepcopy(schema)
                for key, hi in BOUNDS.items():
                    if key in schema.get("properties", {}):
                        schema["properties"][key]["maximum"] = hi
            query = {p["name"]: _resolve(p.get("schema", {}), comps)
                     for p in op.get("parameters", []) if p.get("in") == "query"}
            yield path, method, schema, query


def _snapshot(root):
    out = {}
    for d, _, files in os.walk(root):
        for f in files:
            p = os.path.join(d, f)
            st_ = os.lstat(p)
            out[p] = (st_.st_size, st_.st_mtime_ns)
    return out


#: the texts drawn for a string besides arbitrary ones
STRINGS = ["plan", "robot.toml", "kr240-2", "../x", "/etc", "plan/../..", "a" * 300]


def from_schema(schema: dict, strings: list[str] = STRINGS) -> st.SearchStrategy:
    """Values for a JSON schema of the OpenAPI document: in and just out of its bounds;
    a string is arbitrary text or one of ``strings``."""
    if "anyOf" in schema:
        return st.one_of([from_schema(s, strings) for s in schema["anyOf"]])
    if "enum" in schema:
        return st.sampled_from(schema["enum"]) | st.text(max_size=6)
    t = schema.get("type")
    if t == "null":
        return st.none()
    if t in ("number", "integer"):
        lo, hi = schema.get("minimum"), schema.get("maximum")
        edge = [v for v in (lo, hi) if v is not None]
        inside = (st.integers(lo, hi) if t == "integer" else
                  st.floats(lo, hi, allow_nan=False, allow_infinity=False))
        return inside | st.sampled_from(edge + [v + d for v in edge for d in (-1, 1)] or [0])
    if t == "string":
        return st.text(max_size=40) | st.sampled_from(strings)
    if t == "boolean":
        return st.booleans()
    if t == "array":
        return st.lists(from_schema(schema.get("items", {}), strings),
                        max_size=min(8, schema.get("maxItems", 8) + 1))
    if t == "object" or "properties" in schema:
        props = schema.get("properties", {})
        return st.fixed_dictionaries({}, optional={k: from_schema(v, strings)
                                                   for k, v in props.items()})
    return JSON


JSON = st.recursive(st.none() | st.booleans() | st.integers()
                    | st.floats(allow_nan=False, allow_infinity=False)
                    | st.text(max_size=20),
                    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c,
                                                                         max_size=4),
                    max_leaves=10)


#: routes where a valid body runs a whole campaign (tens of seconds): fuzzed with malformed
#: bodies only (their options record has a required field: a malformed body is refused)
SLOW = ("/api/jobs/demo",)
#: the read-only routes of this face: they must not write, even inside the workspace
READ_ONLY = ("/api/sensitivity", "/api/runs", "/api/session")
SEGMENT = st.text(max_size=30) | st.sampled_from(
    ["..", "%2e%2e", "/etc/passwd", "a" * 300, "plan/note.txt", "plan/plan.csv", "plan",
     "plan/../../x", "robot.toml", "plan/note.txt/.."])


def _fuzz(client, path, method, body, query, examples, segment=SEGMENT,
          sent: list | None = None) -> dict[int, int]:
    """Call the operation with examples of ``body`` (None: no body), of its path
    parameters and of its query parameters (``query``: name -> schema; strings drawn from
    ``segment``); count the answers by status; each request's body is appended to
    ``sent``."""
    seen: dict[int, int] = {}
    names = re.findall(r"{(\w+)}", path)

    @settings(max_examples=examples, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(data=st.fixed_dictionaries({"body": body if body is not None else st.none(),
                                       "params": st.fixed_dictionaries(
                                           {n: segment for n in names}),
                                       "query": st.fixed_dictionaries({}, optional={
                                           n: segment if q.get("type") == "string"
                                           else from_schema(q) for n, q in query.items()})}))
    def call(data):
        url = path
        for n, v in data["params"].items():
            url = url.replace("{" + n + "}", quote(v, safe=""))
        kwargs = {} if body is None else {"json": data["body"]}
        if data["query"]:
            kwargs["params"] = {k: v for k, v in data["query"].items() if v is not None}
        if sent is not None:
            sent.append(data["body"])
        r = client.request(method.upper(), url, **kwargs)
        assert r.status_code < 500, (url, data, r.text)
        seen[r.status_code] = seen.get(r.status_code, 0) + 1

    call()
    return seen


def _outside(snapshot: dict, workspace) -> dict:
    return {p: v for p, v in snapshot.items() if not p.startswith(str(workspace) + os.sep)}


def test_fuzz_api_from_openapi(client, workspace):
    doc = client.get("/openapi.json").json()
    ops = sorted(_operations(doc), key=lambda op: not op[0].startswith(READ_ONLY))
    assert any(m == "post" for _, m, _, _ in ops)
    assert any(q for *_, q in ops)  # /api/runs/file?path=
    (workspace / "plan" / "note.txt").write_text("a file to find")
    before = _snapshot(workspace.parent)
    for path, method, schema, query in ops:
        mine = path.startswith(READ_ONLY)
        body = None if schema is None else JSON if path in SLOW else \
            st.one_of(from_schema(schema), JSON)
        seen = _fuzz(client, path, method, body, query,
                     150 if mine and (body is not None or query) else 25)
        if path == "/api/sensitivity":
            # the drawn bodies reach the job, not only the validation
            assert seen.get(200, 0) >= 5 and seen.get(422, 0) >= 5, (path, seen)
        if path == "/api/runs/file":
            assert seen.get(200, 0) >= 1 and seen.get(422, 0) >= 5, (path, seen)
        if mine:
            assert _snapshot(workspace.parent) == before, path
    assert _outside(_snapshot(workspace.parent), workspace) == _outside(before, workspace)


@pytest.mark.parametrize("text", ["a" * 300, "x/" * 120, "\x00", "plan/\x00", "..", "./..",
                                  "plan//..//..", "C:/Windows", "~root", "\\..\\x"])
def test_odd_paths_are_422(client, text):
    for field in ("plan", "robot"):
        body = {"trials": 5, "n_tests": 2, field: text}
        if field == "plan":
            body["poses"] = "plan"
        r = client.post("/api/sensitivity", json=body)
        assert r.status_code == 422, (field, text, r.text)


@pytest.mark.parametrize("raw", ['{"translation_sigma_um": Infinity}', '{"trials": NaN}',
                                 '{"wrench_N_Nm": [0, 1e999, 0, 0, 0, 0]}', "{", "[]", "null",
                                 '{"q_deg": [[NaN]], "poses": "typed"}'])
def test_non_finite_and_broken_json_are_422(client, raw):
    r = client.post("/api/sensitivity", content=raw,
                    headers={"Content-Type": "application/json"})
    assert r.status_code == 422, r.text


#: body fields that name a job's own output (a file or directory it writes)
OUTPUTS = ("out", "report", "plot", "events_file", "name")
#: body fields that (may) name where the server connects to
ADDRESSES = ("scheduler",)


class _Watch:
    """While ``on``: the addresses this process connects to and the paths it opens or
    lists (an audit hook, added once per process and idle when off)."""

    hooked = False
    current = None

    def __init__(self) -> None:
        self.connects: list = []
        self.opened: list[str] = []

    def __enter__(self):
        import socket
        import sys

        if not _Watch.hooked:
            sys.addaudithook(_Watch._hook)
            _Watch.hooked = True
        _Watch.current = self
        self._connect = socket.socket.connect
        watch = self

        def connect(sock, address):
            watch.connects.append(address)
            return watch._connect(sock, address)

        socket.socket.connect = connect
        return self

    def __exit__(self, *exc) -> None:
        import socket

        socket.socket.connect = self._connect
        _Watch.current = None

    @staticmethod
    def _hook(event: str, args) -> None:
        watch = _Watch.current
        if watch is None or event not in ("open", "os.listdir", "os.scandir"):
            return
        path = args[0] if args else None
        if isinstance(path, (str, bytes, os.PathLike)):
            watch.opened.append(os.fsdecode(path))


def _digest(root) -> dict:
    import hashlib

    out = {}
    for d, _, files in os.walk(root):
        for f in files:
            p = os.path.join(d, f)
            if not os.path.islink(p):
                with open(p, "rb") as fh:
                    out[p] = hashlib.sha256(fh.read()).hexdigest()
    return out


def _named_outputs(bodies: list, workspace) -> list[str]:
    """The workspace paths the bodies named as outputs (absolute, as text)."""
    named = []
    for body in bodies:
        if isinstance(body, dict):
            for key in OUTPUTS:
                value = body.get(key)
                if isinstance(value, str) and value:
                    named.append(os.path.normpath(os.path.join(workspace, value)))
                    named.append(os.path.normpath(os.path.join(workspace, "plans", value)))
    return named


#: a value per field name that the jobs accept (small: each job of the walk runs briefly)
KNOWN = {"robot": "kr240-2", "path": "part.csv", "x_mm": "1400..1800", "y_mm": "-200..200",
         "z_mm": "200", "x_step_mm": 200, "y_step_mm": 200, "tool_angle_step_deg": 90,
         "config": "-1,-1,-1", "workers": 0, "plan": "plan", "protocol": "plan/protocol.toml",
         "fake": True, "assume_yes": True, "confirm": True, "time_scale": 1000.0,
         "trials": 5, "tests": [3], "n_tests": 3, "q_rad": [0.1, 0.5, -1.0, 0.2, 0.6, 0.3],
         "candidates": 200, "pool_size": 50, "step_rad": 0.5, "source": "plan/protocol.toml",
         "name": "walk", "run_dir": "runA", "run": "runA", "a": "runA", "b": "runB",
         "text": "<robot name='r'/>"}


def _string_field(schema: dict) -> bool:
    kinds = [schema] + schema.get("anyOf", [])
    return any(k.get("type") == "string" for k in kinds)


def _walk_bodies(props: dict, dangerous: list[str]):
    """A body of known values, then that body with each string field (and each text map,
    the plan form's ``values``) set to each dangerous value in turn, and with ``fake``
    false (a real robot)."""
    base = {k: v for k, v in KNOWN.items() if k in props}
    for k in props:
        if k in OUTPUTS and k != "name":
            base[k] = "walk-out"
    yield base
    if "fake" in props:
        yield {**base, "fake": False}
    for key, schema in props.items():
        for value in dangerous:
            if _string_field(schema):
                yield {**base, key: value}
            elif isinstance(schema.get("additionalProperties"), dict):
                yield {**base, key: {"campaign.robot": value}}


def _walk(client, path: str, props: dict, dangerous: list[str], sent: list,
          hung: list) -> None:
    """Post each body of :func:`_walk_bodies`; a queued job is followed to its end before
    the next (so that each is run, not refused by a full queue); one still running after
    120 s is cancelled and its body appended to ``hung``."""
    import time

    for n, body in enumerate(_walk_bodies(props, dangerous)):
        body = {k: (f"walk-out-{n}" if v == "walk-out" else v) for k, v in body.items()}
        sent.append(body)
        r = client.post(path, json=body)
        assert r.status_code < 500, (path, body, r.text)
        if r.status_code == 202 and path.startswith("/api/jobs/"):
            job_id, end = r.json()["id"], time.monotonic() + 120
            while client.get(f"/api/jobs/{job_id}").json()["state"] in ("queued", "running"):
                if time.monotonic() > end:
                    hung.append((path, body))
                    client.delete(f"/api/jobs/{job_id}")
                    break
                time.sleep(0.02)
        elif r.status_code == 200 and path in ("/api/acquire/start", "/api/acquire/resume"):
            _wait_detached(r.json().get("pid"))


def _wait_detached(pid) -> None:
    """Wait for a detached acquisition (its own session) to end; SIGINT it after 60 s."""
    import signal
    import time

    end = time.monotonic() + 60
    while pid and os.path.exists(f"/proc/{pid}"):
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[-1].split()[0] == "Z":
                    return
        except OSError:
            return
        if time.monotonic() > end:
            os.kill(pid, signal.SIGINT)
            end = time.monotonic() + 60
        time.sleep(0.05)


def _acquirable_plan(plan) -> None:
    """``plan`` replaced by a KR240-2 plan of 2 tests of 1 repeat (the simulated lab
    acquires it in a second or two at the walk's time scale)."""
    import pandas as pd

    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    shutil.rmtree(plan)
    write_plan(make_plan(load_protocol(Path(__file__).parents[2] / "protocols" /
                                       "kr240-2.toml"), candidates=200), plan, figure=False)
    df = pd.read_csv(plan / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    df.iloc[:2].assign(repeats=1).to_csv(plan / "plan.csv", index=False)


@pytest.mark.timeout(900)
def test_fuzz_safety_rules_for_every_operation(client, app, workspace, tmp_path):
    """Every operation, with bodies that name a listener's address, files outside the
    workspace and existing files inside it: no connection to an address of the request
    nor to the plan's robot (the server has no --hardware), no acquisition on hardware,
    no read outside the workspace, no change to a file that existed before except in an
    output the request named."""
    import socket
    import time

    assert not app.state.hardware
    app.state.jobs_in_threads = True  # the jobs run here, watched
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "secret.toml").write_text('api_password = "hunter2"\n')
    shutil.copy(workspace / "robot.toml", outside / "robot.toml")
    for name in ("runA", "runB"):  # finished runs: raw files a job must not append to
        (workspace / name).mkdir()
        (workspace / name / "samples.jsonl").write_text('{"instrument": "t"}\n')
        (workspace / name / "metadata.json").write_text('{"status": "complete"}\n')
    shutil.copy(Path(__file__).parents[2] / "examples" / "part_circle.csv",
                workspace / "part.csv")
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(16)
    sock.setblocking(False)
    port = sock.getsockname()[1]
    _acquirable_plan(workspace / "plan")
    proto = workspace / "plan" / "protocol.toml"
    proto.write_text(proto.read_text().replace("socket://192.168.1.20:7000",
                                               f"socket://127.0.0.1:{port}"))
    addresses = [f"tcp://127.0.0.1:{port}", f"127.0.0.1:{port}",
                 f"socket://127.0.0.1:{port}", f"http://127.0.0.1:{port}/"]
    files = [str(outside / "secret.toml"), str(outside / "robot.toml"),
             "../outside/secret.toml", "../../outside/robot.toml", "runA/samples.jsonl",
             "runA/metadata.json", "plan/plan.csv", "plan/protocol.toml", "runA", "plan",
             "robot.toml", "part.csv"]
    strings = STRINGS + addresses + files
    segment = st.text(max_size=30) | st.sampled_from(strings)
    before = _digest(workspace)
    sent: list = []
    hung: list = []
    acquired: list = []
    import campaign.jobs.acquire as acquire_job

    real_run = acquire_job.run

    def watched_run(o, *args, **kwargs):
        acquired.append(o)
        return real_run(o, *args, **kwargs)

    acquire_job.run = watched_run
    try:
        with _Watch() as watch:
            doc = client.get("/openapi.json").json()
            for path, method, schema, query in _operations(doc):
                body = None if schema is None else JSON if path in SLOW else \
                    st.one_of(from_schema(schema, strings), JSON)
                _fuzz(client, path, method, body, query, 20, segment, sent)
                if method == "post" and schema is not None and path not in SLOW:
                    _walk(client, path, schema.get("properties", {}),
                          addresses[:2] + files[:3] + files[4:6], sent, hung)
            jobs = getattr(app.state, "jobs", None)
            for job in [] if jobs is None else jobs.jobs():
                jobs.cancel(job.id)
            end = time.monotonic() + 300
            while jobs is not None and any(j.state in ("queued", "running")
                                           for j in jobs.jobs()):
                assert time.monotonic() < end, [j.public() for j in jobs.jobs()]
                time.sleep(0.05)
    finally:
        acquire_job.run = real_run
    try:
        conn, _ = sock.accept()
        conn.close()
        reached = True
    except BlockingIOError:
        reached = False
    sock.close()
    assert not reached, "something connected to an address a request named"
    assert not hung, hung
    assert not [a for a in watch.connects
                if isinstance(a, tuple) and len(a) >= 2 and a[1] == port]
    assert not [o for o in acquired if not (o.fake or o.dry_run)]
    read = sorted({p for p in watch.opened
                   if os.path.abspath(p).startswith(str(outside) + os.sep)})
    assert not read, read
    named = _named_outputs(sent, workspace)
    after = _digest(workspace)
    changed = sorted(p for p, h in before.items() if after.get(p, h) != h
                     and not any(p == n or p.startswith(n + os.sep) for n in named))
    assert not changed, changed
    assert (outside / "secret.toml").read_text() == 'api_password = "hunter2"\n'
