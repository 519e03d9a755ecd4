"""The collision record, reduced: which contacts happened when, and which of
them attract. numpy only.

A record (``PeriodRecords.collisions``, or a store's ``coll_*`` datasets) has
per lane, period, robot pair, contact kind (``KINDS``: robot i's part, then
robot j's) and bin of the gait period: the time steps in contact, the contact
impulse on robot i (world x, y; N s) and its component along r = c_j - c_i.
A positive component pulls robot i toward robot j: the paper's attraction
criterion (I_N + I_F) . r > 0. By Newton's third law robot j receives the
opposite impulse, which pulls it toward robot i just as much.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..labels import CONTACT_KINDS as KINDS, PARTS  # noqa: F401 (the record's kinds, in its order)
from .relaxation import Spread


@dataclasses.dataclass(frozen=True)
class PeriodTotals:
    """Per lane, period and pair: the impulse along r (N s) and the steps in contact summed over kinds
    and bins ([B, K, P]), and both per contact kind ([B, K, P, 9], in ``KINDS`` order)."""

    impulse_r: np.ndarray
    steps: np.ndarray
    impulse_r_by_kind: np.ndarray
    steps_by_kind: np.ndarray


def period_totals(coll: dict) -> PeriodTotals:
    """Per lane, period and pair: the impulse along r and the steps in contact,
    summed over kinds and bins, and both per kind (``coll``: the collision record's arrays)."""
    ir = np.asarray(coll["impulse_r"], float)
    st = np.asarray(coll["steps"])
    by_kind = ir.sum(-1)
    return PeriodTotals(by_kind.sum(-1), st.sum((-1, -2)), by_kind, st.sum(-1))


def attractive_periods(coll: dict) -> np.ndarray:
    """[B, K, P] bool: some contact kind's impulse along r was positive in
    that period (at least one attractive collision, the paper's criterion)."""
    return (period_totals(coll).impulse_r_by_kind > 0).any(-1)


@dataclasses.dataclass(frozen=True)
class Collision:
    """One contiguous run of phase bins in which one contact kind was in contact, in one period.

    ``kind``: the contact kind (``KINDS``); ``first_bin``, ``last_bin``: its bins (inclusive); ``phase``:
    the fraction of the period at its start; ``steps``: time steps in contact; ``impulse_r``: the impulse
    along r on robot i (N s, positive attracts); ``impulse``: the impulse vector on robot i (N s, world x, y).
    """

    kind: str
    first_bin: int
    last_bin: int
    phase: float
    steps: int
    impulse_r: float
    impulse: tuple[float, float]


def sequence(coll: dict, lane: int, period: int, pair: int = 0, min_steps: int = 1) -> list[Collision]:
    """The collisions of one period of one lane in gait order: one :class:`Collision` per contiguous run
    of bins with at least ``min_steps`` steps in contact of a kind, sorted by start bin (then kind)."""
    st = np.asarray(coll["steps"])[lane, period, pair]
    ir = np.asarray(coll["impulse_r"], float)[lane, period, pair]
    iv = np.asarray(coll["impulse"], float)[lane, period, pair]
    bins = st.shape[-1]
    out = []
    for k, name in enumerate(KINDS):
        on = st[k] >= min_steps
        g = 0
        while g < bins:
            if not on[g]:
                g += 1
                continue
            h = g
            while h + 1 < bins and on[h + 1]:
                h += 1
            sl = slice(g, h + 1)
            vec = iv[k, sl].sum(0)
            out.append(Collision(name, g, h, g / bins, int(st[k, sl].sum()), float(ir[k, sl].sum()),
                                 (float(vec[0]), float(vec[1]))))
            g = h + 1
    return sorted(out, key=lambda e: (e.first_bin, e.kind))


@dataclasses.dataclass(frozen=True)
class KindContacts:
    """One contact kind over the periods a :func:`kind_summary` selected: the fraction of periods with
    that contact (NaN without periods), the mean impulse along r per such period (N s; 0 without one) and
    the fraction of those periods whose impulse along r attracted (NaN without one)."""

    kind: str
    periods_with_contact: float
    mean_impulse_r: float
    attractive_fraction: float


def kind_summary(coll: dict, mask=None) -> tuple[KindContacts, ...]:
    """Per contact kind (``KINDS`` order) over the periods selected by ``mask`` [B, K] (default all), pair 0."""
    t = period_totals(coll)
    st, ir = t.steps_by_kind[..., 0, :], t.impulse_r_by_kind[..., 0, :]  # pair 0
    if mask is not None:
        st, ir = st[np.asarray(mask, bool)], ir[np.asarray(mask, bool)]
    st, ir = st.reshape(-1, len(KINDS)), ir.reshape(-1, len(KINDS))
    out = []
    for k, name in enumerate(KINDS):
        hit = st[:, k] > 0
        out.append(KindContacts(name, float(hit.mean()) if len(hit) else np.nan,
                                float(ir[hit, k].mean()) if hit.any() else 0.0,
                                float((ir[hit, k] > 0).mean()) if hit.any() else np.nan))
    return tuple(out)


# ------------------------------------------------------------------ arm hits and what they slide a robot

SETTLE_S = 0.1  # after a hit, the struck robot is followed this long (friction stops 0.3 m/s in ~80 ms at mu 0.37)


@dataclasses.dataclass(frozen=True)
class ArmHit:
    """One arm hitting another robot's body, and how far the struck robot moved.

    ``striker`` hit ``struck`` from ``start_s`` to ``end_s`` (the collision record's bins: at least one
    step of contact between an arm of the striker and the struck robot's body in each); ``push_mm`` is
    how far the struck robot's centre moved while the hit lasted, ``coast_mm`` how far it moved in the
    ``SETTLE_S`` after it, touching nothing, ``slide_mm`` from the hit's start to the end of that time,
    ``turn_deg`` its heading change over the same span."""

    striker: int
    struck: int
    start_s: float
    end_s: float
    push_mm: float
    coast_mm: float
    slide_mm: float
    turn_deg: float


@dataclasses.dataclass(frozen=True)
class HitSlides:
    """The arm hits of one or more trials (:func:`arm_hits`) and their summary.

    ``left_out``: hits not counted because the struck robot touched a third robot during the hit, touched
    anything in the ``SETTLE_S`` after it, or the track ended first (what it moved is not the hit's alone).
    ``coast_share``: the coasting's share of all the pushing and coasting, sum(coast) / sum(push + coast):
    near 0 where a struck robot moves only while an arm is on it (it is swept aside), near 1 where it is
    kicked and slides on."""

    hits: tuple[ArmHit, ...]
    left_out: int

    @property
    def slide_mm(self) -> Spread:
        return Spread.of([h.slide_mm for h in self.hits])

    @property
    def push_mm(self) -> Spread:
        return Spread.of([h.push_mm for h in self.hits])

    @property
    def coast_mm(self) -> Spread:
        return Spread.of([h.coast_mm for h in self.hits])

    @property
    def duration_ms(self) -> Spread:
        return Spread.of([1e3 * (h.end_s - h.start_s) for h in self.hits])

    @property
    def turn_deg(self) -> Spread:
        """The struck robots' heading change per hit, unsigned."""
        return Spread.of([abs(h.turn_deg) for h in self.hits])

    @property
    def coast_share(self) -> float:
        tot = sum(h.push_mm + h.coast_mm for h in self.hits)
        return float(sum(h.coast_mm for h in self.hits) / tot) if tot > 0 else float("nan")

    def __add__(self, other: "HitSlides") -> "HitSlides":
        return HitSlides(self.hits + other.hits, self.left_out + other.left_out)

    def as_dict(self) -> dict:
        q = dataclasses.asdict
        return {"hits": len(self.hits), "left_out": self.left_out, "slide_mm": q(self.slide_mm),
                "push_mm": q(self.push_mm), "coast_mm": q(self.coast_mm), "duration_ms": q(self.duration_ms),
                "turn_deg": q(self.turn_deg), "coast_share": self.coast_share, "settle_s": SETTLE_S}


def _runs(on: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) of every maximal run of True in a 1-D bool array."""
    d = np.diff(np.concatenate([[0], on.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def arm_hits(steps, pairs, period: float, t, poses, settle_s: float = SETTLE_S) -> HitSlides:
    """The arm hits of one trial and what each slid the struck robot (:class:`ArmHit`).

    Args:
      steps: [K, P, 9, B] the collision record's steps in contact (one trial: periods, pairs i < j, contact
        kinds in ``KINDS`` order — robot i's part, then robot j's — and bins of the period).
      pairs: [P, 2] the robots of each pair.
      period: the gait period (s); bin b of period k spans [(k + b / B) T, (k + (b + 1) / B) T].
      t: [S] times of the track (s, from the trial's start), poses: [S, N, >= 3] x, y (m), heading (rad).

    A hit is a maximal run of bins, across period ends, with contact between an arm of one robot and the
    body of another. It counts where the struck robot touches no robot but the striker during it and
    nothing at all in the ``settle_s`` after it, inside the track."""
    steps = np.asarray(steps)
    pairs = np.asarray(pairs, int)
    k, p, nk, b = steps.shape
    if nk != len(KINDS):
        raise ValueError(f"the collision record has {nk} contact kinds, expected {len(KINDS)}")
    on = steps.transpose(1, 2, 0, 3).reshape(p, nk, k * b) > 0  # [P, kinds, bins in time]
    n = int(pairs.max()) + 1 if len(pairs) else 0
    n = max(n, np.asarray(poses).shape[1])
    touch = np.zeros((n, n, k * b), bool)
    for q, (i, j) in enumerate(pairs):
        touch[i, j] = touch[j, i] = on[q].any(0)
    dtb = period / b
    t = np.asarray(t, float)
    xy = np.asarray(poses, float)[..., :2]
    head = np.unwrap(np.asarray(poses, float)[..., 2], axis=0)

    def at(s, when):
        return np.array([np.interp(when, t, xy[:, s, 0]), np.interp(when, t, xy[:, s, 1])])

    arm_on_i = [KINDS.index(k) for k in ("body-arm1", "body-arm2")]  # robot j's arm on robot i's body
    arm_on_j = [KINDS.index(k) for k in ("arm1-body", "arm2-body")]  # robot i's arm on robot j's body
    hits, left = [], 0
    for q, (i, j) in enumerate(pairs):
        for struck, striker, kinds in ((i, j, arm_on_i), (j, i, arm_on_j)):
            for g0, g1 in _runs(on[q, kinds].any(0)):
                ta, tb = g0 * dtb, (g1 + 1) * dtb
                tc = tb + settle_s
                g2 = min(int(np.ceil(tc / dtb)), k * b)  # bins up to the end of the settling
                others = np.delete(touch[struck, :, g0:g1 + 1], [struck, striker], axis=0)
                if tc > t[-1] or others.any() or touch[struck, :, g1 + 1:g2].any():
                    left += 1
                    continue
                pa, pb, pc = at(struck, ta), at(struck, tb), at(struck, tc)
                turn = np.interp(tc, t, head[:, struck]) - np.interp(ta, t, head[:, struck])
                hits.append(ArmHit(int(striker), int(struck), float(ta), float(tb),
                                   float(1e3 * np.linalg.norm(pb - pa)), float(1e3 * np.linalg.norm(pc - pb)),
                                   float(1e3 * np.linalg.norm(pc - pa)), float(np.degrees(turn))))
    hits.sort(key=lambda h: (h.start_s, h.struck))
    return HitSlides(tuple(hits), left)
