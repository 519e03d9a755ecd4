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
