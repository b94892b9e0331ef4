"""One campaign's model evaluated a block of tests at a time.

:data:`EVAL_BLOCK` tests per block keep the equilibrium's working arrays in cache; the
per-test covariances (:mod:`~analysis.identification.streaming.covariances`) and the
linearised systems (:mod:`~analysis.identification.streaming.systems`) use the same
blocks.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.estimators.exact_model import model_displacement_state

#: tests per block when one campaign's model is evaluated: the equilibrium's working
#: arrays then stay in cache (measured on 1e5 KR240-2 tests, warm start with the model
#: Jacobian: 2.0-2.2 us/test in blocks of 4096, 2.7-3.4 in blocks of 8192; 41 us/test as
#: one block of 1e5 before the entry-major kernels)
EVAL_BLOCK = 4096


def model_in_blocks(robot, q, x, w, with_jacobian, dq0=None, cols=None, measured=None,
                     out=None, tips=None, w_ref=None):
    """:func:`model_displacement_state` for one campaign (q (m, 6)) in blocks of tests.

    ``dq0`` (..., m, 6): Newton's starting deflections (the previous iterate's), or None.
    Returns f, F (or None), ok, dq; F (..., m, 6, len(cols)) holds the columns ``cols``
    (default all) with zero rows where not ``measured`` (default all measured), made
    block by block.
    """
    # ``tips``: a dict kept by the caller across evaluations at the same q: the unloaded
    # tool poses (m, 4, 4), filled on first use (the unloaded chain does not depend on x)
    def select(F, sl=slice(None)):
        F = F if cols is None else F[..., cols]
        return F if measured is None else F * measured[sl][..., None]

    if q.ndim != 2 or q.shape[0] <= EVAL_BLOCK:
        f, F, ok, dq = model_displacement_state(robot, q, x, w, with_jacobian, dq0,
                                                w_ref=w_ref)
        return f, None if F is None else select(F), ok, dq
    m = q.shape[0]
    f, ok, dq = np.empty((m, 6)), np.empty(m, dtype=bool), np.empty(q.shape)
    if tips is not None and "tip" not in tips:
        tips["tip"] = np.empty((m, 4, 4))
        tips["filled"] = np.zeros(m, dtype=bool)
    shape = (m, 6, q.shape[-1] if cols is None else len(cols))
    # ``out``: a model Jacobian no longer needed, overwritten (its page faults are saved)
    F = (out if out is not None and out.shape == shape else np.empty(shape)) \
        if with_jacobian else None
    for s in range(0, m, EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        unloaded = None
        if tips is not None:  # the unloaded tool pose of each block, computed once
            unloaded = {"tip": tips["tip"][sl]} if tips["filled"][s] else {}
        fb, Fb, okb, dqb = model_displacement_state(robot, q[sl], x, w[sl], with_jacobian,
                                                    None if dq0 is None else dq0[sl],
                                                    unloaded=unloaded,
                                                    w_ref=None if w_ref is None
                                                    else w_ref[..., sl, :])
        if tips is not None and not tips["filled"][s]:
            tips["tip"][sl] = unloaded["tip"]
            tips["filled"][sl] = True
        f[sl], ok[sl], dq[sl] = fb, okb, dqb
        if with_jacobian:
            F[sl] = select(Fb, sl)
    return f, F, ok, dq
