"""Robot programs written from computed joint targets (KRL for KUKA, URScript for UR)."""
