"""A throwaway PostgreSQL cluster for the ledger tests, on 127.0.0.1.

initdb and pg_ctl from Debian's ``postgresql`` package (/usr/lib/postgresql/*/bin)
make a cluster in a temporary directory, run as the ``postgres`` user when the
tests run as root (PostgreSQL refuses root), with password authentication over
TCP. Where the package is missing or the cluster cannot start, :func:`start` raises
:class:`Unavailable` naming the package, and the PostgreSQL tests skip.
"""

from __future__ import annotations

import glob
import os
import shutil
import socket
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

#: the superuser's password of the throwaway cluster (it listens on 127.0.0.1 only)
PASSWORD = "ledger-test-secret"
PACKAGE = "postgresql (Debian package: initdb and pg_ctl)"


class Unavailable(RuntimeError):
    """No PostgreSQL server can be started here."""


@dataclass(frozen=True)
class Cluster:
    """A running cluster: its directory, port and the command prefix to run as its owner."""

    root: Path
    port: int
    bindir: Path
    prefix: tuple[str, ...]

    def url(self, database: str = "postgres", password: str = PASSWORD) -> str:
        return f"postgresql://postgres:{password}@127.0.0.1:{self.port}/{database}"

    def create_database(self, name: str) -> str:
        import psycopg

        with psycopg.connect(f"host=127.0.0.1 port={self.port} user=postgres "
                             f"password={PASSWORD} dbname=postgres", autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)

    def stop(self) -> None:
        subprocess.run([*self.prefix, str(self.bindir / "pg_ctl"), "-D",
                        str(self.root / "data"), "-m", "immediate", "stop"],
                       capture_output=True, timeout=60)
        shutil.rmtree(self.root, ignore_errors=True)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start() -> Cluster:
    """Start a cluster; raise :class:`Unavailable` when it cannot be."""
    dirs = sorted(glob.glob("/usr/lib/postgresql/*/bin"))
    if not dirs or not Path(dirs[-1], "initdb").is_file():
        raise Unavailable(f"{PACKAGE} is not installed")
    bindir = Path(dirs[-1])
    root = Path(tempfile.mkdtemp(prefix="ledger-pg-"))
    prefix: tuple[str, ...] = ()
    if os.geteuid() == 0:
        if shutil.which("runuser") is None:
            raise Unavailable("running as root needs runuser to start PostgreSQL as postgres")
        import pwd

        try:
            owner = pwd.getpwnam("postgres")
        except KeyError:
            raise Unavailable(f"no postgres user: install {PACKAGE}") from None
        os.chown(root, owner.pw_uid, owner.pw_gid)
        prefix = ("runuser", "-u", "postgres", "--")
    (root / "pw").write_text(PASSWORD + "\n")
    if prefix:
        os.chown(root / "pw", owner.pw_uid, owner.pw_gid)
    port = _free_port()
    steps = [
        [*prefix, str(bindir / "initdb"), "-D", str(root / "data"), "-U", "postgres",
         "--pwfile", str(root / "pw"), "--auth=scram-sha-256", "-E", "UTF8",
         "--no-instructions"],
        [*prefix, str(bindir / "pg_ctl"), "-D", str(root / "data"), "-l",
         str(root / "log"), "-w", "-t", "120", "-o",
         f"-p {port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off", "start"],
    ]
    for cmd in steps:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
        if proc.returncode != 0:
            shutil.rmtree(root, ignore_errors=True)
            raise Unavailable(f"{Path(cmd[len(prefix)]).name} failed "
                              f"({(proc.stderr or proc.stdout).strip()[-300:]}); {PACKAGE}")
    return Cluster(root, port, bindir, prefix)
