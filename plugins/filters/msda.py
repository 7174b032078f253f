"""Multi-scan data association by a wavelet transform, MSDA (SPEC §6; seed 004).

Seed 004 ("Алгоритм объединения данных с использованием вейвлет-преобразования",
its ref. [15]: Tian & Jing, "A multi-space data association algorithm for target
tracking systems", Commun. Nonlinear Sci. Numer. Simul. 12(4), 2007): "over
several scans the measurement nearest the prediction is selected; from these
measurements a single image Z_p is formed by a wavelet transform; it updates the
target's state at the current scan with the Kalman filter"; like nearest
neighbour it needs no clutter density or P_D.

What the seed leaves open, and the choices made here:

1. *Nearest to which prediction.*  At each scan k the gated candidate nearest in
   Mahalanobis distance to that scan's own prediction ẑ_k = H x⁻_k, exactly the
   nearest-neighbour choice (d² = νᵀS⁻¹ν ≤ γ, P(χ²_m ≤ γ) = P_G).
2. *What the transform acts on.*  The window's residuals (innovations) of the
   chosen candidates, ν_j = z*_j − H x⁻_j, j = k−N+1 … k (each against its own
   prediction): they are comparable across scans (all zero-mean under the
   target hypothesis), unlike the measurements themselves, which move with the
   target.
3. *The transform and Z_p.*  The discrete wavelet decomposition of the residual
   sequence (PyWavelets ``wavedec``, ``wavelet`` default Haar, ``level`` J
   default the deepest, ``pywt.dwt_max_level(N, wavelet)``, mode
   ``periodization``), the detail coefficients set to zero, the approximation
   reconstructed (``waverec``) and its newest sample taken as the fused
   residual ν_p; mapped back to the newest time, Z_p = ẑ_k + ν_p.  For the Haar
   wavelet and N = 2^J this is the mean of the window's residuals
   (ν_p = (1/N) Σ_j ν_j): the transform is a low-pass filter of the innovation
   sequence, which damps a single clutter pick.
4. *Missing entries.*  A scan with nothing gated, one of another sensor
   configuration (a different H), or one before the first scan contributes the
   newest residual ν_k in its place (no information of its own); when the
   newest scan has nothing gated, prediction only (as NN).
5. *The update.*  The Kalman update with ν_p, S = H P⁻ Hᵀ + R and the sensor's R
   (K = P⁻ Hᵀ S⁻¹, Joseph form): Z_p is treated as one measurement of the
   newest state.  The correlation of ν_p with earlier updates (the window's
   residuals were already used) is ignored, as NN ignores that z* may be false.

With ``window = 1`` the fused residual is the chosen one and MSDA is exactly the
nearest-neighbour filter (tested to 1e-12).  The innovation exposed is (ν_p, S)
with its Gaussian ℓ and NIS; the ``Association`` records NN's choice (one-hot
weights, ℓ of the chosen candidate).
"""

from __future__ import annotations

import attrs
import numpy as np
import pywt

from hybridtrack import hookimpl
from hybridtrack.core.protocols import Association
from hybridtrack.core.validation import check_positive_int
from hybridtrack.sdk.estimation import bank_field
from hybridtrack.sdk.linalg import symmetrize
from hybridtrack_plugins.filters import _covariance as cov_form
from hybridtrack_plugins.filters._association import ScanEstimator, nearest_weights, pad_axis
from hybridtrack_plugins.filters.kalman import CovarianceState

#: the extension mode of the transform: length-preserving and orthogonal
MODE = "periodization"


@attrs.frozen(eq=False, kw_only=True)
class MSDAState(CovarianceState):
    """A covariance-form bank plus, per filter, the window's N slots (newest last): the chosen residuals
    ``residuals`` (M, N, m̄), the H they were taken with ``H`` (M, N, m̄, n) (zero-padded to the widest m̄) and
    ``dims`` (M, N) their dimension (0: nothing gated, or no scan yet)."""

    residuals: np.ndarray = bank_field(0)
    H: np.ndarray = bank_field(0)
    dims: np.ndarray = bank_field(0)


def _widen(state: MSDAState, m: int) -> MSDAState:
    """The window's slots padded to at least m residual components."""
    return attrs.evolve(state, residuals=pad_axis(state.residuals, 2, m, 0.0), H=pad_axis(state.H, 2, m, 0.0))


class MSDAFilter(ScanEstimator):
    """MSDA over a bank (module docstring): ``gate_probability`` P_G in (0, 1) or ``None`` (no gate),
    ``window`` N ≥ 1 scans, ``wavelet`` a discrete PyWavelets name (default ``"haar"``), ``level`` J
    (None: the deepest for N; 0: no transform, NN), ``form`` the covariance update form."""

    name = "msda"
    example_parameters = {"gate_probability": 0.99, "window": 1}

    def __init__(
        self, gate_probability: float | None = 0.99, window: int = 2, wavelet: str = "haar", level: int | None = None, form: str = "joseph"
    ):
        super().__init__(gate_probability, form)
        self.window = check_positive_int(window, "window", what="the number of scans fused")
        if not isinstance(wavelet, str) or wavelet not in pywt.wavelist(kind="discrete"):
            raise ValueError(f"wavelet: expected a discrete wavelet name of PyWavelets (e.g. 'haar', 'db2'), got {wavelet!r}")
        self.wavelet = wavelet
        deepest = pywt.dwt_max_level(self.window, pywt.Wavelet(wavelet).dec_len)
        if level is None:
            level = deepest
        if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or not 0 <= level <= deepest:
            raise ValueError(
                f"level: expected an integer in 0 … {deepest} (the deepest {wavelet!r} level for window {self.window}), got {level!r}"
            )
        self.level = int(level)

    def initialize(self, mean, cov) -> MSDAState:
        x, P = self.check_prior(mean, cov)
        M, n = x.shape
        N = self.window
        empty = {"residuals": np.zeros((M, N, 0)), "H": np.zeros((M, N, 0, n)), "dims": np.zeros((M, N), dtype=np.int64)}
        return MSDAState(x, P, x, P, **empty)

    def conform(self, states: list) -> list:
        """Pad the residual slots of every state to the widest m̄ of the group, so that they concatenate."""
        m = max(s.residuals.shape[2] for s in states)
        return [_widen(s, m) for s in states]

    def associate_scan(self, state: MSDAState, nu, H, R, selection, sensor_name, candidates, z_pred):
        """NN choice of one scan, the window slid by one, the fused residual, the Kalman update."""
        x, P = state.x, state.P
        M, n = x.shape
        m = nu.shape[-1]
        S, chol, gamma, d2, gated = self.gate(nu, P, H, R, selection)
        beta, missed, selected, loglik = nearest_weights(d2, gated, chol)
        record = Association(sensor_name, np.asarray(candidates), z_pred, S, gamma, d2, gated, beta, missed, selected, loglik)
        has = selected >= 0
        rows = np.flatnonzero(has)
        chosen = np.zeros((M, m))
        chosen[rows] = nu[rows, selected[rows]]
        # the window, newest last: this scan's residual, its H, its dimension (0: nothing gated)
        s = _widen(state, m)
        mb = s.residuals.shape[2]
        r_new = pad_axis(chosen, 1, mb, 0.0)
        H_new = pad_axis(np.broadcast_to(H, (M, m, n)), 1, mb, 0.0)
        residuals = np.concatenate([s.residuals[:, 1:], r_new[:, None]], axis=1)
        Hw = np.concatenate([s.H[:, 1:], H_new[:, None]], axis=1)
        dims = np.concatenate([s.dims[:, 1:], np.where(has, m, 0)[:, None]], axis=1)
        new_window = attrs.evolve(s, residuals=residuals, H=Hw, dims=dims)
        if nu.shape[1] == 0 or not rows.size:
            return attrs.evolve(new_window, innovation=None), np.zeros((M, m)), S, record
        fused = self.fuse(residuals[:, :, :m], (dims == m) & np.all(Hw == H_new[:, None], axis=(2, 3)), chosen)
        x_new, P_new, _, _, _ = cov_form.update(x, P, fused, H, R, selection, self.form)
        self.check_finite("update", updated_mean=x_new)
        x_new = np.where(has[:, None], x_new, x)
        P_new = np.where(has[:, None, None], P_new, P)
        nu_used = np.where(has[:, None], fused, 0.0)
        return attrs.evolve(new_window, x=x_new, P=symmetrize(P_new)), nu_used, S, record

    def fuse(self, residuals: np.ndarray, usable: np.ndarray, newest: np.ndarray) -> np.ndarray:
        """ν_p (M, m): the newest sample of the level-J approximation of the window's residuals (M, N, m).

        Entries not ``usable`` (M, N) take ``newest`` (M, m); J = 0 returns ``newest`` itself.
        """
        if self.level == 0:
            return newest
        sequence = np.where(usable[:, :, None], residuals, newest[:, None, :])
        coefficients = pywt.wavedec(sequence, self.wavelet, mode=MODE, level=self.level, axis=1)
        approximation = [coefficients[0]] + [np.zeros_like(c) for c in coefficients[1:]]
        smooth = pywt.waverec(approximation, self.wavelet, mode=MODE, axis=1)
        return smooth[:, self.window - 1]


@hookimpl
def register_estimators(registry):
    registry.add(MSDAFilter.name, MSDAFilter)
