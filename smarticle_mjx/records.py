"""What a store holds, as typed records the reducers may take (no store, engine or page imported here).

:class:`RelaxRecord` is :func:`smarticle_mjx.store.read_relax`'s result: a relaxation study's trials.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .labels import BAD_STATUS


@dataclasses.dataclass(frozen=True)
class RelaxRecord:
    """What a relaxation study's stores hold (:func:`smarticle_mjx.store.read_relax`), trials in trial order.
    T trials, K periods, N robots, P = N (N - 1) / 2 pairs; lengths in m, angles in rad (docs/store.md)."""

    start_poses: np.ndarray  # [T, N, 5] the perturbed compressed start (x, y, heading, alpha1, alpha2)
    valid: np.ndarray  # [T] bool
    status: np.ndarray  # [T] engine status bits (labels.BAD_STATUS: flagged)
    periods_run: np.ndarray  # [T] periods simulated (< K when stopped early)
    touched: np.ndarray  # [T, K, P] bool: the pair touched at least once in the period
    min_dist: np.ndarray  # [T, K, P] deepest contact distance in the period (m), +inf if none
    poses: np.ndarray  # [T, K, N, 5] every robot's pose at each period's end; NaN after an early stop
    left_plate: np.ndarray  # [T, N] first period ending with the robot off the plate; 0: never
    trial: np.ndarray  # [T] trial indices
    settings: dict  # the first store's relax settings (RelaxConfig's JSON)
    periods: int  # K
    period_s: float
    model: str
    overrides: dict
    body_length: float  # m
    body_thickness: float  # m
    paths: tuple[str, ...]

    @property
    def usable(self) -> np.ndarray:
        """[T] bool: valid and not flagged by the engine (the trials every measure counts)."""
        return np.asarray(self.valid, bool) & ((np.asarray(self.status) & int(BAD_STATUS)) == 0)
