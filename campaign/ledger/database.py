"""Open a ledger: a URL (or a file path) -> a migrated SQLAlchemy engine.

The ledger is named explicitly, by ``--db URL`` or the environment variable
:data:`ENV` (never a default path): a plain path or ``sqlite:///PATH`` is an
SQLite file, ``postgresql://user:password@host:port/db`` a PostgreSQL database
reached through psycopg 3. Opening migrates the schema to the head revision
(Alembic, run in code on the caller's connection, under a lock: PostgreSQL's
advisory lock, SQLite's write lock), so two stations opening one ledger at once
migrate it once. Every failure to reach, read or write the database is one
:class:`InputError` whose text names the URL without its password.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from analysis.errors import InputError

#: the environment variable that names the ledger when ``--db`` is not given
ENV = "STIFFNESS_CAMPAIGN_DB"

#: key of PostgreSQL's advisory lock around migrations (any fixed 64-bit number)
MIGRATION_LOCK = 7_301_033

#: execution option of a transaction that writes (SQLite: BEGIN IMMEDIATE)
WRITE = "ledger_write"

#: seconds an SQLite writer waits for another writer's lock before giving up
SQLITE_BUSY_S = 60.0


def ledger_url(db: str | None) -> str:
    """The ledger's URL from ``--db`` or :data:`ENV`; refuses neither given."""
    text = (db if db is not None else os.environ.get(ENV, "")).strip()
    if not text:
        raise InputError(f"no ledger: give --db URL (an SQLite file path, sqlite:///PATH or "
                         f"postgresql://user@host/db) or set {ENV}", where="--db")
    if "://" not in text:
        return "sqlite:///" + str(Path(text).expanduser().resolve())
    return text


def shown(url) -> str:
    """The URL as printed: the password replaced by ***."""
    from sqlalchemy.engine import make_url

    try:
        return make_url(str(url)).render_as_string(hide_password=True)
    except Exception:  # an unparsable URL: show its scheme only
        return str(url).split("://", 1)[0] + "://..."


def _sqlite_file(url) -> Path | None:
    """The SQLite file of ``url`` (``sqlite:///PATH`` or the URI form
    ``sqlite:///file:PATH?mode=ro&uri=true``), None for an in-memory database."""
    db = url.database
    if db and db.startswith("file:"):
        db = db.removeprefix("file:").split("?", 1)[0]
    return None if not db or db == ":memory:" else Path(db)


def _parse(text: str):
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    try:
        url = make_url(text)
    except ArgumentError:
        raise InputError("not a database URL (expected sqlite:///PATH or "
                         "postgresql://user@host:port/db)", where="--db") from None
    backend = url.get_backend_name()
    if backend == "postgresql":
        return url.set(drivername="postgresql+psycopg")
    if backend != "sqlite":
        raise InputError(f"{backend}: unsupported database (the ledger runs on SQLite or "
                         "PostgreSQL)", where=shown(url))
    return url


def _sqlite_engine(url):
    from sqlalchemy import create_engine, event

    engine = create_engine(url, connect_args={"timeout": SQLITE_BUSY_S})

    @event.listens_for(engine, "connect")
    def _autocommit_driver(dbapi_connection, record):
        # SQLAlchemy emits BEGIN itself (below): the driver's implicit transactions off
        dbapi_connection.isolation_level = None

    @event.listens_for(engine, "begin")
    def _begin(conn):
        # a writing transaction takes the write lock first: writers queue (busy timeout)
        # instead of failing half-way; a reading one takes none (a read-only file reads)
        write = conn.get_execution_options().get(WRITE, False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")

    return engine


def open_ledger(db: str | None, *, create: bool):
    """A migrated engine for the ledger ``db`` (see :func:`ledger_url`).

    ``create``: an SQLite file that does not exist is created (``history add``,
    the analysis recording); otherwise a missing file is refused. A read-only file,
    a server that cannot be reached or refuses the credentials: one InputError.
    """
    from sqlalchemy import create_engine

    url = _parse(ledger_url(db))
    where = shown(ledger_url(db))
    if url.get_backend_name() == "sqlite":
        path = _sqlite_file(url)
        if path is not None:
            if not path.exists():
                if not create:
                    raise InputError("no ledger file here (history add creates one)",
                                     where=str(path))
                if not path.parent.is_dir():
                    raise InputError("the ledger's directory does not exist",
                                     where=str(path.parent))
            elif not path.is_file():
                raise InputError("not a file", where=str(path))
            elif create and not path.stat().st_mode & (stat.S_IWUSR | stat.S_IWGRP
                                                       | stat.S_IWOTH):
                raise InputError("the ledger file is read-only", where=str(path))
        engine = _sqlite_engine(url)
    else:
        engine = create_engine(url, connect_args={"connect_timeout": 10},
                               pool_pre_ping=True)
    try:
        migrate(engine)
    except InputError:
        engine.dispose()
        raise
    except Exception as err:
        engine.dispose()
        raise database_error(err, where) from None
    return engine


def database_error(err: Exception, where: str) -> InputError:
    """A driver's error as one line naming the database (never its password)."""
    from sqlalchemy.exc import DBAPIError

    orig = err.orig if isinstance(err, DBAPIError) and err.orig is not None else err
    lines = [s.strip() for s in str(orig).splitlines() if s.strip()]
    text = " ".join(lines) if lines else type(orig).__name__
    if "readonly" in text or "read-only" in text:
        text = "the ledger is read-only: " + text
    if "not a database" in text:
        text = "not an SQLite ledger: " + text
    return InputError(f"cannot use the ledger: {text}"[:300], where=where)


def writer(engine):
    """``engine`` for a transaction that writes (on SQLite it takes the write lock first)."""
    return engine.execution_options(**{WRITE: True})


def _revisions(conn, config) -> tuple[str | None, str]:
    """(the ledger's revision, the head revision of the shipped migrations)."""
    from alembic.runtime.migration import MigrationContext
    from alembic.script import ScriptDirectory

    return (MigrationContext.configure(conn).get_current_revision(),
            ScriptDirectory.from_config(config).get_current_head())


def migrate(engine, revision: str = "head") -> None:
    """Bring the ledger's schema to ``revision`` (the head; Alembic, in one transaction
    under the write lock, after a look without one: a current ledger is not written)."""
    from alembic import command
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(Path(__file__).parent / "migrations"))
    with engine.connect() as conn:
        current, head = _revisions(conn, config)
    if revision == "head" and current == head:
        return
    with writer(engine).begin() as conn:
        if conn.dialect.name == "postgresql":
            conn.exec_driver_sql(f"SELECT pg_advisory_xact_lock({MIGRATION_LOCK})")
        config.attributes["connection"] = conn
        command.upgrade(config, revision)
