"""Alembic environment of the ledger: runs the migrations on the connection the caller
passes in ``config.attributes["connection"]`` (:func:`campaign.ledger.database.migrate`),
inside the caller's transaction; never reads an alembic.ini nor a URL of its own."""

from alembic import context

from campaign.ledger.schema import Base

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=Base.metadata,
                  render_as_batch=connection.dialect.name == "sqlite")
with context.begin_transaction():
    context.run_migrations()
