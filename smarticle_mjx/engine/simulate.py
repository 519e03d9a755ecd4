"""One simulation call: N robots, K gait periods, per-period records."""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import configs
from ..gait import GaitSpec
from ..scene import SceneParams
from .core import Lanes, Record, Scene, Status, on_step_grid


@dataclasses.dataclass
class SimResult:
    """Result of :func:`simulate`.

    Attributes:
      period: gait period (s).
      poses: [K+1, N, 5] poses (x, y, heading, alpha1, alpha2) at t = k T,
        k = 0..K (gait phase 0; k = 0 is the initial pose).
      touched: [K, P] robots of pair p touched at least once in period k.
      min_dist: [K, P] deepest contact distance per period (m), inf if none.
      pairs: [P, 2] robot indices of each pair.
      status: Status bits.
      track_t: [S] times of the full-rate track, or None.
      track: [S, N, 5] poses along the track, or None.
      collisions: the collision record of the K periods (see
        ``PeriodRecords.collisions``, without the lane axis), or None.
    """

    period: float
    poses: np.ndarray
    touched: np.ndarray
    min_dist: np.ndarray
    pairs: np.ndarray
    status: int
    body_length: float
    track_t: np.ndarray | None = None
    track: np.ndarray | None = None
    collisions: dict | None = None

    def relative(self, i: int = 0, j: int = 1):
        """(|r| in W, theta, phi) of robots i, j at every period boundary [K+1]."""
        return configs.relative_coordinates(self.poses[:, i], self.poses[:, j], self.body_length)


def simulate(params: SceneParams, poses, gait: GaitSpec, periods: int, phase=None,
             track_stride: int | None = None, backend: str = "native", nthread: int | None = None,
             record: Record | None = None, imperfections=None, row: int = 0,
             retrigger=None, start_delays: bool = True) -> SimResult:
    """Simulate N robots on the plate for ``periods`` gait periods.

    Args:
      params: scene parameters.
      poses: [N, 5] initial poses (x, y, heading, alpha1, alpha2) in m, rad.
      gait: gait shared by all robots.
      periods: number of gait periods K (>= 1).
      phase: optional [N] phase offsets (fractions of a period).
      track_stride: record the full-rate track every this many steps
        (shorthand for ``record=Record(track_stride=...)``).
      backend: "native" (default), "mjx", "warp" or "dart" (full-rate tracks: native and dart).
      record: what to record beyond per-period poses and touches.
      imperfections: an ``imperfections.Draw`` of these robots (its scene
        quirks must already be in ``params``); ``row``: the lane or trial
        whose phase jitter applies.
      retrigger: optional [3] (s.d. in periods, seed, key): every robot re-started each cycle with a
        fresh delay; or [4] (and an onset cycle): a lasting offset per robot from that cycle on
        (``Lanes.retrigger``).
      start_delays: read ``phase`` and the imperfections' start offsets as start delays
        (``Lanes.with_start_delays``: the robot furthest ahead starts at t = 0, the others later, each
        from its gait's first corner), as relaxation trials and scans run them since version 0.4.1;
        False: every robot's clock starts at t = 0 at its offset (versions up to 0.4.0).

    Raises:
      ValueError: bad parameters, or robots overlapping at the start.
    """
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 5:
        raise ValueError(f"poses must be [N, 5], got shape {poses.shape}")
    if periods < 1:
        raise ValueError(f"periods must be >= 1, got {periods}")
    record = record or Record()
    if track_stride is not None:
        record = dataclasses.replace(record, track_stride=track_stride)
    record.validate()
    params.validate()
    gait.validate(params.robot.servo_speed, params.robot.arm_limit_deg)
    if len(poses) > 1 and not configs.poses_valid(poses, params.robot):
        raise ValueError("initial poses overlap: robots would start interpenetrating")
    scene = Scene.build(params, len(poses), collisions=record.collisions)
    lanes = Lanes.from_gait(poses, gait, phase)
    if imperfections is not None:
        lanes = imperfections.lanes(lanes, [row], start_delays=start_delays)
    if start_delays and lanes.phase.any():
        lanes = lanes.with_start_delays()
    if retrigger is not None:
        lanes = dataclasses.replace(lanes, retrigger=np.asarray(retrigger, float).reshape(1, -1))
    lanes = on_step_grid(lanes, params.timestep)
    from . import make_backend
    be = make_backend(backend, scene, nthread=nthread)
    try:
        state = be.initial_state(lanes)
        _, rec, track = be.advance(state, lanes, periods, record=record)
    finally:
        be.close()
    all_poses = np.concatenate([poses[None], rec.poses[0]], 0)
    res = SimResult(lanes.period, all_poses, rec.touched[0], rec.min_dist[0], scene.layout.pairs,
                    int(Status(int(rec.status[0]))), params.robot.body_length)
    if rec.collisions is not None:
        res.collisions = {k: v[0] for k, v in rec.collisions.items()}
    if track is not None:
        res.track_t = track["t"]
        res.track = scene.poses_from_qpos(track["qpos"][0])
    return res
