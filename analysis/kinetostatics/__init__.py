"""Kinetostatics: the Cartesian stiffness K_X = J^-T (K_theta - K_C) J^-1, the
nonlinear equilibrium under a wrench, dexterity (kappa_F of the normalized
Jacobian) and the workspace maps built from them (SI units)."""
