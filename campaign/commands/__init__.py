"""CLI sub-commands: each module here exposes ``register(app)``.

Modules are discovered by :func:`campaign.cli.build_app`, so a new command is a
new file and no shared list has to be edited.
"""
