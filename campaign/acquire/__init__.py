"""``campaign acquire``: run a planned campaign, on hardware or the simulated lab, losing nothing.

Modules: :mod:`.session` (order of steps), :mod:`.preflight` (limits, approach
poses, dry run), :mod:`.instruments` (drivers and the fake lab), :mod:`.runner`
(state machine), :mod:`.settle` (settling from tracker readings),
:mod:`.checks`, :mod:`.geometry`, :mod:`.rundir` (the run directory of
``docs/run_format.md``), :mod:`.progress` (rich, quiet, JSON lines).
"""
