"""CLI sub-commands: each module here exposes ``register(app)``.

Modules are discovered by :func:`campaign.cli.app.build_app`, so a new command is a
new file and works as such. Listing it in :data:`campaign.cli.app.LAZY_COMMANDS`
(name, module, one-line help) defers its import until it is invoked. Either
way a command module imports only light modules at its top (typer, rich,
numpy, analysis.errors, campaign.options); pandas, scipy, matplotlib,
pinocchio and the analysis code that pulls them in are imported inside the
command function, so that start-up stays fast (tests/project/test_startup_imports.py).
"""
