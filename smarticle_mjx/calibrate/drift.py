"""Plate-frame drift, measured without the model: a test for a tilted plate.

A robot on a level plate steps the same way in its own body frame whatever
its heading: per gait cycle c its centre moves by R(h_c) s, where h_c is its
heading then (below: at the boundary the step is centred on) and s the body-frame step (which our model,
with another robot's geometry and servo, never gets exactly right). A plate
that tilts adds the same vector v in the plate frame to every cycle:

    step_c = R(h_c) s + v.

Over cycles of trials started at different headings, s and v separate by
linear least squares, one (s, v) per gait (amplitude, chirality, period):
``v`` is the robots' drift in the plate frame with the body-frame step taken
out, and needs no model. On a level plate it is zero within its standard
error whatever the model mismatch; the body-frame mismatch that hides a
small tilt in the per-trial step residuals (docs/calibration.md) cannot fake
it. Only robots that never come within the contact distance of another are
used. A group needs cycles at headings at least ``MIN_SPREAD_DEG`` apart,
else s and v are not separable and it is left out.

A cycle's step is the difference of the mean positions of two consecutive
whole cycles (:func:`cycle_means`; not of the positions at two cycle
boundaries): the wobble within
a cycle repeats, so the means step by the same amount, while each frame's
tracking error and the body's own jitter at the instant of a boundary enter
a mean divided by the frames in it. The drift is then resolved to
thousandths of a millimetre per cycle, which also resolves a plate that is
not level in another way: a plate slipperier along one axis, or whose grip
depends on the robot's heading, changes the step with the heading, and with
two or three headings per gait that is read as a drift too (development
seeds: 10 of 15 anisotropic plates and 8 of 12 heading-dependent ones,
against 1 and 3 with boundary positions). Such a drift points different
ways in different gaits, where a tilt's points downhill in all of them:
:func:`directions` tells the two apart where two or more gaits drift
(docs/calibration.md).

``drift_test`` pools the groups into one chi-square test of v = 0;
``fit_tilt`` turns the measured v into a plate tilt by the model's linear
response to a small tilt (two model runs per direction).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .residuals import CONTACT_W, MM, masked

MIN_SPREAD_DEG = 60.0  # headings of a group must span at least this
P_DRIFT = 1e-3  # significance that makes drift a finding
MIN_CYCLE_FRAMES = 4  # a cycle with fewer tracked frames has no mean (a gap in the track)
# a tilt pulls every robot downhill: the drifts of different gaits point the same way, within what the
# robot's own direction-dependent slip turns them (development tilts: at most 18 deg from their mean)
MAX_DIRECTION_SPREAD_DEG = 45.0


def group_key(g) -> tuple:
    return (round(float(g.amplitude_deg), 6), g.chirality, g.kind, round(float(g.period()), 6))


def robot_alone(pose: np.ndarray, i: int, body_length: float) -> bool:
    n = pose.shape[1]
    for j in range(n):
        if j != i:
            r = np.hypot(pose[:, i, 0] - pose[:, j, 0], pose[:, i, 1] - pose[:, j, 1])
            if np.nanmin(r) < CONTACT_W * body_length:
                return False
    return True


def cycle_means(t, pose, period) -> tuple[np.ndarray, np.ndarray]:
    """Mean position [C, 2] (m) over the frames of each whole gait cycle inside the track, and the
    heading [C - 1] (rad) at the boundary between consecutive cycles (interpolated).

    A body's within-cycle wobble is the same every cycle, so the means of two consecutive cycles differ
    by one cycle's step, while a frame's tracking error enters a mean divided by its frame count; the step
    between two means is centred on the boundary between their cycles, whose heading it is rotated by."""
    ok = np.isfinite(pose).all(-1)
    t_ok, p_ok = t[ok], pose[ok]
    if len(t_ok) < 2:
        return np.zeros((0, 2)), np.zeros(0)
    # a cycle is whole when the track covers it to within a frame and a half at either end (a track of
    # whole periods ends one frame before its last boundary)
    edge = 1.5 * float(np.median(np.diff(t_ok)))
    c0, c1 = int(np.ceil((t_ok[0] - edge) / period)), int(np.floor((t_ok[-1] + edge) / period))
    means = []
    for c in range(c0, c1):
        sel = (t_ok >= c * period - 1e-9) & (t_ok < (c + 1) * period - 1e-9)
        if sel.sum() < MIN_CYCLE_FRAMES:  # a gap: the cycles on either side are not neighbours
            break
        means.append(p_ok[sel, :2].mean(0))
    means = np.array(means).reshape(-1, 2)
    h = np.interp((np.arange(max(len(means) - 1, 0)) + c0 + 1) * period, t_ok, p_ok[:, 2])
    return means, h


def cycles(t, pose, period, body_length) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """Per robot that stays alone: (robot, headings [K], steps [K, 2] in mm) between consecutive whole
    cycles (:func:`cycle_means`); ``period`` is one for all robots or [N], each robot's."""
    out = []
    periods = np.broadcast_to(np.asarray(period, float), (pose.shape[1],))
    for i in range(pose.shape[1]):
        if not robot_alone(pose, i, body_length):
            continue
        m, h = cycle_means(t, pose[:, i], periods[i])
        if len(m) >= 2:
            out.append((i, h, np.diff(m, axis=0) * MM))
    return out


def _design(h: np.ndarray) -> np.ndarray:
    c, s_ = np.cos(h), np.sin(h)
    a = np.zeros((2 * len(h), 4))
    a[0::2] = np.column_stack([c, -s_, np.ones_like(c), np.zeros_like(c)])
    a[1::2] = np.column_stack([s_, c, np.zeros_like(c), np.ones_like(c)])
    return a


def _track_cov(k: int, var_step: float, var_pos: float) -> np.ndarray:
    """Covariance [2k, 2k] of one track's k steps (x, y interleaved): each
    step carries its own variation (``var_step``) and the difference of two
    noisy cycle positions (``var_pos`` each), so neighbours anticorrelate."""
    c1 = np.diag(np.full(k, var_step + 2 * var_pos)) - var_pos * (np.eye(k, k=1) + np.eye(k, k=-1))
    return np.kron(c1, np.eye(2))


def regress(tracks: list[tuple[np.ndarray, np.ndarray]], noise: tuple[float, float] | None = None) -> dict | None:
    """Generalised least squares step = R(h) s + v over the cycles of one
    gait's tracks [(headings [C], steps [C, 2] mm), ...]; None if the
    headings do not span ``MIN_SPREAD_DEG`` (s and v not separable).

    Steps are differences of cycle positions, so the tracking error of a
    position enters two neighbouring steps with opposite signs; ordinary
    least squares would count it twice and overstate v's error. The step
    variation and the position error are estimated from the residuals'
    variance and lag-1 covariance within tracks, and the fit repeated with
    that covariance; ``noise`` (var_step, var_pos) gives them instead (to fit
    another signal at the same headings with the same weights).

    Returns:
      dict: s [2] (body frame, mm/cycle), v [2] (plate frame, mm/cycle),
      cov_v, cov_s [2, 2], cycles, spread_deg, var_step, var_pos (mm^2).
    """
    parts = []
    for h, d in tracks:
        h, d = np.asarray(h, float), np.asarray(d, float)
        ok = np.isfinite(h) & np.isfinite(d).all(-1)
        if ok.sum() >= 1:
            parts.append((h[ok], d[ok]))
    if not parts or sum(len(h) for h, _ in parts) < 4:
        return None
    h_all = np.concatenate([h for h, _ in parts])
    u = np.exp(1j * h_all)
    spread = float(np.degrees(np.max(np.abs(np.angle(u[:, None] / u[None, :])))))
    if spread < MIN_SPREAD_DEG:
        return None
    a_parts = [_design(h) for h, _ in parts]
    y_parts = [d.reshape(-1) for _, d in parts]
    a, y = np.concatenate(a_parts), np.concatenate(y_parts)
    x, *_ = np.linalg.lstsq(a, y, rcond=None)
    # residual variance and lag-1 covariance within tracks (per coordinate)
    g0, g1, n0, n1 = 0.0, 0.0, 0, 0
    for ap, yp in zip(a_parts, y_parts):
        r = (yp - ap @ x).reshape(-1, 2)
        g0 += float((r * r).sum())
        n0 += r.size
        if len(r) > 1:
            g1 += float((r[1:] * r[:-1]).sum())
            n1 += r[1:].size
    dof_scale = n0 / max(1, n0 - 4)
    g0 = g0 / max(1, n0) * dof_scale
    g1 = g1 / n1 if n1 else 0.0
    var_pos = max(0.0, -g1)
    var_step = max(g0 - 2 * var_pos, 0.05 * g0, 1e-12)
    if noise is not None:
        var_step, var_pos = noise
    ata = np.zeros((4, 4))
    atb = np.zeros(4)
    for ap, yp in zip(a_parts, y_parts):
        w = np.linalg.inv(_track_cov(len(yp) // 2, var_step, var_pos))
        ata += ap.T @ w @ ap
        atb += ap.T @ w @ yp
    cov = np.linalg.inv(ata)
    x = cov @ atb
    return {"s": x[:2], "v": x[2:], "cov_v": cov[2:, 2:], "cov_s": cov[:2, :2], "cycles": int(len(h_all)),
            "spread_deg": spread,
            "var_step": var_step, "var_pos": var_pos}


def _gait_tracks(trials, tracks=None) -> dict:
    """{gait group: ([headings per track], [steps per track])} over every robot that stays alone."""
    groups: dict = {}
    for k, tr in enumerate(trials):
        pose = tr.pose if tracks is None else masked(tracks[k], tr)[0]
        for i, h, d in cycles(tr.t, pose, tr.periods, tr.params.robot.body_length):
            g = groups.setdefault(group_key(tr.gaits[i]), ([], []))
            g[0].append(h)
            g[1].append(d)
    return groups


def _drifts(groups: dict) -> dict:
    """:func:`regress` per gait group of :func:`_gait_tracks`, where the headings separate s and v."""
    out = {}
    for key, (hs, ds) in groups.items():
        res = regress(list(zip(hs, ds)))
        if res is not None:
            out[key] = res
    return out


def group_drift(trials, tracks=None) -> dict:
    """v per gait group, from the measured tracks (``tracks`` None) or from
    model tracks [F, N, 5] aligned with ``trials`` (masked like the data)."""
    return _drifts(_gait_tracks(trials, tracks))


def directions(rows: list[dict]) -> dict:
    """Do the gaits' drifts point one way, as a tilt's do? ``rows``: drift_test's groups. Over the groups
    whose drift exceeds twice its standard error, the circular mean direction (weighted by |v| / se) and
    each one's angle from it; ``consistent``: every angle within ``MAX_DIRECTION_SPREAD_DEG``, or fewer
    than two such groups (nothing to compare: then a tilt is not told from a plate that is not level in
    another way)."""
    sig = [(np.asarray(g["v_mm"]), max(float(np.mean(g["se_mm"])), 1e-12)) for g in rows]
    sig = [(v, se) for v, se in sig if np.hypot(*v) > 2 * se]
    if len(sig) < 2:
        return {"groups": len(sig), "mean_deg": None, "max_angle_deg": None, "consistent": True,
                "compared": False}
    ang = np.array([math.atan2(v[1], v[0]) for v, _ in sig])
    w = np.array([np.hypot(*v) / se for v, se in sig])
    mean = math.atan2(float(w @ np.sin(ang)), float(w @ np.cos(ang)))
    dev = np.degrees(np.abs(np.angle(np.exp(1j * (ang - mean)))))
    return {"groups": len(sig), "mean_deg": math.degrees(mean), "angles_deg": dev.tolist(),
            "max_angle_deg": float(dev.max()), "consistent": bool(dev.max() <= MAX_DIRECTION_SPREAD_DEG),
            "compared": True}


@dataclasses.dataclass(frozen=True)
class PlateDrift:
    """Does the gaits' plate-frame drift follow the robot's own step, as a plate slipperier along one axis
    makes it, or is it one vector, as a tilt makes it? (:func:`plate_drift_models`; model-free.)

    A plate slipperier along one axis stretches each step along it: step = (1 + E) R(h) s with E symmetric
    and traceless (strength eps, axis psi). In complex numbers E z = eps e^{2i psi} conj(z), so the extra
    step is K conj(s) e^{-ih}, K = eps e^{2i psi}: it turns against the heading, and its size is the
    robot's own step in that gait. With the few headings a gait has, the regression step = R(h) s + v
    (:func:`regress`) reads part of it as a drift, v_g = K w_g, where w_g is what the same regression
    reads from conj(s_g) e^{-ih} at the gait's own headings. A tilt adds the same vector to every gait.

    Attributes:
      groups: gait groups with a drift (two or more make the comparison).
      chi2_drift: of v_g = 0 (the drift test's).
      chi2_one_vector: of one v for every gait (a tilt's drift, its size taken as the same in every gait).
      chi2_anisotropy: of v_g = K w_g, one K for every gait.
      anisotropy: K (re, im) in the best fit: |K| about (1 - r) / (1 + r) for a ratio r of the plate's
        mobilities along its axes, arg / 2 the slipperier axis.
      chi2_grip: of a grip that depends on the robot's heading: a plate whose mu under a
        robot is mu (1 + e cos 2(h - h0)) scales the robot's step along itself, step = (1 + c1 cos 2h +
        c2 sin 2h) R(h) s, and the regression reads v_g = c1 u_g + c2 u'_g (u, u' what it reads from
        R(h) s cos 2h and R(h) s sin 2h at the gait's headings; c1, c2 one pair for every gait). Outside
        the library; reported beside the anisotropy (``anisotropic``), and used by no rule of the
        calibration: as a reading of an anisotropic plate it did not keep outside grips out
        (docs/calibration.md, "Does the drift follow the robot?").
    """

    groups: int
    chi2_drift: float
    chi2_one_vector: float
    chi2_anisotropy: float
    anisotropy: tuple[float, float]
    chi2_grip: float

    @property
    def applicable(self) -> bool:
        return self.groups >= 2

    @property
    def follows_the_robot(self) -> bool:
        """The drifts fit one plate anisotropy better than one drift vector."""
        return self.applicable and self.chi2_anisotropy < self.chi2_one_vector

    @property
    def p_one_vector(self) -> float:
        """p-value of one drift vector for every gait (chi^2 on 2 (groups - 1) dof; nan with one group): how
        well a tilt's drift alone accounts for the gaits' drifts."""
        from scipy.stats import chi2 as chi2_dist
        return float(chi2_dist.sf(self.chi2_one_vector, 2 * (self.groups - 1))) if self.applicable else float("nan")

    @property
    def anisotropic(self) -> bool:
        """The drifts fit one plate anisotropy better than one drift vector and better than a grip that
        depends on the robot's heading."""
        return self.follows_the_robot and self.chi2_anisotropy < self.chi2_grip

    def as_dict(self) -> dict:
        return {**dataclasses.asdict(self), "anisotropy": list(self.anisotropy), "applicable": self.applicable,
                "follows_the_robot": self.follows_the_robot, "anisotropic": self.anisotropic,
                "p_one_vector": self.p_one_vector}


def plate_drift_models(groups: list[tuple[list, list]], fits: list[dict | None] | None = None,
                       offsets: list[tuple[np.ndarray, np.ndarray] | None] | None = None) -> PlateDrift:
    """:class:`PlateDrift` from the tracks of each gait group [([headings per track], [steps per track,
    mm]), ...] (groups whose headings do not separate s and v are left out, as in the drift test); ``fits``:
    their :func:`regress` results where already made. Each group's v is weighted by its covariance taken as
    isotropic (the mean of its two variances).

    ``offsets`` (per group: a model's drift v [2] and its covariance [2, 2], or None to leave the group out):
    the drift is read beyond that model's, v - v_model, with both covariances, so the comparison asks what
    the model leaves unexplained (:func:`fit_tilt`). The robot's own step s_g and the
    headings stay the measured ones."""
    rows = []
    fits = fits if fits is not None else [regress(list(zip(hs, ds))) for hs, ds in groups]
    offsets = offsets if offsets is not None else [(np.zeros(2), np.zeros((2, 2)))] * len(groups)
    for (hs, _), r, off in zip(groups, fits, offsets):
        if r is None or off is None:
            continue
        s_g = complex(*r["s"])

        def read(fn):
            signal = []
            for h in hs:
                h = np.asarray(h, float)
                z = fn(h)
                signal.append((h, np.column_stack([z.real, z.imag])))
            return complex(*regress(signal, noise=(r["var_step"], r["var_pos"]))["v"])

        w = read(lambda h: np.conj(s_g) * np.exp(-1j * h))
        u1 = read(lambda h: s_g * np.exp(1j * h) * np.cos(2 * h))
        u2 = read(lambda h: s_g * np.exp(1j * h) * np.sin(2 * h))
        v_off, cov_off = (np.asarray(x, float) for x in off)
        rows.append((complex(*(r["v"] - v_off)), w, float(np.mean(np.diag(r["cov_v"] + cov_off))), u1, u2))
    if not rows:
        return PlateDrift(0, 0.0, 0.0, 0.0, (0.0, 0.0), 0.0)
    v = np.array([x[0] for x in rows])
    w = np.array([x[1] for x in rows])
    var = np.array([x[2] for x in rows])
    k = complex(np.sum(np.conj(w) * v / var) / max(float(np.sum(np.abs(w) ** 2 / var)), 1e-300))
    one = complex(np.sum(v / var) / np.sum(1.0 / var))
    # the grip: two real coefficients for the two complex signals, by weighted least squares on (re, im)
    sw = 1.0 / np.sqrt(var)
    a = np.column_stack([np.concatenate([(x * sw).real, (x * sw).imag]) for x in
                         (np.array([x[3] for x in rows]), np.array([x[4] for x in rows]))])
    y = np.concatenate([(v * sw).real, (v * sw).imag])
    c, *_ = np.linalg.lstsq(a, y, rcond=None)
    chi2_grip = float(np.sum((y - a @ c) ** 2))
    return PlateDrift(len(rows), float(np.sum(np.abs(v) ** 2 / var)), float(np.sum(np.abs(v - one) ** 2 / var)),
                      float(np.sum(np.abs(v - k * w) ** 2 / var)), (k.real, k.imag), chi2_grip)


def plate_drift_beyond(data: list[tuple[list, list]], model: list[tuple[list, list]],
                       data_fits: list[dict | None] | None = None,
                       model_fits: list[dict | None] | None = None) -> PlateDrift:
    """:class:`PlateDrift` of the drift a model leaves: per gait group, the measured tracks ``data`` and the
    model's tracks ``model`` of the same trials ([([headings per track], [steps per track, mm]), ...], aligned);
    ``data_fits``, ``model_fits``: their own :func:`regress` results where already made.
    The model's drift is read with the measured group's weights (its step variation and position error), so
    that the two regressions are the same linear map and what the model reproduces cancels exactly; its
    error is the model's own (the spread of its steps about the regression)."""
    data_fits = data_fits if data_fits is not None else [regress(list(zip(hs, ds))) for hs, ds in data]
    model_fits = model_fits if model_fits is not None else [regress(list(zip(hs, ds))) for hs, ds in model]
    offsets = []
    for (mh, md), f, own in zip(model, data_fits, model_fits):
        same = regress(list(zip(mh, md)), noise=(f["var_step"], f["var_pos"])) if f is not None else None
        offsets.append(None if own is None or same is None else (same["v"], own["cov_v"]))
    return plate_drift_models(data, data_fits, offsets)


def drift_test(trials) -> dict:
    """Is there plate-frame drift? Chi-square of v = 0 pooled over groups.

    Returns:
      dict: groups (per group: amplitude, v, se, chi2), chi2, dof, p,
      significant (p < P_DRIFT), speed_mm_per_s (pooled |v| / period).
    """
    from scipy.stats import chi2 as chi2_dist
    tracks = _gait_tracks(trials)
    fits = {key: regress(list(zip(hs, ds))) for key, (hs, ds) in tracks.items()}  # as group_drift's
    res = {key: r for key, r in fits.items() if r is not None}
    rows, total, dof = [], 0.0, 0
    for key, r in sorted(res.items()):
        c = float(r["v"] @ np.linalg.solve(r["cov_v"], r["v"]))
        total += c
        dof += 2
        rows.append({"amplitude_deg": key[0], "chirality": key[1], "period_s": key[3], "v_mm": r["v"].tolist(),
                     "se_mm": np.sqrt(np.diag(r["cov_v"])).tolist(), "chi2": c, "cycles": r["cycles"],
                     "spread_deg": r["spread_deg"]})
    p = float(chi2_dist.sf(total, dof)) if dof else float("nan")
    return {"groups": rows, "chi2": total, "dof": dof, "p": p, "significant": bool(dof and p < P_DRIFT),
            "threshold_p": P_DRIFT, "directions": directions(rows),
            "plate_models": plate_drift_models(list(tracks.values()), list(fits.values())).as_dict()}


def downhill(response, direction) -> bool:
    """Does a model robot pulled the way the data drift (``direction``, a plate-frame vector) drift that way?
    ``response``: 2 x 2, its plate-frame drift per degree of the library's ``plate_tilt`` along x and along y,
    which names the way gravity pulls. A tilt pulls a robot along its slope, and a robot whose slides are
    held by Coulomb friction drifts with the pull's component along each way it slides, so its drift has a
    non-negative component along the pull whatever the slides' directions (u . R u >= 0 for a pull along u;
    tests/test_calibrate_mismatch.py checks it on a slider written there). A gait whose model robot, pulled
    along the data's drift, drifts against it is not making a tilt's drift (its trajectories moved for
    another reason between the model runs, as with arms dragging on the plate), and it cannot size one."""
    u = np.asarray(direction, float)
    return bool(u @ np.asarray(response, float) @ u > 0.0)


def fit_tilt(trials, run_model, step_deg: float = 1.0, bound_deg: float = 4.0) -> dict:
    """The plate tilt (x, y in degrees, the library's ``plate_tilt``) whose
    model drift matches the measured one, by weighted least squares over the
    groups, with its covariance, and an interval that carries the model
    robot's mismatch.

    ``run_model(tilt_x, tilt_y)`` returns model tracks aligned with
    ``trials``. The model's drift is linear in small tilts: it is measured at
    zero and at ``step_deg`` along each axis (three model runs).

    The drift a tilt causes scales with how the robot slides, which a model
    robot built differently gets wrong by a factor (docs/calibration.md:
    on the independent robot, a model sliding 5-26x less per cycle drifted
    4-20x less per degree). That factor is a discrepancy the statistical
    error does not hold. It is estimated per gait group, as the log-spread
    of the tilts each group alone gives (one plate, so they should agree)
    and the log of the ratio of the measured robots' slide per cycle to the
    model's (:func:`slide`); their root sum of squares ``log_sd`` widens the
    tilt's magnitude multiplicatively: ``interval`` is the statistical 95 %
    interval scaled by exp(+-1.96 log_sd). The test that the plate is tilted
    at all stays model-free (:func:`drift_test`) and the direction is not
    widened. Intervals end at ``bound_deg`` (the library's tilt range: a
    steeper plate would be seen by eye), and the tilt is shortened along its
    direction to fit them (``tilt_deg_unbounded`` keeps the least-squares value); ``size_determined`` is False where
    the magnitude's interval spans more than a factor 4.

    A gait whose model robot, pulled the way the data drift (their mean direction beyond the model's drift
    on a level plate, weighted as the fit weighs them), drifts against that way (:func:`downhill`) is left
    out of the fit, of its chi^2 and of the mismatch term, and listed in ``uphill_groups`` with its response;
    where no gait is left, there is no fit (``ok`` False).

    ``plate_models_beyond_model``: :func:`plate_drift_beyond` of the data against the level-plate model run,
    whether or not a tilt is fitted (the tilt stage's gate reads it where the model drags its arms on the
    plate or holds an anisotropic plate).
    """
    tracks = _gait_tracks(trials)
    meas = _drifts(tracks)
    zero = run_model(0.0, 0.0)
    model_tracks = _gait_tracks(trials, zero)
    v0 = _drifts(model_tracks)
    vx = group_drift(trials, run_model(step_deg, 0.0))
    vy = group_drift(trials, run_model(0.0, step_deg))
    s_meas, s_model = group_slide(trials), group_slide(trials, zero)
    rows, ys, ws, keys, uphill = [], [], [], [], []
    for key, m in meas.items():
        if key not in v0 or key not in vx or key not in vy:
            continue
        rows.append(np.column_stack([(vx[key]["v"] - v0[key]["v"]) / step_deg,
                                     (vy[key]["v"] - v0[key]["v"]) / step_deg]))
        ys.append(m["v"] - v0[key]["v"])
        ws.append(np.linalg.inv(m["cov_v"] + v0[key]["cov_v"]))  # measured and model drift both carry error
        keys.append(key)
    if rows:  # the way the data drift beyond the model's level-plate drift, weighted as the fit weighs them
        pull = np.linalg.solve(sum(ws), sum(w @ y for w, y in zip(ws, ys)))
        pull = pull / max(float(np.hypot(*pull)), 1e-300)
        kept = [downhill(j, pull) for j in rows]
        uphill = [{"amplitude_deg": k[0], "chirality": k[1], "period_s": k[3], "response_mm_per_deg": j.tolist()}
                  for k, j, ok in zip(keys, rows, kept) if not ok]
        rows, ys, ws, keys = ([x for x, ok in zip(seq, kept) if ok] for seq in (rows, ys, ws, keys))
    # does the drift the model leaves follow the robot's own step? (PlateDrift, beyond the level-plate model)
    both = [k for k in meas if k in v0]
    beyond = plate_drift_beyond([tracks[k] for k in both], [model_tracks[k] for k in both],
                                [meas[k] for k in both], [v0[k] for k in both]).as_dict()
    if not rows:
        return {"ok": False, "uphill_groups": uphill, "plate_models_beyond_model": beyond}
    ata = sum(j.T @ w @ j for j, w in zip(rows, ws))
    atb = sum(j.T @ w @ y for j, w, y in zip(rows, ws, ys))
    cov = np.linalg.inv(ata)
    tilt = cov @ atb
    chi2_before = float(sum(y @ w @ y for y, w in zip(ys, ws)))
    chi2_after = float(sum((y - j @ tilt) @ w @ (y - j @ tilt) for j, w, y in zip(rows, ws, ys)))
    se = np.sqrt(np.diag(cov))
    # the discrepancy: per-group tilts (each group's two equations alone) and the slide ratio
    groups, logs, slides = [], [], []
    for key, j, y in zip(keys, rows, ys):
        g = {"amplitude_deg": key[0], "chirality": key[1], "period_s": key[3], "response_mm_per_deg": j.tolist()}
        if abs(np.linalg.det(j)) > 1e-12 * max(float(np.abs(j).max()) ** 2, 1e-300):
            tg = np.linalg.solve(j, y)
            g["tilt_deg"] = tg.tolist()
            if np.hypot(*tg) > 0:
                logs.append(math.log(float(np.hypot(*tg))))
        if key in s_meas and key in s_model and s_meas[key][0] > 0 and s_model[key][0] > 0:
            g["slide_mm"] = [s_meas[key][0], s_model[key][0]]
            slides.append(math.log(s_meas[key][0] / s_model[key][0]))
        groups.append(g)
    sd_gaits = float(np.std(logs, ddof=1)) if len(logs) > 1 else 0.0
    sd_slide = float(np.sqrt(np.mean(np.square(slides)))) if slides else 0.0
    log_sd = math.hypot(sd_gaits, sd_slide)
    lo_f, hi_f = math.exp(-1.96 * log_sd), math.exp(1.96 * log_sd)

    def widened(v, s_):
        ends = [f * x for f in (lo_f, hi_f) for x in (v - 1.96 * s_, v + 1.96 * s_)]
        return (float(max(min(ends), -bound_deg)), float(min(max(ends), bound_deg)))

    unbounded = tilt.copy()
    # a value the library's plate_tilt can take, shortened along its own direction (the drift fixes the
    # direction; clipping each axis would turn it)
    tilt = tilt * min(1.0, bound_deg / max(float(np.abs(tilt).max()), 1e-300))
    mag = float(math.hypot(*tilt))
    mag_se = float(math.sqrt(max(tilt @ cov @ tilt, 0.0)) / mag) if mag > 0 else float(np.sqrt(np.trace(cov)))
    mag_lo = max(0.0, (mag - 1.96 * mag_se)) * lo_f
    mag_hi = min((mag + 1.96 * mag_se) * hi_f, bound_deg * math.sqrt(2.0))
    return {"ok": True, "tilt_deg": tilt.tolist(), "tilt_deg_unbounded": unbounded.tolist(), "se_deg": se.tolist(),
            "interval": {"tilt_x_deg": widened(tilt[0], se[0]), "tilt_y_deg": widened(tilt[1], se[1])},
            "interval_statistical": {"tilt_x_deg": (float(tilt[0] - 1.96 * se[0]), float(tilt[0] + 1.96 * se[0])),
                                     "tilt_y_deg": (float(tilt[1] - 1.96 * se[1]), float(tilt[1] + 1.96 * se[1]))},
            "chi2_before": chi2_before, "chi2_after": chi2_after, "groups": len(rows),
            "magnitude_deg": mag, "magnitude_interval": (mag_lo, mag_hi),
            "size_determined": bool(mag_lo > 0 and mag_hi / mag_lo <= 4.0),
            "direction_deg": float(math.degrees(math.atan2(tilt[1], tilt[0])) % 360.0),
            "uphill_groups": uphill, "plate_models_beyond_model": beyond,
            "discrepancy": {"log_sd": log_sd, "log_sd_gaits": sd_gaits, "log_sd_slide": sd_slide, "per_group": groups}}


def slide(t, pose, period, body_length) -> list[tuple[int, float]]:
    """Per robot that stays alone: (robot, S) with S (mm per cycle) how far its body slides within a cycle,
    read off its mean within-cycle motion (residuals.features' wobble: displacement and rotation since the
    cycle's start, in the body frame, averaged over cycles per phase bin): the path of that mean curve from
    the cycle's start through its BINS bin means, each rotation counted as the slide of a point a quarter
    of the body's length from its centre (a bar's mean contact point). A tilt's drift is the plate-parallel
    pull biasing the slides (Coulomb friction: drift ~ tilt / mu x slide), so two robots that slide by
    different amounts drift differently on the same plate (docs/calibration.md)."""
    from .residuals import features
    lever = body_length / 4.0 * MM
    out = []
    feats = features(t, pose, None, period)
    for i in range(pose.shape[1]):
        if not robot_alone(pose, i, body_length):
            continue
        w = feats.wobble[0][i]  # [3, BINS]: dx, dy (mm), dtheta (deg)
        if not np.isfinite(w).all():
            continue
        w = np.concatenate([np.zeros((3, 1)), w], 1)
        d = np.diff(w, axis=1)
        out.append((i, float(np.sum(np.hypot(d[0], d[1]) + lever * np.radians(np.abs(d[2]))))))
    return out


def group_slide(trials, tracks=None) -> dict:
    """Mean slide per cycle (mm) per gait group, {key: (mean, se, n robots)}, from the measured tracks
    (``tracks`` None) or from model tracks aligned with ``trials`` (masked like the data)."""
    groups: dict = {}
    for k, tr in enumerate(trials):
        pose = tr.pose if tracks is None else masked(tracks[k], tr)[0]
        for i, s in slide(tr.t, pose, tr.periods, tr.params.robot.body_length):
            groups.setdefault(group_key(tr.gaits[i]), []).append(s)
    out = {}
    for key, v in groups.items():
        v = np.asarray(v)
        out[key] = (float(v.mean()), float(v.std(ddof=1) / math.sqrt(len(v))) if len(v) > 1 else float("nan"), len(v))
    return out
