"""Reading a run directory as ``docs/run_format.md`` defines it.

:mod:`~campaign.run_format.reader` reads and checks a run (finished or partial),
:mod:`~campaign.run_format.tests_meta` the ``tests.meta.json`` sidecar of a tests
CSV file, :mod:`~campaign.run_format.trace` what the report's traceability needs.
The run is written by :mod:`campaign.acquire` (``rundir``, ``session``).
"""
