"""Using an identified model: compensation along a path, workpiece placement.

:mod:`~campaign.use.path_file` reads path files, :mod:`~campaign.use.compensate_output`
writes what ``campaign compensate`` produces and :mod:`~campaign.use.verify_fake`
checks a compensation on the simulated lab; :mod:`~campaign.use.place_run` builds,
runs and writes the placement search. The jobs are :mod:`campaign.jobs.compensate`
and :mod:`campaign.jobs.place`.
"""
