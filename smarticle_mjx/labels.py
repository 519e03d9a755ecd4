"""The names the records use, shared by every floor (engine, store, reducers).

Nothing here imports anything of the package, so any floor may use it
without a back-arrow: the parts of a robot and the contact kinds between two
robots (the collision record's order), and the per-lane status bits.
"""

from __future__ import annotations

import enum

# The parts of a robot (MJCF geoms r{i}_body, r{i}_arm1, r{i}_arm2) and the nine
# contact kinds between robots i < j, robot i's part first, in the record's order.
PARTS = ("body", "arm1", "arm2")
CONTACT_KINDS = tuple(f"{a}-{b}" for a in PARTS for b in PARTS)


class Status(enum.IntFlag):
    """Per-lane status bits; a lane may carry several. ``OK`` is 0."""

    OK = 0
    INVALID = 1  # initial configuration overlaps: never simulated
    NONFINITE = 2  # NaN/inf appeared in the state
    PENETRATION = 4  # robots interpenetrated deeper than the bound
    RETIRED = 8  # stopped early: outcome decided (engine.batch)
    OVERFLOW = 16  # contact/constraint buffers overflowed (warp backend): records not trustworthy


# a lane whose records cannot be trusted
BAD_STATUS = Status.NONFINITE | Status.PENETRATION | Status.OVERFLOW
# the store's flag meanings (CF conventions), bit by bit
STATUS_MEANINGS = {Status.INVALID: "invalid_start", Status.NONFINITE: "non_finite",
                   Status.PENETRATION: "penetration", Status.RETIRED: "retired_early", Status.OVERFLOW: "buffer_overflow"}
