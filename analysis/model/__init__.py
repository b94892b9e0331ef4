"""Robot models: DH tables and robot files read into Pinocchio, and the batched
forward kinematics and Jacobian of the chain (metres, radians)."""
