"""The motion modes an adaptive bank runs: seed 001's turn bank and the check that modes share one layout."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hybridtrack.core.interfaces import MotionModel
from hybridtrack.core.plugins import resolve
from hybridtrack.core.registry import Registry
from hybridtrack.core.validation import check_positive, check_positive_int


def turn_bank(r_min: float = 1.0, r_max: float = 10.0, n: int = 10, noise_cov=None) -> list[tuple[str, dict]]:
    """The 2n+1 hypotheses of seed 001 §3: straight, left turns r_1 … r_n, right turns r_1 … r_n.

    Radii r_i = r_min + (i − 1)(r_max − r_min)/(n − 1) (n = 1: r_min alone, which must equal r_max).
    """
    n = check_positive_int(n, "n")
    r_min, r_max = check_positive(r_min, "r_min", "a radius"), float(r_max)
    if not np.isfinite(r_max) or r_min > r_max:
        raise ValueError(f"r_min, r_max: expected 0 < r_min ≤ r_max, got r_min = {r_min}, r_max = {r_max}")
    if n == 1 and r_min != r_max:
        raise ValueError(f"n: one radius needs r_min = r_max, got r_min = {r_min}, r_max = {r_max}")
    extra = {} if noise_cov is None else {"noise_cov": noise_cov}
    radii = np.linspace(r_min, r_max, n)
    return (
        [("straight", dict(extra))]
        + [("left_turn", {"radius": float(r), **extra}) for r in radii]
        + [("right_turn", {"radius": float(r), **extra}) for r in radii]
    )


def resolve_modes(modes: Sequence, registry: Registry, *, one_layout: bool = True) -> list[MotionModel]:
    """The motion models of ``modes`` (objects, names or (name, parameters)), at least one; with ``one_layout`` all
    in one state layout (the algorithms whose bank mixes layouts pass False)."""
    models = [resolve("motion_model", m, registry) for m in modes]
    if not models:
        raise ValueError("modes: expected at least one motion mode, got an empty set")
    layouts = {m.layout for m in models}
    if one_layout and len(layouts) != 1:
        raise ValueError(f"modes: every mode must share one state layout, got {sorted(layouts)}")
    return models
