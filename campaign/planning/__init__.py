"""Planning a campaign: candidate poses in the zones, design criteria, the optimal set of tests.

:mod:`~campaign.planning.candidates` draws and filters candidate poses,
:mod:`~campaign.planning.design` and :mod:`~campaign.planning.criteria` score a
design under the identification's noise model, :mod:`~campaign.planning.separation`
keeps planned poses apart, :mod:`~campaign.planning.planner` chooses the tests and
:mod:`~campaign.planning.plan_output` / :mod:`~campaign.planning.plan_map` write
the plan directory. The job that runs it is :mod:`campaign.jobs.plan`.
"""
