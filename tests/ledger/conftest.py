"""Fixtures of the ledger tests: a throwaway PostgreSQL cluster for the session, a fresh
ledger per test on SQLite and on PostgreSQL, and four demo campaigns of one robot on
the simulated lab (the fourth with k2 10 % lower), made once for the session."""

from __future__ import annotations

import re
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.ledger.postgres_cluster import Cluster, Unavailable, start

#: the robot's serial the demo protocols give ([instruments.robot] serial)
SERIAL = "KR-0001"
#: the shipped KR240-2 protocol's true stiffness (Table 2), N m/rad
K_TRUE = [1409800, 400760, 935280, 360000, 370000, 380000]
#: the fourth campaign's k2 factor: the gearbox of joint 2 has lost 10 %
K2_WORN = 0.9


@pytest.fixture(scope="session")
def pg_cluster() -> Iterator[Cluster | str]:
    """The session's PostgreSQL cluster, or the reason it cannot start."""
    try:
        cluster = start()
    except Unavailable as why:
        yield str(why)
        return
    try:
        yield cluster
    finally:
        cluster.stop()


def new_ledger(backend: str, pg_cluster, tmp_path: Path) -> str:
    """The URL of an empty ledger on ``backend`` (skips PostgreSQL where it cannot start)."""
    if backend == "sqlite":
        return f"sqlite:///{tmp_path / 'ledger.sqlite'}"
    if isinstance(pg_cluster, str):
        pytest.skip(f"PostgreSQL unavailable: {pg_cluster}")
    return pg_cluster.create_database(f"ledger_{uuid.uuid4().hex[:12]}")


@pytest.fixture(params=["sqlite", "postgresql"])
def ledger(request, pg_cluster, tmp_path) -> str:
    """A fresh ledger URL, on each backend in turn."""
    return new_ledger(request.param, pg_cluster, tmp_path)


def demo_protocol(text: str, seed: int, k: list[float]) -> str:
    """The shipped KR240-2 protocol with the robot's serial, the lab's seed and stiffness."""
    text, n1 = re.subn(r'(\[instruments\.robot\]\n(?:.*\n)*?address = .*\n)',
                       rf'\1serial = "{SERIAL}"\n', text, count=1)
    text, n2 = re.subn(r"^seed = \d+", f"seed = {seed}", text, flags=re.M)
    text, n3 = re.subn(r"^true_joint_stiffness = \[.*\]",
                       f"true_joint_stiffness = {[float(v) for v in k]}", text, flags=re.M)
    assert (n1, n2, n3) == (1, 1, 1), "the shipped protocol's layout changed"
    return text


@pytest.fixture(scope="session")
def demo_runs(tmp_path_factory) -> list[Path]:
    """Run directories of four demo campaigns of robot KR-0001 on the simulated lab (seeds
    1-4); the fourth with k2 10 % lower."""
    from campaign.jobs.demo import DemoOptions, run
    from campaign.shipped_protocols import shipped_protocol

    root = tmp_path_factory.mktemp("demo-campaigns")
    text = shipped_protocol("kr240-2").read_text(encoding="utf-8")
    runs = []
    for i in range(1, 5):
        k = list(K_TRUE)
        if i == 4:
            k[1] *= K2_WORN
        protocol = root / f"protocol{i}.toml"
        protocol.write_text(demo_protocol(text, i, k), encoding="utf-8")
        # the protocol's lab clock (50 x the wall clock): a faster one gives the same
        # readings but leaves less margin to the lab's sampling deadlines on a loaded machine
        result = run(DemoOptions(root / f"c{i}", protocol, report=False))
        assert result.succeeded
        runs.append(root / f"c{i}" / "run")
    return runs
