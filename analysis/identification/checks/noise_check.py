"""Do the residuals agree with the declared noise? Per component group, which one is off.

The identification weights every residual by the declared noise
(:func:`analysis.identification.noise.residual_covariance`). For each group
of measured components -- translations and rotations -- the ratio
``s = sqrt(mean((r / sigma)^2) / (1 - p / n))`` estimates actual over declared
noise (``sigma`` the declared standard deviation of each residual, ``p``
parameters, ``n`` equations: the fit absorbs p of the n degrees of freedom).
A group with ``s > FACTOR`` or ``s < 1 / FACTOR`` is named, with the term
that dominates its declared sigma (tracker or F/T through the compliance),
so the user knows which figure to revisit.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.noise import NoiseModel

FACTOR = 2.0
#: fewer residuals than this in a group make its ratio too uncertain to judge
MIN_RESIDUALS = 8


def noise_ratio_notes(
    residual,
    sigma: np.ndarray,
    measured: np.ndarray,
    noise: NoiseModel,
    n_params: int,
    factor: float = FACTOR,
    block: int = 8192,
) -> list[str]:
    """Messages for component groups whose residuals disagree with the declared noise.

    Parameters
    ----------
    residual : (m, 6) measured minus predicted displacement (m, rad), or the pair
        (measured, predicted) of (m, 6) arrays it is the difference of (taken block by
        block: no (m, 6) copy).
    sigma : (m, 6) declared standard deviation of each residual component (m, rad): the
        square root of the diagonal of each test's residual covariance (an array, or
        made when sliced, :class:`~analysis.identification.streaming.per_test.PerTestSigma`).
    measured : (m, 6) bool. noise : the declared noise model. n_params : fitted parameters.
    """
    def resid(sl, cols):
        if isinstance(residual, tuple):
            return residual[0][sl, cols] - residual[1][sl, cols]
        return residual[sl, cols]

    m = measured.shape[0]
    n_eq = int(measured.sum())
    if n_eq <= n_params:
        return []
    keep = 1.0 - n_params / n_eq
    notes = []
    for name, cols, disp in (("translation", slice(0, 3), noise.translation_sigma),
                             ("rotation", slice(3, 6), noise.rotation_sigma)):
        count = int(measured[:, cols].sum())
        if count < MIN_RESIDUALS:
            continue
        sq = 0.0
        for s in range(0, m, block):
            sl = slice(s, s + block)
            z = (resid(sl, cols) / sigma[sl][:, cols])[measured[sl, cols]]
            sq += float(np.sum(z**2))
        ratio = float(np.sqrt(sq / count / keep))
        if 1.0 / factor <= ratio <= factor:
            continue
        # which declared term dominates this group's sigma
        mask = measured[:, cols]
        sig = np.concatenate([sigma[s:s + block][:, cols][mask[s:s + block]]
                              for s in range(0, m, block)])
        ft_share = float(np.median(1.0 - (disp / sig) ** 2))
        source = ("the F/T noise (it dominates the declared sigma through the compliance)"
                  if ft_share > 0.5 else
                  f"the {'tracker' if name == 'translation' else 'rotation (tracker fit or probe)'}"
                  " noise")
        way = "too small" if ratio > factor else "too large"
        options = ("--force-sigma-N, --moment-sigma-Nm, --force-pct, --moment-pct"
                   if ft_share > 0.5 else
                   "--translation-sigma-um" if name == "translation" else
                   "--rotation-sigma-urad")
        notes.append(f"{name} residuals are {ratio:.2g} times the declared noise: {source} looks "
                     f"{way} by about that factor (check the instrument figures or the "
                     f"options {options})")
    return notes
