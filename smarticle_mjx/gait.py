"""Gait: time -> arm setpoints, one pure JAX-traceable function for every backend.

Square gait of amplitude a (radians), corners c0 = (+a, +a) then, for
chirality ``CCW`` (+1, counter-clockwise in the (alpha1, alpha2) plane):
(-a, +a), (-a, -a), (+a, -a); for ``CW`` (-1): (+a, -a), (-a, -a), (-a, +a).
Each quarter period one arm moves 2a at the servo's maximal speed, then both
dwell at the corner. CW is CCW with the arms swapped, which is the mirror
image of the robot: opposite chiralities give mirror-image trajectories.

Time-symmetric gait (``DIAGONAL``): c0 -> c2 -> c0, both arms moving at once
(U shape to the opposite U shape and back; S1 -> S3 -> S1 in the paper).

Period policy: a fixed period, or ``period = ref_period * a / ref_amplitude``
(the paper: fixed arm speed, dwell scaled so the period scales with the
amplitude; 1.6 s at 90 deg). The period must leave time for each move.

Every argument but ``kind``-independent constants may be a traced array, so
amplitude, chirality, gait kind and phase offset vary per lane without
recompiling. Works with numpy inputs as well (results are jax arrays).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

SQUARE = 0
DIAGONAL = 1
CCW = 1
CW = -1
KINDS = {"square": SQUARE, "diagonal": DIAGONAL}
CHIRALITIES = {"ccw": CCW, "cw": CW}


def move_time(amplitude, speed, kind):
    """Duration of one edge: 2a at ``speed`` (both gait kinds move 2a)."""
    return 2.0 * amplitude / speed


def setpoints(t, amplitude, period, speed, chirality=CCW, kind=SQUARE, phase=0.0, ratio1=1.0, ratio2=1.0):
    """Arm setpoints (alpha1, alpha2) at time ``t``.

    Args:
      t: time in s, any shape.
      amplitude: alpha_max in rad.
      period: gait period in s.
      speed: maximal arm speed in rad/s; each move is a ramp at this speed.
      chirality: ``CCW`` (+1) or ``CW`` (-1).
      kind: ``SQUARE`` (0) or ``DIAGONAL`` (1).
      phase: offset as a fraction of the period (robot lags by ``phase * T``
        when negative, leads when positive).
      ratio1, ratio2: each arm's servo speed as a multiple of ``speed`` (a
        robot whose two servos differ); an arm moves at its own speed and
        starts each move at the quarter's start, so a ratio changes only
        that arm's timing. A move must fit in its quarter (half period,
        diagonal), which :func:`check_fit` tests.

    Returns:
      Array [..., 2] of setpoints in rad, broadcast over all arguments.
    """
    t = jnp.asarray(t, dtype=float)
    a = jnp.asarray(amplitude, dtype=float)
    T = jnp.asarray(period, dtype=float)
    u = jnp.mod(t / T + phase, 1.0)  # gait phase in [0, 1)
    u = jnp.where(u >= 1.0, 0.0, u)  # float32 mod of a value just below 0 rounds to 1.0: that is phase 0
    tm1 = move_time(a, speed * jnp.asarray(ratio1, dtype=float), kind)
    tm2 = move_time(a, speed * jnp.asarray(ratio2, dtype=float), kind)

    # square: quarter q in 0..3, time since quarter start
    q = jnp.floor(u * 4.0)
    tq = (u - q / 4.0) * T
    # arm that moves in quarter q: CCW moves arm1 on even quarters
    ccw = jnp.asarray(chirality) > 0
    arm1_moves_even = ccw
    s_f = jnp.clip(tq / jnp.where(arm1_moves_even, tm1, tm2), 0.0, 1.0)  # progress of the "first" arm's move
    s_s = jnp.clip(tq / jnp.where(arm1_moves_even, tm2, tm1), 0.0, 1.0)  # and of the "second"'s
    # value of arm "first" (moves on even quarters) and "second" (odd)
    # first: +a -> -a in q0, stays -a in q1, -a -> +a in q2, stays +a in q3
    first = jnp.select([q == 0, q == 1, q == 2], [a * (1 - 2 * s_f), -a, -a * (1 - 2 * s_f)], a)
    # second: +a in q0, +a -> -a in q1, -a in q2, -a -> +a in q3
    second = jnp.select([q == 0, q == 1, q == 2], [a, a * (1 - 2 * s_s), -a], -a * (1 - 2 * s_s))
    sq1 = jnp.where(arm1_moves_even, first, second)
    sq2 = jnp.where(arm1_moves_even, second, first)

    # diagonal: half h in 0..1, both arms +a -> -a then -a -> +a
    h = jnp.floor(u * 2.0)
    th = (u - h / 2.0) * T
    sd1, sd2 = (jnp.clip(th / tm, 0.0, 1.0) for tm in (tm1, tm2))
    dg1, dg2 = (jnp.where(h == 0, a * (1 - 2 * sd), -a * (1 - 2 * sd)) for sd in (sd1, sd2))

    diag = jnp.asarray(kind) == DIAGONAL
    return jnp.stack([jnp.where(diag, dg1, sq1), jnp.where(diag, dg2, sq2)], -1)


def host_setpoints(t, amplitude, period, speed, chirality=CCW, kind=SQUARE, phase=0.0, ratio1=1.0, ratio2=1.0):
    """:func:`setpoints` on the host in numpy, bit for bit.

    The same operations in the same order and in the float type JAX computes in (float32 unless JAX's
    64-bit mode is on), without JAX's dispatch of each operation: an eager call of :func:`setpoints`
    costs milliseconds, this one microseconds. The replay of tracked arms (``engine.core.follow_corners``)
    calls it several times per model run. It must stay identical to :func:`setpoints` (a model robot
    rattling in its backlash amplifies a last-bit change of a setpoint into another run), which
    tests/test_gait.py checks over random and boundary inputs. Returns numpy [..., 2].
    """
    f = np.dtype(jax.dtypes.canonicalize_dtype(np.float64))  # float32, or float64 in JAX's 64-bit mode

    def arr(x):  # jnp.asarray(x, dtype=float); numpy arrays keep their type until they meet one of f's
        return np.asarray(x, dtype=f)

    def div(x, y):  # XLA divides by a divisor broadcast to the quotient's shape as a product with its inverse
        x, y = cast(x), cast(y)
        if np.shape(y) != np.broadcast_shapes(np.shape(x), np.shape(y)):
            return x * (f.type(1.0) / y)
        return x / y

    def cast(x):  # JAX converts an operand of an operation with f to f, unless a Python number (weakly typed)
        weak = isinstance(x, (int, float)) and not isinstance(x, np.generic)
        return x if weak else np.asarray(x).astype(f)

    t, a, T = arr(t), arr(amplitude), arr(period)
    u = np.mod(div(t, T) + cast(phase), f.type(1.0))
    u = np.where(u >= 1.0, f.type(0.0), u)
    tm1 = div(2.0 * a, cast(speed) * arr(ratio1))  # move_time
    tm2 = div(2.0 * a, cast(speed) * arr(ratio2))
    q = np.floor(u * f.type(4.0))
    tq = (u - q / f.type(4.0)) * T
    arm1_moves_even = np.asarray(chirality) > 0
    s_f = np.clip(div(tq, np.where(arm1_moves_even, tm1, tm2)), f.type(0.0), f.type(1.0))
    s_s = np.clip(div(tq, np.where(arm1_moves_even, tm2, tm1)), f.type(0.0), f.type(1.0))
    first = np.select([q == 0, q == 1, q == 2], [a * (1 - 2 * s_f), -a, -a * (1 - 2 * s_f)], a)
    second = np.select([q == 0, q == 1, q == 2], [a, a * (1 - 2 * s_s), -a], -a * (1 - 2 * s_s))
    sq1 = np.where(arm1_moves_even, first, second)
    sq2 = np.where(arm1_moves_even, second, first)
    h = np.floor(u * f.type(2.0))
    th = (u - h / f.type(2.0)) * T
    sd1, sd2 = (np.clip(div(th, tm), f.type(0.0), f.type(1.0)) for tm in (tm1, tm2))
    dg1, dg2 = (np.where(h == 0, a * (1 - 2 * sd), -a * (1 - 2 * sd)) for sd in (sd1, sd2))
    diag = np.asarray(kind) == DIAGONAL
    return np.stack(np.broadcast_arrays(np.where(diag, dg1, sq1), np.where(diag, dg2, sq2)), -1).astype(f, copy=False)


def check_fit(amplitude, period, speed, kind, ratios) -> None:
    """ValueError unless every arm's move, at ``speed`` times its ratio, fits in
    its quarter (square) or half (diagonal) period; arrays broadcast."""
    edges = np.where(np.asarray(kind) == DIAGONAL, 2, 4)
    slowest = np.min(np.asarray(ratios, float), axis=-1) if np.ndim(ratios) else float(ratios)
    need = 2.0 * np.asarray(amplitude, float) / (speed * slowest)
    room = np.asarray(period, float) / edges
    if np.any(need > room * (1 + 1e-9)):
        worst = float(np.max(need / room))
        raise ValueError(f"an arm's servo is too slow for its gait: its move takes {worst:.3g} of the time "
                         "the gait allows (raise the period or the arm's speed ratio)")


def setpoints_and_rates(t, amplitude, period, speed, chirality=CCW, kind=SQUARE, phase=0.0, ratio1=1.0, ratio2=1.0):
    """Setpoints and their time derivatives, [..., 4] = (a1, a2, da1/dt, da2/dt).

    The rates are the exact derivative of :func:`setpoints` (forward-mode
    autodiff), i.e. +-speed during a move and 0 while dwelling; the servo
    uses them as velocity feed-forward.
    """
    t = jnp.asarray(t, dtype=float)
    f = lambda tt: setpoints(tt, amplitude, period, speed, chirality, kind, phase, ratio1, ratio2)  # noqa: E731
    sp, rate = jax.jvp(f, (t,), (jnp.ones_like(t),))
    return jnp.concatenate([sp, rate], -1)


@dataclasses.dataclass(frozen=True)
class GaitSpec:
    """A gait as a user names it (host-side, validated).

    ``period_s`` None means the paper's policy: ``ref_period_s`` scaled by
    ``amplitude_deg / ref_amplitude_deg``.
    """

    amplitude_deg: float = 90.0
    chirality: str = "ccw"
    kind: str = "square"
    period_s: float | None = None
    ref_period_s: float = 1.6
    ref_amplitude_deg: float = 90.0

    def period(self) -> float:
        if self.period_s is not None:
            return float(self.period_s)
        return self.ref_period_s * self.amplitude_deg / self.ref_amplitude_deg

    def validate(self, speed: float, arm_limit_deg: float = 100.0) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"gait kind must be one of {sorted(KINDS)}, got {self.kind!r}")
        if self.chirality not in CHIRALITIES:
            raise ValueError(f"chirality must be one of {sorted(CHIRALITIES)}, got {self.chirality!r}")
        if not 0 < self.amplitude_deg <= min(90.0, arm_limit_deg):
            raise ValueError(f"amplitude must be in (0, 90] deg (servo range), got {self.amplitude_deg}")
        T = self.period()
        if not (T > 0 and math.isfinite(T)):
            raise ValueError(f"gait period must be positive, got {T}")
        edges = 4 if self.kind == "square" else 2
        need = edges * float(move_time(math.radians(self.amplitude_deg), speed, KINDS[self.kind]))
        if T < need * (1 - 1e-9):
            raise ValueError(
                f"period {T:.4g} s is shorter than the {edges} moves at max speed need ({need:.4g} s)")

    @property
    def amplitude(self) -> float:
        return math.radians(self.amplitude_deg)

    @property
    def chirality_sign(self) -> int:
        return CHIRALITIES[self.chirality]

    @property
    def kind_code(self) -> int:
        return KINDS[self.kind]

    def setpoints(self, t, speed: float, phase=0.0) -> np.ndarray:
        """Host convenience: numpy setpoints [..., 2] at times ``t``."""
        return host_setpoints(t, self.amplitude, self.period(), speed, self.chirality_sign, self.kind_code, phase)
