"""Real robots' imperfections: named, sourced sets drawn per robot from stated priors.

A model preset (``presets.py``) is an ideal robot: every robot of a scene is
the same mirror-symmetric machine, and every robot's gait clock is the same.
Real robots are not. An *imperfection set* names which departures a study
draws and from which priors:

* **servo speed**: each arm's servo runs at its own multiple of the nominal
  speed (two servos of one robot differ), so one arm's moves take longer;
* **backlash**: each arm swings freely within its gear's play (a second,
  unactuated hinge; ``scene.RobotQuirk``);
* **centre-of-mass offset**: the body's centre of mass sits off its axis;
* **clock drift**: each robot's gait period differs a little from the
  others' (its board's oscillator);
* **phase jitter**: robots start their gaits at slightly different times
  (per trial: per scan lane, per relaxation trial).

Robot draws depend on the study's seed and the robot's index only (robot 0
of a seed is the same robot in every scan, lane and trial, as the lab
reused its robots); phase jitter depends on the seed and the lane or trial.
A scan may run several pairs of robots (``robot_draws`` K: lane i runs pair
i mod K, robots 2k and 2k + 1 of the pool drawn from ``robot_seed``), so
that a claim measured over its lanes is one of the robots' population, not
of one pair; two studies with the same robot seed and K run the same pairs.
Every store records the set's name, its seed and the values drawn.

The paper's simulation added no noise (``none``). ``--imperfections NAME``
chooses a set; ``smx models --imperfections`` lists them.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .scene import RobotQuirk, SceneParams

_ROBOT_TAG = 0x51524B52  # "QRKR": apart from the configuration and relaxation streams
_LANE_TAG = 0x51524B4C  # "QRKL"

# the slowest arm drawn: at every amplitude of the default period policy a move takes
# 0.9 of its quarter period at the nominal speed (1.6 s at 90 deg, 8.727 rad/s), so an
# arm at 0.92 still fits with its robot's clock 0.5 % fast and the period on the step grid
MIN_SPEED_RATIO = 0.92


@dataclasses.dataclass(frozen=True)
class ImperfectionSet:
    """A named set of imperfections and their priors (0 or None: that imperfection is off).

    Attributes:
      speed_sd: per arm, speed ratio ~ Normal(1, speed_sd) clipped to
        [MIN_SPEED_RATIO, 2 - MIN_SPEED_RATIO].
      backlash_deg: per arm, free play half-width ~ Uniform(lo, hi) deg.
      com_sd_m: per robot, centre-of-mass offset along and across the body ~ Normal(0, com_sd_m).
      clock_halfwidth: per robot, gait period x (1 + e), e ~ Uniform(-h, h).
      phase_sd: per robot and trial, gait phase offset ~ Normal(0, phase_sd) periods.
      sources: (imperfection, where its prior comes from).
    """

    name: str
    summary: str
    speed_sd: float = 0.0
    backlash_deg: tuple[float, float] | None = None
    com_sd_m: float = 0.0
    clock_halfwidth: float = 0.0
    phase_sd: float = 0.0
    sources: tuple[tuple[str, str], ...] = ()

    @property
    def ideal(self) -> bool:
        return not (self.speed_sd or self.backlash_deg or self.com_sd_m or self.clock_halfwidth or self.phase_sd)

    @property
    def changes_scene(self) -> bool:
        return bool(self.backlash_deg or self.com_sd_m)

    def check_backend(self, backend: str) -> None:
        """ValueError, before anything runs, where ``backend`` cannot run this set's gait
        imperfections (the engines refuse them again when they meet them)."""
        from .capabilities import require
        prefix = f"imperfections {self.name!r}: "
        for needed, feature in ((self.speed_sd, "per_arm_speeds"), (self.phase_sd, "start_delays"),
                                (self.clock_halfwidth, "own_clocks"), (self.changes_scene, "robot_quirks")):
            if needed:
                require(backend, feature, prefix)

    def priors(self) -> dict:
        return {"speed_sd": self.speed_sd, "backlash_deg": None if self.backlash_deg is None else list(self.backlash_deg),
                "com_sd_m": self.com_sd_m, "clock_halfwidth": self.clock_halfwidth, "phase_sd": self.phase_sd}


_SPEED = ("servo speed ratio per arm ~ N(1, 0.05), clipped to [0.92, 1.08]",
          "chosen: public sources give no unit-to-unit spread for the lab's Power HD HD-1440A (on a 3.7 V cell "
          "against its rated 4.8 V); a 10 % difference between a robot's two servos is what a planar estimate "
          "needs for the lab's 1.5e-3 W/cycle (shared/reference/smarticle.md); 0.92 is the slowest arm whose "
          "move still fits its quarter period with a fast clock")
_BACKLASH = ("gear backlash per arm ~ U(1, 2) deg half-width",
             "MuJoCo's modelling guide (Backlash: a second hinge of +-1-2 deg); the play of small plastic-gear "
             "hobby servos")
_COM = ("centre-of-mass offset per robot ~ N(0, 1 mm) along and across the body",
        "chosen: battery and board placed by hand in a 5.4 x 2.2 cm body; not measured in public sources")
_CLOCK = ("gait period per robot x (1 + e), e ~ U(-0.5 %, 0.5 %)",
          "the +-0.5 % frequency tolerance of the ceramic resonators of Arduino-class boards "
          "(the lab firmware: wsavoie/ArduinoSmarticle)")
_PHASE = ("gait start per robot and trial ~ N(0, 0.02) periods (32 ms at 90 deg): the robots start one after "
          "another by these offsets, each from its gait's first corner",
          "chosen: robots started by one command within a 20 ms servo frame or two")

_RESYNC = ("no clock drift between cycles: every robot is re-started each gait cycle and keeps its start offset",
           "the lab firmware re-triggers every robot each gait cycle on an external (microphone) interrupt "
           "(wsavoie/ArduinoSmarticle, regularStates/interruptPhaseLocking); a clock 0.5 % off then moves its "
           "last corner at most 8 ms (0.005 period) early or late within the cycle, which this set leaves out")

SETS: dict[str, ImperfectionSet] = {s.name: s for s in (
    ImperfectionSet("none", "ideal robots with one clock (the paper's simulation added no noise)"),
    ImperfectionSet("lab", "every imperfection below, at its stated prior: the lab's robots as public sources "
                    "bound them", speed_sd=0.05, backlash_deg=(1.0, 2.0), com_sd_m=1e-3, clock_halfwidth=5e-3,
                    phase_sd=0.02, sources=(_SPEED, _BACKLASH, _COM, _CLOCK, _PHASE)),
    ImperfectionSet("lab-resync", "the lab set with the firmware's per-cycle re-synchronisation: the same robots "
                    "(servos, gears, centres of mass) and start offsets, clocks that do not walk apart",
                    speed_sd=0.05, backlash_deg=(1.0, 2.0), com_sd_m=1e-3, phase_sd=0.02,
                    sources=(_SPEED, _BACKLASH, _COM, _PHASE, _RESYNC)),
    ImperfectionSet("drivetrain", "each robot's own servos and gears (speed per arm and backlash), with one "
                    "shared clock and start: what the robot is, without how it is run", speed_sd=0.05,
                    backlash_deg=(1.0, 2.0), sources=(_SPEED, _BACKLASH)),
    ImperfectionSet("servo-speed", "only the two servos' speeds differ", speed_sd=0.05, sources=(_SPEED,)),
    ImperfectionSet("backlash", "only gear backlash", backlash_deg=(1.0, 2.0), sources=(_BACKLASH,)),
    ImperfectionSet("com-offset", "only an off-centre centre of mass", com_sd_m=1e-3, sources=(_COM,)),
    ImperfectionSet("clock-drift", "only the robots' gait clocks differ", clock_halfwidth=5e-3, sources=(_CLOCK,)),
    ImperfectionSet("phase-jitter", "only the robots' gait starts differ", phase_sd=0.02, sources=(_PHASE,)),
)}


def get(name: str) -> ImperfectionSet:
    """The set called ``name`` (ValueError, one line naming the known ones)."""
    try:
        return SETS[name]
    except KeyError:
        raise ValueError(f"unknown imperfections {name!r}; choose one of {', '.join(SETS)}") from None


@dataclasses.dataclass(frozen=True)
class Draw:
    """The imperfections of robots 0..N-1 under one set and seed.

    Attributes:
      arm_speed: [N, 2] each arm's servo speed ratio.
      clock: [N] each robot's gait period as a multiple of the nominal one.
      quirks: per robot, backlash and centre-of-mass offset (scene level).
    """

    set: ImperfectionSet
    seed: int
    arm_speed: np.ndarray
    clock: np.ndarray
    quirks: tuple[RobotQuirk, ...]

    def robot(self, i: int) -> "Draw":
        """Robot ``i`` alone: a one-robot draw (a lone robot on the plate)."""
        return self._robots(i, i + 1)

    def pair(self, k: int) -> "Draw":
        """Robots ``2k`` and ``2k + 1``: the ``k``-th pair of a pool drawn for several pairs (a scan whose
        lanes run ``robot_draws`` different pairs of robots). Pair 0 of a two-robot draw is the draw itself."""
        if not 0 <= 2 * k + 1 < len(self.clock):
            raise ValueError(f"pair {k} is not in a draw of {len(self.clock)} robots")
        return self._robots(2 * k, 2 * k + 2)

    def _robots(self, lo: int, hi: int) -> "Draw":
        return dataclasses.replace(self, arm_speed=self.arm_speed[lo:hi], clock=self.clock[lo:hi],
                                   quirks=self.quirks[lo:hi])

    def scene(self, params: SceneParams) -> SceneParams:
        """``params`` with these robots' scene-level quirks (unchanged for a set without any)."""
        if not self.set.changes_scene:
            return params
        return params.replace(quirks=self.quirks)

    def lane_phase(self, rows) -> np.ndarray:
        """[len(rows), N] gait phase offsets (periods) of lanes or trials ``rows``."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        n = len(self.clock)
        if not self.set.phase_sd:
            return np.zeros((len(rows), n))
        return np.stack([np.random.default_rng([self.seed, int(r), _LANE_TAG]).normal(0.0, self.set.phase_sd, n)
                         for r in rows]) if len(rows) else np.zeros((0, n))

    def lanes(self, lanes, rows, start_delays: bool = True):
        """``lanes`` (engine ``Lanes`` of rows ``rows``) with these robots' speeds, clocks and phases.

        A set's gait-start offsets are start delays (``start_delays``, since version 0.4.1): in each lane
        the robot furthest ahead starts at t = 0, each other one its offset later, all from the gait's
        first corner (``Lanes.with_start_delays``). ``start_delays=False`` gives what versions up to 0.4.0
        ran (every robot's clock started at t = 0 at its offset, so a robot ahead began part of a move
        away from its arms), to replay their stores."""
        b, n = lanes.poses.shape[:2]
        if n != len(self.clock):
            raise ValueError(f"imperfections drawn for {len(self.clock)} robots, lanes have {n}")
        if self.set.ideal:
            return lanes
        changes = {"phase": lanes.phase + self.lane_phase(rows)}
        if self.set.speed_sd:
            changes["arm_speed"] = np.broadcast_to(self.arm_speed, (b, n, 2)).copy()
        if self.set.clock_halfwidth:
            changes["robot_period"] = lanes.period * np.broadcast_to(self.clock, (b, n)).copy()
        lanes = dataclasses.replace(lanes, **changes)
        return lanes.with_start_delays() if self.set.phase_sd and start_delays else lanes

    def to_json(self) -> dict:
        return {"name": self.set.name, "seed": int(self.seed), "priors": self.set.priors(),
                "arm_speed": self.arm_speed.tolist(), "clock": self.clock.tolist(),
                "backlash_deg": [list(q.backlash_deg) if q.backlash_deg is not None else None for q in self.quirks],
                "com_offset_m": [list(q.com_offset) for q in self.quirks]}


def draw(name: str, n_robots: int, seed: int) -> Draw:
    """Draw robots 0..n_robots-1 of set ``name``; robot i's values depend on (seed, i) only."""
    s = get(name)
    speed, clock, quirks = np.ones((n_robots, 2)), np.ones(n_robots), []
    for i in range(n_robots):
        rng = np.random.default_rng([int(seed), i, _ROBOT_TAG])
        # one stream per robot, drawn in a fixed order whatever the set switches on
        z_speed = rng.normal(0.0, 1.0, 2)
        u_play = rng.uniform(0.0, 1.0, 2)
        z_com = rng.normal(0.0, 1.0, 2)
        u_clock = rng.uniform(-1.0, 1.0)
        speed[i] = np.clip(1.0 + s.speed_sd * z_speed, MIN_SPEED_RATIO, 2.0 - MIN_SPEED_RATIO)
        clock[i] = 1.0 + s.clock_halfwidth * u_clock
        play = None
        if s.backlash_deg:
            lo, hi = s.backlash_deg
            play = tuple(float(lo + (hi - lo) * u) for u in u_play)
        quirks.append(RobotQuirk(backlash_deg=play, com_offset=tuple(float(v) + 0.0 for v in s.com_sd_m * z_com)))
    return Draw(s, int(seed), speed, clock, tuple(quirks))


def from_json(d: dict | None) -> Draw | None:
    """The draw a store recorded, re-drawn from its name and seed (None: the store has none)."""
    if not d:
        return None
    return draw(d["name"], len(d["clock"]), int(d["seed"]))


def catalogue() -> list[str]:
    """Every model preset and imperfection set with the sources of their values (``smx models --list``)."""
    from . import presets
    lines = []
    for p in presets.PRESETS.values():
        lines.append(f"{p.name}{' (default)' if p.name == presets.DEFAULT else ''}: {p.summary}")
        lines += [f"    {field}: {source}" for field, source in p.sources]
    lines.append("\nimperfections (--imperfections NAME):")
    for st in SETS.values():
        lines.append(f"{st.name}: {st.summary}")
        lines += [f"    {prior}: {source}" for prior, source in st.sources]
    return lines
