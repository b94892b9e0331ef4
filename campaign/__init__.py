"""Campaign protocol files, planner, acquisition runner and the ``campaign`` CLI."""
