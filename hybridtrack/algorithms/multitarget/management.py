"""Track management: when a tentative track is confirmed and when a track is deleted.

Two rules, both vectorized over the T tracks of a scan, both fed the same per-scan facts (was the track given
a detection; the change of its log-likelihood-ratio score):

* :class:`MofN` — the classic logic (Blackman & Popoli 1999, §3.2): a tentative track is confirmed once it has
  M hits among its first N scans (the initiating one included) and deleted as soon as M can no longer be
  reached; a confirmed track is deleted after ``delete_misses`` scans in a row without a detection.
* :class:`TrackScore` — Blackman's sequential track score (Blackman & Popoli 1999, §6.2; Blackman 2004,
  "Multiple hypothesis tracking for multiple target tracking", IEEE AES Magazine 19(1), eqs. 5-8): the log
  likelihood ratio L of "a target" against "clutter",

      L_1 = ln(β_NT / β_FA)                                  (birth: new-target vs false-detection density)
      ΔL_k = ln(P_D N(ν_k; 0, S_k) / β_FA)                   (a detection)
      ΔL_k = ln(1 − P_D P_G)                                 (no detection)

  is Wald's SPRT (Wald 1947) with error probabilities α (confirming a false track) and β (deleting a true
  one): confirm when L ≥ T_c = ln((1 − β)/α), delete a tentative track when L ≤ T_d = ln(β/(1 − α)); a
  confirmed track is deleted when L falls more than ``deletion_drop`` (default T_c − T_d) below its maximum.

Either rule also deletes any track not given a detection for ``max_coast`` seconds (a time-based deleter, the
one that fits reports at irregular rates such as AIS) when that is set.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from hybridtrack.core.validation import check_positive, check_positive_int

TENTATIVE, CONFIRMED = 0, 1


def _probability(name: str):
    def check(instance, attribute, value):
        if not (isinstance(value, (int, float)) and 0.0 < value < 1.0):
            raise ValueError(f"{name}: expected a probability in (0, 1), got {value!r}")

    return check


def _optional_positive(name: str):
    return lambda value: None if value is None else check_positive(value, name)


@attrs.define
class TrackStatus:
    """The management state of T tracks (arrays of length T, rows in the tracker's order).

    ``status`` TENTATIVE or CONFIRMED; ``score`` L and ``peak`` max L so far; ``hits`` and ``scans`` the
    detections and scans since birth (the initiating one included); ``misses`` the scans in a row without a
    detection; ``last_hit`` the time (s) of the last detection; ``duplicate`` the scans in a row the track was found a
    duplicate of an older one (:class:`~.tracker.MultiTargetTracker`, ``duplicate_probability``)."""

    status: np.ndarray
    score: np.ndarray
    peak: np.ndarray
    hits: np.ndarray
    scans: np.ndarray
    misses: np.ndarray
    last_hit: np.ndarray
    duplicate: np.ndarray

    @classmethod
    def born(cls, count: int, score: float, time: float, hits: int = 1) -> TrackStatus:
        """``count`` new tentative tracks with score ``score``, ``hits`` detections (one per initiating scan) at ``time``."""
        return cls(
            status=np.full(count, TENTATIVE, dtype=np.int8),
            score=np.full(count, float(score)),
            peak=np.full(count, float(score)),
            hits=np.full(count, hits, dtype=np.intp),
            scans=np.full(count, hits, dtype=np.intp),
            misses=np.zeros(count, dtype=np.intp),
            last_hit=np.full(count, float(time)),
            duplicate=np.zeros(count, dtype=np.intp),
        )

    def __len__(self) -> int:
        return self.status.shape[0]

    def take(self, rows) -> TrackStatus:
        return TrackStatus(*(getattr(self, f.name)[rows] for f in attrs.fields(TrackStatus)))

    @staticmethod
    def concatenate(parts) -> TrackStatus:
        return TrackStatus(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in attrs.fields(TrackStatus)))

    def record(self, hit: np.ndarray, delta_score: np.ndarray, time: float) -> None:
        """One scan's facts: ``hit`` (T,) whether each track was given a detection (for JPDA: its most probable
        event), ``delta_score`` (T,) ΔL."""
        self.score = self.score + delta_score
        self.peak = np.maximum(self.peak, self.score)
        self.hits = self.hits + hit
        self.scans = self.scans + 1
        self.misses = np.where(hit, 0, self.misses + 1)
        self.last_hit = np.where(hit, time, self.last_hit)


def _coasted(status: TrackStatus, time: float, max_coast: float | None) -> np.ndarray:
    if max_coast is None:
        return np.zeros(len(status), dtype=bool)
    return time - status.last_hit > max_coast


@attrs.frozen
class MofN:
    """M-of-N confirmation, deletion after ``delete_misses`` misses in a row (module docstring)."""

    confirm_hits: int = attrs.field(default=3, converter=lambda v: check_positive_int(v, "confirm_hits"))
    confirm_scans: int = attrs.field(default=4, converter=lambda v: check_positive_int(v, "confirm_scans"))
    delete_misses: int = attrs.field(default=3, converter=lambda v: check_positive_int(v, "delete_misses"))
    max_coast: float | None = attrs.field(default=None, converter=_optional_positive("max_coast (s)"))

    def __attrs_post_init__(self):
        if self.confirm_hits > self.confirm_scans:
            raise ValueError(f"confirm_hits: M = {self.confirm_hits} hits cannot fit in N = {self.confirm_scans} scans (M ≤ N)")

    def decide(self, status: TrackStatus, time: float) -> tuple[np.ndarray, np.ndarray]:
        """(confirm, delete) (T,) booleans after :meth:`TrackStatus.record` of the scan at ``time``."""
        tentative = status.status == TENTATIVE
        confirm = tentative & (status.hits >= self.confirm_hits) & (status.scans <= self.confirm_scans)
        unreachable = status.hits + np.maximum(self.confirm_scans - status.scans, 0) < self.confirm_hits
        delete = np.where(tentative & ~confirm, unreachable, status.misses >= self.delete_misses)
        return confirm, (delete | _coasted(status, time, self.max_coast)) & ~confirm


@attrs.frozen
class TrackScore:
    """Blackman's sequential track score with SPRT thresholds from α and β (module docstring)."""

    false_track_probability: float = attrs.field(default=1e-4, validator=_probability("false_track_probability (α)"))
    track_loss_probability: float = attrs.field(default=0.1, validator=_probability("track_loss_probability (β)"))
    deletion_drop: float | None = attrs.field(default=None, converter=_optional_positive("deletion_drop"))
    max_coast: float | None = attrs.field(default=None, converter=_optional_positive("max_coast (s)"))

    @property
    def confirm_threshold(self) -> float:
        """T_c = ln((1 − β)/α)."""
        return math.log((1 - self.track_loss_probability) / self.false_track_probability)

    @property
    def delete_threshold(self) -> float:
        """T_d = ln(β/(1 − α))."""
        return math.log(self.track_loss_probability / (1 - self.false_track_probability))

    @property
    def drop(self) -> float:
        """How far below its peak a confirmed track's score may fall: ``deletion_drop`` or T_c − T_d."""
        return self.confirm_threshold - self.delete_threshold if self.deletion_drop is None else self.deletion_drop

    def decide(self, status: TrackStatus, time: float) -> tuple[np.ndarray, np.ndarray]:
        """(confirm, delete) (T,) booleans after :meth:`TrackStatus.record` of the scan at ``time``."""
        tentative = status.status == TENTATIVE
        confirm = tentative & (status.score >= self.confirm_threshold)
        delete = np.where(tentative, status.score <= self.delete_threshold, status.score < status.peak - self.drop)
        return confirm, (delete | _coasted(status, time, self.max_coast)) & ~confirm
