"""Monte-Carlo studies: the paper's robustness curve (robustness), simulated campaigns of a
design (design_simulation).
"""
