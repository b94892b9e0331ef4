"""ABB RWS 1.0 and 2.0: dialects, the driver's transcript against the fakes, faults, an
independent RWS 1.0 client library (``abb-robot-client`` from PyPI, used unchanged) and
a generic HTTPS client (``requests``, Basic authentication) for RWS 2.0."""

from __future__ import annotations

import numpy as np
import pytest

from drivers import rws
from drivers.abb_rws import ABBRWSRobot
from drivers.errors import AddressError, ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.sim.fake_rws import FakeRWS
from drivers.sim.settings import LabSettings
from drivers.sim.world import World

SYMBOL = "T_ROB1/StiffLoop"


@pytest.fixture
def world():
    return World(LabSettings(robot="irb6640", seed=3, time_scale=200.0,
                             true_joint_stiffness=(1e6,) * 6))


@pytest.fixture(params=[1, 2], ids=["rws1", "rws2"])
def abb(request, world):
    fake = FakeRWS(world, version=request.param)
    fake.start()
    sep = "&" if "?" in fake.url else "?"
    drv = ABBRWSRobot(fake.url + f"{sep}motion_timeout=5&poll=0.005", timeout=0.5)
    yield fake, drv
    drv.close()
    fake.stop()


def test_dialects_and_values():
    one, two = rws.Dialect(1), rws.Dialect(2)
    assert (one.default_port, two.default_port) == (80, 443)
    assert one.default_user == ("Default User", "robotics")
    assert two.default_user == ("Admin", "robotics")
    assert one.symbol_set("T_ROB1/M/x") == ("/rw/rapid/symbol/data/RAPID/T_ROB1/M/x",
                                            {"action": "set"})
    assert two.symbol_set("T_ROB1/M/x") == ("/rw/rapid/symbol/RAPID/T_ROB1/M/x/data", {})
    assert one.mastership("request") == ("/rw/mastership", {"action": "request"})
    assert two.mastership("release") == ("/rw/mastership/edit/release", {})
    assert one.rapid("stop") == ("/rw/rapid/execution", {"action": "stop"})
    assert two.rapid("stop") == ("/rw/rapid/execution/stop", {})
    assert (one.ctrlstate()[0], two.ctrlstate()[0]) == ("/rw/panel/ctrlstate",
                                                        "/rw/panel/ctrl-state")
    state = {"_type": "ms-jointtarget", **{f"rax_{i}": str(i * 1.5) for i in range(1, 7)}}
    assert one.states(one.wrap([state])) == [state] == two.states(two.wrap([state]))
    np.testing.assert_allclose(rws.joint_degrees(state), [1.5, 3, 4.5, 6, 7.5, 9])
    assert one.status(one.error(-5, "no")) == (-5, "no") == two.status(two.error(-5, "no"))
    assert one.status({"x": 1}) == (None, "")
    with pytest.raises(ProtocolError, match="_embedded._state"):
        one.states({"state": []})
    with pytest.raises(ProtocolError, match="state"):
        two.states({"_embedded": {"_state": []}})
    text = rws.format_jointtarget(np.array([1, -2.5, 3, 0, 90, -180.123456]))
    assert text == ("[[1.000000,-2.500000,3.000000,0.000000,90.000000,-180.123456],"
                    "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]")
    np.testing.assert_allclose(rws.parse_jointtarget(text), [1, -2.5, 3, 0, 90, -180.123456])
    for bad in ("[[1,2,3],[0,0,0,0,0,0]]", "[[a,0,0,0,0,0],[0,0,0,0,0,0]]", "TRUE"):
        with pytest.raises(ProtocolError, match="jointtarget"):
            rws.parse_jointtarget(bad)
    with pytest.raises(ProtocolError, match="ms-jointtarget"):
        rws.joint_degrees({"_type": "rap-data"})
    assert rws.parse_bool(" true ") is True and rws.format_bool(False) == "FALSE"
    with pytest.raises(AddressError, match="rws://"):
        ABBRWSRobot("socket://1.2.3.4:80")


def test_transcript_connect_read_move_close(abb, world):
    fake, drv = abb
    drv.connect()
    q0 = drv.read_joints().value
    np.testing.assert_allclose(q0, world.joint_angles(), atol=1e-7)
    target = q0 + np.radians([2.0, -1.0, 3.0, 0.0, 4.0, -5.0])
    np.testing.assert_allclose(drv.move_joints(target, 0.5, 1.0).value, target,
                               atol=np.radians(1e-5))
    # \T is the largest step over the speed (here 5 deg at 0.5 rad/s), at least 0.5 s
    assert float(fake.symbols["stiff_time"]) == pytest.approx(max(0.5, np.radians(5) / 0.5),
                                                              abs=1e-3)
    np.testing.assert_allclose(rws.parse_jointtarget(fake.symbols["stiff_target"]),
                               np.degrees(target), atol=1e-6)
    assert fake.symbols["stiff_go"] == "FALSE" and fake.mastership_holder is None
    drv.close()
    d = fake.dialect
    j = "?json=1" if d.version == 1 else ""
    a = "&json=1" if d.version == 1 else ""

    def res(resource):
        path, query = resource
        q = "&".join(f"{k}={v}" for k, v in query.items())
        return path + ("?" + q + a if q else j)

    sym = [res(d.symbol_set(f"{SYMBOL}/{n}")) for n in ("stiff_target", "stiff_time",
                                                        "stiff_go")]
    got = [(m, p, s) for m, p, s in fake.transcript]
    polls = [x for x in got if x == ("GET", res(d.symbol(f"{SYMBOL}/stiff_go")), 200)]
    assert polls, got
    expected = ([("GET", res(d.execution()), 401)] if d.version == 1 else []) + [
        ("GET", res(d.execution()), 200),                      # connect
        ("GET", res(d.jointtarget()), 200),                    # read_joints
        ("GET", res(d.ctrlstate()), 200),                      # motors must be on
        ("GET", res(d.execution()), 200),                      # RAPID must run
        ("GET", res(d.jointtarget()), 200),                    # start of the step
        ("POST", res(d.mastership("request")), 204),
        *[("POST", p, 204) for p in sym],
        ("POST", res(d.mastership("release")), 204),
        *polls,
        ("GET", res(d.jointtarget()), 200),                    # check at the target
        ("GET", res(d.jointtarget()), 200),                    # the role's read-back
        ("GET", "/logout" + j, 204),
    ]
    assert got == expected


def test_faults(abb, world):
    fake, drv = abb
    version = fake.dialect.version
    bad = ABBRWSRobot(fake.url.replace(":robotics@", ":wrong@"), timeout=0.5)
    with pytest.raises(ConnectionFailed, match="authentication refused"):
        bad.connect()
    drv.connect()
    q = drv.read_joints().value
    fake.mastership_holder = "RobotStudio"
    with pytest.raises(DeviceFault, match=r"HTTP 403 .*held by another client \(RobotStudio\)"
                       r" \(controller code -1073445865\)"):
        drv.move_joints(q, 0.5, 1.0)
    fake.mastership_holder = None
    fake.ctrlstate = "guardstop"
    with pytest.raises(DeviceFault, match="controller state 'guardstop'"):
        drv.move_joints(q, 0.5, 1.0)
    fake.ctrlstate = "motoron"
    fake.exec_state = "stopped"
    with pytest.raises(DeviceFault, match="RAPID is stopped"):
        drv.move_joints(q, 0.5, 1.0)
    fake.exec_state = "running"
    with pytest.raises(DeviceFault, match="HTTP 400 .*Invalid value for symbol stiff_time"):
        drv.write_symbol("stiff_time", "fast")
    # a dropped connection: the error, then the next request authenticates anew
    world.faults.inject(fake.device, "disconnect")
    with pytest.raises(ConnectionFailed):
        drv.read_joints()
    before = len(fake.transcript)
    drv.read_joints()
    if version == 1:  # Digest: the forgotten session costs a new challenge
        assert [s for _, _, s in fake.transcript[before:]] == [401, 200]
    # late and missing answers time out; the next request is answered normally
    fake.late_delay = 0.8
    for fault in ("late", "drop"):
        world.faults.inject(fake.device, fault)
        with pytest.raises(DeviceTimeout, match="no answer within 0.5 s"):
            drv.read_joints()
        np.testing.assert_allclose(drv.read_joints().value, q, atol=1e-7)


def test_motion_timeout_stops_rapid(abb):
    fake, drv = abb
    drv.motion_timeout = 0.1
    drv.connect()
    q = drv.read_joints().value
    fake.symbols["stiff_time"] = "100"
    with fake._lock:  # a motion that never ends: stiff_go stays TRUE
        drv.max_speed = 1e-3
    with pytest.raises(DeviceTimeout, match="RAPID stopped"):
        drv.move_joints(q + np.radians([10, 0, 0, 0, 0, 0]), 1e-3, 1.0)
    assert fake.exec_state == "stopped" and fake.symbols["stiff_go"] == "TRUE"
    assert fake.transcript[-1][:2][0] == "POST" and "stop" in fake.transcript[-1][1]
    moved = np.degrees(drv.read_joints().value - q)[0]
    assert 0 <= moved < 10  # stopped on the path, short of the target


def test_rws2_certificate_and_content_types(world, tmp_path):
    requests = pytest.importorskip("requests")
    fake = FakeRWS(world, version=2)
    fake.start()
    try:
        strict = ABBRWSRobot(fake.url.replace("?insecure=1", ""), timeout=1.0)
        with pytest.raises(ConnectionFailed, match="TLS certificate refused"):
            strict.connect()
        ca = tmp_path / "controller.pem"
        ca.write_bytes(fake.cert_pem)
        with ABBRWSRobot(fake.url.replace("?insecure=1", f"?ca={ca}"), timeout=1.0) as drv:
            assert drv.execution_state() == "running"
        base = f"https://127.0.0.1:{fake.port}"
        auth = requests.auth.HTTPBasicAuth("Admin", "robotics")
        plain = requests.get(base + "/rw/panel/opmode", auth=auth, verify=str(ca),
                             headers={"Accept": "application/json"})
        assert plain.status_code == 406
        form = requests.post(base + f"/rw/rapid/symbol/RAPID/{SYMBOL}/stiff_time/data",
                             auth=auth, verify=str(ca), data={"value": "3"},
                             headers={"Accept": rws.HAL_JSON})
        assert form.status_code == 406  # form body without ;v=2.0
        assert requests.get(base + "/rw/panel/opmode", verify=str(ca),
                            headers={"Accept": rws.HAL_JSON}).status_code == 401
        page = requests.get(base + "/rw/panel/opmode", auth=auth, verify=str(ca),
                            headers={"Accept": "application/xhtml+xml;v=2.0"})
        assert page.headers["Content-Type"] == "application/xhtml+xml;v=2.0"
        assert '<li class="pnl-opmode" title="opmode"><span class="opmode">AUTO</span>' \
            in page.text
    finally:
        fake.stop()


def test_standard_rws1_client_library_on_the_fake(world):
    rws_lib = pytest.importorskip("abb_robot_client.rws", reason="needs abb-robot-client "
                                  "(pip install abb-robot-client)")
    fake = FakeRWS(world, version=1)
    fake.start()
    try:
        client = rws_lib.RWS(f"http://127.0.0.1:{fake.port}")  # its defaults: Default User
        jt = client.get_jointtarget()
        np.testing.assert_allclose(jt.robax, np.degrees(world.joint_angles()), atol=1e-5)
        assert client.get_execution_state().ctrlexecstate == "running"
        assert client.get_controller_state() == "motoron"
        assert client.get_operation_mode() == "AUTO"
        assert client.get_rapid_variable("StiffLoop/stiff_go") == "FALSE"
        client.set_rapid_variable("StiffLoop/stiff_time", "2.5")
        assert fake.symbols["stiff_time"] == "2.5"
        with pytest.raises(rws_lib.ABBException, match="Invalid value"):
            client.set_rapid_variable("StiffLoop/stiff_go", "maybe")
        client.stop()
        assert fake.exec_state == "stopped"
        assert [s for _, _, s in fake.transcript].count(401) == 1  # then the session cookie
    finally:
        fake.stop()


def test_generic_rws2_client_on_the_fake(world, tmp_path):
    requests = pytest.importorskip("requests")
    fake = FakeRWS(world, version=2)
    fake.start()
    try:
        ca = tmp_path / "controller.pem"
        ca.write_bytes(fake.cert_pem)
        s = requests.Session()
        s.trust_env = False
        s.auth = requests.auth.HTTPBasicAuth("Admin", "robotics")
        s.verify = str(ca)
        s.headers["Accept"] = rws.HAL_JSON
        base = f"https://127.0.0.1:{fake.port}"
        r = s.get(base + "/rw/motionsystem/mechunits/ROB_1/jointtarget")
        assert r.headers["Content-Type"] == rws.HAL_JSON
        assert {"-http-session-", "ABBCX"} <= set(r.cookies.keys())
        state = r.json()["state"][0]
        assert state["_type"] == "ms-jointtarget"
        np.testing.assert_allclose([float(state[f"rax_{i}"]) for i in range(1, 7)],
                                   np.degrees(world.joint_angles()), atol=1e-5)
        ex = s.get(base + "/rw/rapid/execution").json()["state"][0]
        assert ex["ctrlexecstate"] == "running"
        post = s.post(base + "/rw/mastership/edit/request",
                      headers={"Content-Type": rws.FORM_V2})
        assert post.status_code == 204
        w = s.post(base + f"/rw/rapid/symbol/RAPID/{SYMBOL}/stiff_time/data",
                   data={"value": "4"}, headers={"Content-Type": rws.FORM_V2})
        assert w.status_code == 204 and fake.symbols["stiff_time"] == "4"
        stop = s.post(base + "/rw/rapid/execution/stop", data={"stopmode": "stop"},
                      headers={"Content-Type": rws.FORM_V2})
        assert stop.status_code == 204 and fake.exec_state == "stopped"
    finally:
        fake.stop()
