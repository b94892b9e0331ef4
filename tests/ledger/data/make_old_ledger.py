"""Write ledger_rev0001.sqlite: a ledger at the first schema revision with one record.

The test of the migration (tests/ledger/test_ledger_reliability.py) opens the
committed file and checks that the record survives the upgrade to the head. The
record is a demo campaign of robot KR-0001 (``campaign demo`` with serial KR-0001,
seed 1). Run: ``python tests/ledger/data/make_old_ledger.py RUN_DIR``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from sqlalchemy import MetaData, create_engine, insert

from campaign.ledger.database import migrate
from campaign.ledger.entry import read_entry
from campaign.ledger.store import _row

OUT = Path(__file__).with_name("ledger_rev0001.sqlite")


def main(run: str) -> None:
    OUT.unlink(missing_ok=True)
    engine = create_engine(f"sqlite:///{OUT}")
    migrate(engine, "0001")
    meta = MetaData()
    meta.reflect(engine)
    table = meta.tables["campaigns"]
    row = _row(read_entry(Path(run)))
    values = {c.name: getattr(row, c.name) for c in table.columns if c.name != "id"}
    with engine.begin() as conn:
        conn.execute(insert(table).values(**values))
    engine.dispose()
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main(sys.argv[1])
