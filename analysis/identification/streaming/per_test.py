"""Per-test arrays of one large campaign, made a block of tests at a time when sliced.

An identification passes several times over arrays with one 6 x n block per test:
the Jacobian J(q) (m, 6, 6), the design A (m, 6, p) of the linear model, the
whitening of the residual covariances. At 1e6 tests each is 0.3 GB. Above
:data:`LAZY_TESTS` tests they are not held: these objects stand in for them, and
``obj[s:e]`` computes the rows of tests s..e-1 (the same numbers as a slice of the
full array). Every pass of :mod:`analysis.identification.linalg.sandwich` and of the fits
already walks the tests in blocks, so they take either. Recomputing J costs about
1.3 us per test and pass; holding it would cost 288 bytes per test.

The last block made is kept, because one pass often slices the same block twice
(a design and the covariance made from the same J).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

#: campaigns of more tests than this hold no (m, 6, n) per-test arrays (29 MB each at
#: this size; 0.3 GB at 1e6 tests)
LAZY_TESTS = 100_000


def streamed(m: int, batch: tuple[int, ...] = ()) -> bool:
    """Is a fit of ``m`` tests (in a batch of campaigns of shape ``batch``) streamed: one
    campaign of more than :data:`LAZY_TESTS` tests, whose per-test blocks are made when
    sliced. The one place the campaign's size is decided
    (:func:`analysis.identification.streaming.systems.systems_for`, the Jacobian's blocks)."""
    return not batch and m > LAZY_TESTS


class PerTestBlocks(ABC):
    """Base of the per-test arrays made when sliced: ``shape``, ``ndim``, ``len`` and
    ``obj[key]`` like an ndarray for slices of tests, single tests and ``obj[i, c]``."""

    shape: tuple[int, ...]

    @property
    def ndim(self) -> int:
        return len(self.shape)

    def __len__(self) -> int:
        return self.shape[0]

    @abstractmethod
    def _make(self, start: int, stop: int) -> np.ndarray:
        """The rows of tests start..stop-1 (what each kind of array computes)."""

    def _block(self, start: int, stop: int) -> np.ndarray:
        last = getattr(self, "_last", None)
        if last is not None and last[0] == (start, stop):
            return last[1]
        out = self._make(start, stop)
        self._last = ((start, stop), out)
        return out

    def __getitem__(self, key):
        rest: tuple = ()
        if isinstance(key, tuple):
            key, rest = key[0], key[1:]
        if isinstance(key, (int, np.integer)):
            i = int(key) + (self.shape[0] if key < 0 else 0)
            if not 0 <= i < self.shape[0]:
                raise IndexError(f"test {key} out of range ({self.shape[0]} tests)")
            out = self._block(i, i + 1)[0]
        elif isinstance(key, slice) and key.step in (None, 1):
            start, stop, _ = key.indices(self.shape[0])
            out = self._block(start, max(start, stop))
        else:
            raise TypeError(f"{type(self).__name__} takes a slice of tests or one test, "
                            f"not {key!r}")
        return out[rest] if rest else out

    def __array__(self, dtype=None, copy=None):
        """The whole array (small campaigns and tests only: it is what is not held)."""
        from analysis.identification.linalg.lsq import TEST_BLOCK

        out = np.empty(self.shape)
        for s in range(0, self.shape[0], TEST_BLOCK):
            out[s:s + TEST_BLOCK] = self[s:s + TEST_BLOCK]
        return out if dtype is None else out.astype(dtype)


class PerTestJacobian(PerTestBlocks):
    """J(q) (m, 6, n) of the tests' joint angles ``q`` (m, n) (rad): m/rad, rad/rad."""

    def __init__(self, robot, q: np.ndarray) -> None:
        self.robot, self.q = robot, q
        self.shape = (q.shape[0], 6, q.shape[-1])

    def _make(self, start, stop):
        return self.take(slice(start, stop))

    def take(self, rows) -> np.ndarray:
        """J of the tests ``rows`` (a slice or integer indices)."""
        from analysis.model.kinematics import jacobian

        return jacobian(self.robot, self.q[rows])


class PerTestDesign(PerTestBlocks):
    """The linear model's design A (m, 6, p) of the joints ``cols``, zero rows where not
    ``measured``: ``design_block(J, w)``
    (:mod:`analysis.identification.estimators.linear_model`)."""

    def __init__(self, J, w: np.ndarray, measured: np.ndarray, cols: list[int]) -> None:
        self.J, self.w, self.measured, self.cols = J, w, measured, list(cols)
        self.shape = (w.shape[0], 6, len(self.cols))

    def _make(self, start, stop):
        from analysis.identification.estimators.linear_model import design_block

        sl = slice(start, stop)
        return design_block(self.J[sl], self.w[sl])[..., self.cols] * self.measured[sl, :, None]


class PerTestSigma(PerTestBlocks):
    """The standard deviation of each residual component (m, 6) (m, rad): the square root of
    the diagonal of per-test covariances ``cov`` (an array, or made when sliced with a
    ``take`` of integer rows,
    :class:`~analysis.identification.streaming.covariances.PerTestCovariance`)."""

    def __init__(self, cov) -> None:
        self.cov = cov
        self.shape = (cov.shape[0], 6)

    def _make(self, start, stop):
        return self.take(slice(start, stop))

    def take(self, rows) -> np.ndarray:
        """The sigmas (k, 6) of the tests ``rows`` (a slice or sorted integer indices)."""
        cov = self.cov[rows] if isinstance(rows, slice) else self.cov.take(rows)
        return np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))


def release_freed_heap() -> None:
    """Give the C heap's free pages back to the system (glibc ``malloc_trim``).

    Blocks of tests allocate and free many arrays below glibc's mmap threshold; the pages
    they leave free stay in the process (counted in its resident size) until trimmed.
    Called between the stages of a large identification. A no-op where the C library
    has no malloc_trim.
    """
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.malloc_trim(0)
    except (OSError, AttributeError):
        pass


def is_lazy(a) -> bool:
    """True for a per-test array made when sliced."""
    return isinstance(a, PerTestBlocks)


def apply(A, x: np.ndarray, block: int | None = None) -> np.ndarray:
    """A x per test: (m, 6) from A (m, 6, p) (array or made when sliced) and x (p,)."""
    from analysis.identification.linalg.lsq import TEST_BLOCK

    block = TEST_BLOCK if block is None else block
    m = A.shape[0]
    out = np.empty((m, A.shape[1]))
    for s in range(0, m, block):
        out[s:s + block] = A[s:s + block] @ x
    return out


class PerTestWhitening(PerTestBlocks):
    """The whitening L^-1 (m, 6, 6) of per-test covariances ``cov`` (array or made when
    sliced), rows of unmeasured components zero
    (:func:`analysis.identification.linalg.lsq.whitening`)."""

    def __init__(self, cov, measured: np.ndarray) -> None:
        self.cov, self.measured = cov, measured
        self.shape = (measured.shape[0], 6, 6)

    def _make(self, start, stop):
        from analysis.identification.linalg.lsq import whitening

        return whitening(self.cov[start:stop], self.measured[start:stop])


class PerTestModelJacobian(PerTestBlocks):
    """The exact model's Jacobian F (m, 6, p) with respect to the compliances of the joints
    ``cols`` at ``x_full`` (6,) (rad/(N m)), zero rows where not ``measured``: the
    equilibrium solved again from the deflections ``dq`` (m, 6) (rad) at x_full, which
    it converges from in one Newton step (:mod:`analysis.identification.estimators.exact_model`), or
    from its cold start once ``dq`` is set to None."""

    def __init__(self, robot, q, w, measured, cols, x_full, dq) -> None:
        self.robot, self.q, self.w, self.measured = robot, q, w, measured
        self.cols, self.x_full, self.dq = list(cols), np.array(x_full, dtype=float), dq
        self.shape = (q.shape[0], 6, len(self.cols))

    def _make(self, start, stop):
        from analysis.identification.estimators.exact_model import model_displacement_state

        sl = slice(start, stop)
        # without the deflections (let go after the last full pass) Newton starts cold
        f, F, ok, _ = model_displacement_state(self.robot, self.q[sl], self.x_full, self.w[sl],
                                               True, None if self.dq is None else self.dq[sl])
        self._values = ((start, stop), f)
        return F[..., self.cols] * self.measured[sl, :, None]

    def cold(self) -> PerTestModelJacobian:
        """The same F whose blocks are made from the equilibrium's cold start (without
        ``dq``: 48 MB let go at 1e6 tests)."""
        return PerTestModelJacobian(self.robot, self.q, self.w, self.measured, self.cols,
                                    self.x_full, None)

    def values(self, sl: slice) -> np.ndarray:
        """The model's displacements f (b, 6) (m, rad) of the tests ``sl`` at x_full, from
        the same evaluation as ``self[sl]`` (made by it if that block is not the last)."""
        start, stop, _ = sl.indices(self.shape[0])
        if getattr(self, "_values", (None,))[0] != (start, stop):
            self._last = None
            self[start:stop]
        return self._values[1]
