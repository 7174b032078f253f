"""``most_likely``: a fixed bank of one filter per mode; the estimate follows the most likely filter.

An algorithm (:class:`hybridtrack.core.algorithm.Algorithm`) written only
against ``hybridtrack.core`` and ``hybridtrack.sdk``, as a third party's would
be.  Every filter i starts from the prior and runs mode i throughout (its
transition fixed at the prior mean x₀, as a fixed bank does); step 0 is the
update with z₀, step k ≥ 1 predicts over Δt_k and updates with z_k.  The
cumulative log-likelihood L_{k,i} = Σ_{j≤k} ℓ_{j,i} (ℓ the innovation
log-likelihood) picks the followed filter î_k = argmax_i L_{k,i}, whose mean
and covariance are the estimate:

    x̂_k = x_{k,î_k},   P_k = P_{k,î_k}.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from hybridtrack.core.algorithm import Algorithm
from hybridtrack.core.interfaces import TransitionBank
from hybridtrack.core.registry import registry_or_default
from hybridtrack.core.types import Gaussian
from hybridtrack.sdk.network import SensorNetwork
from hybridtrack.sdk.timestamps import step_intervals


@attrs.frozen(eq=False, kw_only=True)
class MostLikelyRun:
    """times (K+1,), means (K+1, n), covs (K+1, n, n), mode (K+1,) the followed filter, loglik (K+1, M) L_{k,i}."""

    layout: tuple[str, ...]
    modes: tuple[str, ...]
    times: np.ndarray
    means: np.ndarray
    covs: np.ndarray
    mode: np.ndarray
    loglik: np.ndarray
    decisions: tuple = ()


class MostLikely(Algorithm):
    """Fixed bank of one filter per mode; the estimate follows the filter of largest cumulative log-likelihood."""

    example_parameters = {"modes": ["straight", ("right_turn", {"radius": 100.0})]}

    def __init__(
        self, *, modes: Sequence[Any], sensors, tau: float | None = None, estimator: Any = "kalman", name="most_likely", registry=None
    ):
        registry = registry_or_default(registry)
        self.models = [registry.resolve("motion_model", mode) for mode in modes]
        layouts = {model.layout for model in self.models}
        if len(layouts) != 1:
            raise ValueError(f"modes: a fixed bank needs one state layout, got {sorted(layouts)}")
        self.layout = layouts.pop()
        self.modes = tuple(model.name for model in self.models)
        self.network = sensors if isinstance(sensors, SensorNetwork) else SensorNetwork(sensors)
        self.tau, self.name = tau, name
        self.estimator = registry.resolve("estimator", estimator)

    def run(self, measurements: Mapping[str, np.ndarray], prior, *, times=None, recorder=None) -> MostLikelyRun:
        prior = prior if isinstance(prior, Gaussian) else Gaussian(*prior)
        z = self.network.stack(measurements)
        t, dt = step_intervals(times, self.tau, z.shape[0])
        M, sensors = len(self.models), self.network.sensors
        banks: dict[float, TransitionBank] = {}  # one bank per distinct Δt, fixed at x₀
        state = self.estimator.initialize(np.repeat(prior.mean[None], M, axis=0), np.repeat(prior.cov[None], M, axis=0))
        total = np.zeros(M)
        loglik, means, covs = [], [], []
        for k in range(z.shape[0]):
            if k > 0:
                step = float(dt[k - 1])
                if step not in banks:
                    banks[step] = TransitionBank.stack([model.transition(step, prior.mean) for model in self.models])
                state = self.estimator.predict(state, banks[step])
            state, innovation = self.estimator.update(state, z[k], sensors, self.layout)
            total = total + innovation.loglik
            loglik.append(total)
            means.append(self.estimator.mean(state))
            covs.append(self.estimator.covariance(state))
        loglik = np.stack(loglik)
        mode = np.argmax(loglik, axis=1)
        steps = np.arange(len(mode))
        return MostLikelyRun(
            layout=self.layout,
            modes=self.modes,
            times=t,
            means=np.stack(means)[steps, mode],
            covs=np.stack(covs)[steps, mode],
            mode=mode,
            loglik=loglik,
        )
