"""Least squares on per-test blocks: QR, TSQR of tall systems, sandwich covariances,
batched small solves.
"""
