"""Instrument noise model: standard deviations of what a stiffness test measures.

Every default is a typical figure from instrument specifications, overridable.
A specification's maximum permissible error (MPE) is read as a 2-sigma bound
(sigma = MPE / 2), the usual reading of an MPE quoted with a coverage factor
k = 2 (ISO 10360 / ASME B89.4.19 practice for laser trackers).

Defaults and where they come from
---------------------------------
* Laser tracker point (3-DoF): MPE 15 um + 6 um/m transverse and
  10 um + 0.3 um/m in distance (interferometer) -- typical of current laser
  trackers (manufacturers' MPE figures per ISO 10360-10), at ``tracker_distance``
  = 3 m from the tool. Direction to the tracker unknown: per base-frame
  component, sigma^2 = (2 sigma_t^2 + sigma_r^2) / 3.
* A displacement is the difference of two measured poses (unloaded, loaded):
  the variances add (factor 2).
* Rotation, ``rotation_source = "reflectors"``: least-squares fit of the
  rigid motion of three reflectors at the corners of an equilateral
  triangle of circumradius ``reflector_radius`` (default 0.10 m). For points
  r_i with noise sigma the information matrix of the small rotation is
  sum(|r_i|^2 I - r_i r_i^T) / sigma^2 = diag(3/2, 3/2, 3) rho^2 / sigma^2,
  so sigma_rot = sigma_point * sqrt(2/3) / rho (in-plane axes; the normal
  axis is better by sqrt 2). The plate orientation is unknown, so the
  in-plane value is used for all three components (conservative).
* Rotation, ``rotation_source = "probe"``: a 6-DoF probe with an orientation
  MPE of 0.01 deg (typical of tracker 6-DoF probes; check the data sheet).
* Wrench: six-axis force/torque sensor of 2500 N / 400 N m full scale
  (ATI Omega160 class) with an uncertainty of 1.25 % of full scale at 95 %:
  sigma_f = 15.6 N, sigma_m = 2.5 N m. Taring and gravity compensation are
  assumed done; drift is not modelled.
  A sensor specified in % of the reading adds ``force_relative`` times the
  magnitude of the measured force (and ``moment_relative`` times that of the
  moment) to every component, in quadrature with the absolute sigma.
* Joint angles: encoder resolution 0.001 deg, quantisation sigma =
  resolution / sqrt(12) (joint-angle calibration errors are not modelled),
  or ``joint_sigma_override``. Joint-angle noise moves the model's
  displacement by ``sum_k dd/dq_k dq_k``; :func:`residual_covariance` adds that
  term when it is given the derivative.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from analysis.errors import InputError

MPE_COVERAGE = 2.0


@dataclass(frozen=True)
class NoiseModel:
    """Instrument figures (SI). See the module docstring for the defaults' sources.

    Attributes
    ----------
    tracker_transverse_mpe_m, tracker_transverse_mpe_per_m : transverse MPE
        a + b * distance (m, m/m).
    tracker_distance_mpe_m, tracker_distance_mpe_per_m : distance MPE (m, m/m).
    tracker_distance : tracker-to-tool distance (m).
    rotation_source : ``"reflectors"`` (3-DoF tracker, three reflectors) or ``"probe"``.
    reflector_radius : circumradius of the reflector triangle (m).
    probe_rotation_mpe : 6-DoF probe orientation MPE (rad).
    force_sigma : per force component (N). moment_sigma : per moment component (N m).
    encoder_resolution : joint encoder resolution (rad).
    translation_sigma_override, rotation_sigma_override : if set, the standard
        deviation of one displacement component (m, rad) used as is.
    force_relative, moment_relative : wrench noise proportional to the reading,
        as a fraction of |f| (of |m|) per component (0.005 = 0.5 % of reading).
    joint_sigma_override : if set, sigma of a joint angle reading (rad).
    """

    tracker_transverse_mpe_m: float = 15e-6
    tracker_transverse_mpe_per_m: float = 6e-6
    tracker_distance_mpe_m: float = 10e-6
    tracker_distance_mpe_per_m: float = 0.3e-6
    tracker_distance: float = 3.0
    rotation_source: str = "reflectors"
    reflector_radius: float = 0.10
    probe_rotation_mpe: float = np.radians(0.01)
    force_sigma: float = 0.0125 * 2500.0 / MPE_COVERAGE
    moment_sigma: float = 0.0125 * 400.0 / MPE_COVERAGE
    encoder_resolution: float = np.radians(0.001)
    translation_sigma_override: float | None = None
    rotation_sigma_override: float | None = None
    force_relative: float = 0.0
    moment_relative: float = 0.0
    joint_sigma_override: float | None = None

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if name == "rotation_source" or value is None:
                continue
            if not np.isfinite(value) or value < 0:
                raise InputError(f"must be a finite number >= 0, got {value!r}", where=name)
        if self.rotation_source not in ("reflectors", "probe"):
            raise InputError(
                f"expected 'reflectors' or 'probe', got {self.rotation_source!r}",
                where="rotation_source",
            )
        if self.rotation_source == "reflectors" and self.reflector_radius <= 0:
            raise InputError("must be > 0", where="reflector_radius")

    @property
    def point_sigma(self) -> float:
        """sigma of one tracker point coordinate along a base axis (m)."""
        st = (self.tracker_transverse_mpe_m
              + self.tracker_transverse_mpe_per_m * self.tracker_distance) / MPE_COVERAGE
        sr = (self.tracker_distance_mpe_m
              + self.tracker_distance_mpe_per_m * self.tracker_distance) / MPE_COVERAGE
        return float(np.sqrt((2 * st**2 + sr**2) / 3.0))

    @property
    def translation_sigma(self) -> float:
        """sigma of one component of a measured displacement (loaded - unloaded) (m)."""
        if self.translation_sigma_override is not None:
            return float(self.translation_sigma_override)
        return float(np.sqrt(2.0) * self.point_sigma)

    @property
    def rotation_sigma(self) -> float:
        """sigma of one component of a measured small rotation (loaded vs unloaded) (rad)."""
        if self.rotation_sigma_override is not None:
            return float(self.rotation_sigma_override)
        if self.rotation_source == "probe":
            one = self.probe_rotation_mpe / MPE_COVERAGE
        else:
            one = self.point_sigma * np.sqrt(2.0 / 3.0) / self.reflector_radius
        return float(np.sqrt(2.0) * one)

    @property
    def displacement_sigma(self) -> np.ndarray:
        """(6,) sigma of [dx dy dz (m); rx ry rz (rad)]."""
        return np.array([self.translation_sigma] * 3 + [self.rotation_sigma] * 3)

    @property
    def wrench_sigma(self) -> np.ndarray:
        """(6,) sigma of [fx fy fz (N); mx my mz (N m)]."""
        return np.array([self.force_sigma] * 3 + [self.moment_sigma] * 3)

    def wrench_sigma_at(self, wrench: np.ndarray | None = None) -> np.ndarray:
        """(..., 6) sigma of each wrench component for readings ``wrench`` (..., 6) (N, N m).

        Absolute sigma in quadrature with the part proportional to the reading
        (``force_relative`` |f|, ``moment_relative`` |m|); :attr:`wrench_sigma`
        when ``wrench`` is None or the relative parts are zero.
        """
        if wrench is None or (self.force_relative == 0 and self.moment_relative == 0):
            return self.wrench_sigma if wrench is None else np.broadcast_to(
                self.wrench_sigma, np.shape(wrench)).copy()
        w = np.asarray(wrench, dtype=float)
        f = self.force_relative * np.linalg.norm(w[..., :3], axis=-1)
        m = self.moment_relative * np.linalg.norm(w[..., 3:], axis=-1)
        sf = np.sqrt(self.force_sigma**2 + f**2)
        sm = np.sqrt(self.moment_sigma**2 + m**2)
        return np.concatenate([np.repeat(sf[..., None], 3, -1), np.repeat(sm[..., None], 3, -1)],
                              axis=-1)

    @property
    def joint_sigma(self) -> float:
        """sigma of a joint angle reading (rad): the override, else resolution / sqrt(12)."""
        if self.joint_sigma_override is not None:
            return float(self.joint_sigma_override)
        return float(self.encoder_resolution / np.sqrt(12.0))

    def with_overrides(self, **values) -> NoiseModel:
        """A copy with the given fields replaced (``None`` values are ignored)."""
        return replace(self, **{k: v for k, v in values.items() if v is not None})

    def describe(self) -> dict:
        """Figures in report units, for results files."""
        return {
            "translation_sigma_um": self.translation_sigma * 1e6,
            "rotation_sigma_urad": self.rotation_sigma * 1e6,
            "force_sigma_N": self.force_sigma,
            "moment_sigma_Nm": self.moment_sigma,
            "force_relative_percent": 100 * self.force_relative,
            "moment_relative_percent": 100 * self.moment_relative,
            "joint_sigma_deg": float(np.degrees(self.joint_sigma)),
            "rotation_source": self.rotation_source,
            "tracker_distance_m": self.tracker_distance,
            "mpe_read_as": "2 sigma",
        }


def residual_covariance(
    noise: NoiseModel,
    compliance: np.ndarray | None = None,
    wrench: np.ndarray | None = None,
    joint_gradient: np.ndarray | None = None,
) -> np.ndarray:
    """Covariance (..., 6, 6) of the residual ``d_measured - A x`` of one test.

    ``Sigma = diag(sigma_d^2) + C diag(sigma_w^2) C^T [+ sigma_q^2 G G^T]``: the
    displacement noise plus the wrench noise propagated at first order through
    the Cartesian compliance ``C = J K_theta^-1 J^T`` (m/N, rad/(N m), ...),
    since the model ``A x = C w`` is evaluated at the measured wrench.
    ``wrench`` (..., 6) (N, N m): the readings, for noise proportional to the
    reading (:meth:`NoiseModel.wrench_sigma_at`). ``joint_gradient`` (..., 6, n):
    derivative of the model displacement with respect to the measured joint
    angles (m/rad, rad/rad), for the encoder term; left out when None (with
    encoder quantisation it is ~1e-5 of the deflection, far below the rest).
    ``compliance`` None gives the displacement term only.
    """
    sig = np.diag(noise.displacement_sigma**2)
    if compliance is not None:
        C = np.asarray(compliance, dtype=float)
        ws2 = noise.wrench_sigma_at(wrench) ** 2
        # C diag(s^2) C^T as a batched matmul (a 3-operand einsum is ~5x slower at 1e6 tests)
        sig = sig + (C * ws2[..., None, :]) @ np.swapaxes(C, -1, -2)
    if joint_gradient is not None:
        G = np.asarray(joint_gradient, dtype=float)
        sig = sig + noise.joint_sigma**2 * (G @ np.swapaxes(G, -1, -2))
    return sig


def rigid_fit_sigma(
    points: np.ndarray, sigma: float, point: np.ndarray | None = None
) -> tuple[float, float]:
    """Standard deviations of a tool pose fitted to N >= 3 reflectors measured in turn.

    Each reflector position (tool frame, m) is measured with isotropic noise
    ``sigma`` (m per coordinate). Linearising the rigid fit about the truth, the
    small rotation has covariance ``sigma^2 M^-1`` with
    ``M = sum_i (|c_i|^2 I - c_i c_i^T)`` (c_i: positions about their centroid),
    and the fitted position of ``point`` (default the tool frame's origin, P) has
    ``sigma^2 / N I + [d]x M^-1 [d]x^T sigma^2`` with d its offset from the centroid.

    Returns
    -------
    (sigma_translation, sigma_rotation) : the largest per-axis standard
    deviation of P's position (m) and of the rotation vector (rad).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 3:
        raise ValueError("expected at least three reflector positions (N, 3) in m")
    c = pts - pts.mean(axis=0)
    M = np.sum(np.einsum("ni,ni->n", c, c))[None, None] * np.eye(3) - c.T @ c
    if np.linalg.cond(M) > 1e12:
        raise ValueError("reflectors are collinear: the rotation about their line is unknown")
    cov_r = sigma**2 * np.linalg.inv(M)
    d = (np.zeros(3) if point is None else np.asarray(point, dtype=float)) - pts.mean(axis=0)
    dx = np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
    cov_t = sigma**2 / pts.shape[0] * np.eye(3) + dx @ cov_r @ dx.T
    return float(np.sqrt(np.max(np.diag(cov_t)))), float(np.sqrt(np.max(np.diag(cov_r))))
