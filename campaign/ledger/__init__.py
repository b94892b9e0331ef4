"""The fleet ledger: every campaign of every robot in one database.

:mod:`.schema` declares the table (SQLAlchemy 2 typed ORM); :mod:`.migrations`
holds the Alembic scripts that create and upgrade it; :mod:`.database` opens a
ledger from a URL (SQLite file or PostgreSQL through psycopg) and migrates it;
:mod:`.entry` reads one campaign (run or analysis directory) into an immutable
:class:`~campaign.ledger.entry.LedgerEntry`; :mod:`.store` adds and queries
records; :mod:`.drift` holds the statistics (pure functions of numbers). Nothing
here is imported by ``campaign --help``: SQLAlchemy loads when a ledger command runs.
"""
