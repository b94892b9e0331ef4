"""What the project writes for other tools: robot programs from computed joint targets (KRL for
KUKA, URScript for UR, RAPID, FANUC TP) and simulator descriptions of the robot with its
joint springs (MJCF, URDF, SDFormat: :mod:`analysis.export.sim_model`)."""
