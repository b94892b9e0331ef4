"""Fixtures of the driver tests: a fresh simulated world, a shared lab, hardware addresses.

The ``--ft-url``, ``--tracker-url`` and ``--robot-url`` options are declared in
the top-level ``tests/conftest.py``; here they are read defensively so these
tests also run when that declaration is absent.
"""

from __future__ import annotations

import pytest

from drivers.sim.lab import Lab
from drivers.sim.settings import LabSettings
from drivers.sim.world import World


def option(config: pytest.Config, name: str) -> str | None:
    """Value of a command-line option, or None when it is not declared."""
    try:
        return config.getoption(name, default=None)
    except ValueError:
        return None


@pytest.fixture
def world() -> World:
    """A fresh world: KR240-2, fast settling, seeded noise."""
    return World(LabSettings(seed=11, time_scale=200.0, can_interface="virtual"))


@pytest.fixture(scope="module")
def lab():
    """A running lab shared by the tests of one module (CAN on python-can's virtual bus)."""
    with Lab(LabSettings(seed=5, time_scale=200.0, can_interface="virtual")) as running:
        yield running


@pytest.fixture(autouse=True)
def _clear_lab_faults(request):
    """Faults armed by one test must not leak into the next."""
    yield
    if "lab" in request.fixturenames:
        request.getfixturevalue("lab").world.faults.clear()
        request.getfixturevalue("lab").world.remove_load()


@pytest.fixture
def settle():
    """Function waiting until the simulated settling of a world is practically over."""
    import time

    def wait(world: World, factor: float = 8.0) -> None:
        time.sleep(world.tau * factor + 0.01)

    return wait


@pytest.fixture
def scripted_geocom():
    """Start a one-client GeoCOM line server whose replies a test scripts.

    Call it with ``reply(rpc, trid) -> bytes``: for each request line (empty
    lines are skipped, as instruments skip the driver's leading LF) it sends
    what ``reply`` returns: bytes, or a tuple of bytes sent one write each.
    Returns the ``socket://`` address; the listening socket is closed at the
    end of the test.
    """
    import socket
    import threading

    from drivers import geocom

    servers = []

    def start(reply) -> str:
        srv = socket.socket()
        srv.bind(("127.0.0.1", 0))
        srv.listen(1)
        servers.append(srv)

        def serve():
            conn, _ = srv.accept()
            with conn, conn.makefile("rb") as f:
                for line in f:
                    if not line.strip():
                        continue
                    rpc, _, trid = geocom.decode_request(line)
                    out = reply(rpc, trid)
                    for chunk in out if isinstance(out, tuple) else (out,):
                        conn.sendall(chunk)

        threading.Thread(target=serve, daemon=True).start()
        return f"socket://127.0.0.1:{srv.getsockname()[1]}"

    yield start
    for srv in servers:
        srv.close()
