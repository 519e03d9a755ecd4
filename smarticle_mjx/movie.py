"""Top-view movies of robots, drawn as in the paper's figures.

Each frame shows every robot's body rectangle and arms (their true outline:
plate or capsule), an arrow along the body normal n (the paper's reference
direction, -y in the body frame), a fading trail of the body centres, the
gait period reached and, for a pair, (|r|, theta, phi). Input is a track
[S, N, 5] of poses sampled at times t: from ``smx simulate``, or a lane of a
scan store simulated again (``replay.resimulate_lane``). No engine here.

MP4 goes through the ffmpeg that ``imageio-ffmpeg`` ships (``pip install -e
'.[movie]'``); without it, or for a ``.gif`` name, the movie is a GIF (Pillow).
"""

from __future__ import annotations

import dataclasses
import math
import pathlib

import numpy as np

from . import configs as C
from .scene import RobotParams

COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2")


@dataclasses.dataclass(frozen=True)
class Movie:
    """A rendered movie: its path, format ("mp4" or "gif"), frames, frame rate and size (pixels)."""

    path: pathlib.Path
    format: str
    frames: int
    fps: float
    size: tuple[int, int]


@dataclasses.dataclass(frozen=True)
class MovieOptions:
    """How time maps to frames.

    Attributes:
      fps: frames per second of the movie.
      speed: simulated seconds per movie second (1: real time).
      duration: movie length in s (None: the whole track at ``speed``).
      trail_periods: length of the fading trail, in gait periods.
      size_px: frame width and height in pixels.
    """

    fps: float = 20.0
    speed: float = 4.0
    duration: float | None = None
    trail_periods: float = 5.0
    size_px: int = 480

    def validate(self):
        if not (self.fps > 0 and self.speed > 0 and self.trail_periods >= 0 and self.size_px >= 64):
            raise ValueError("--fps and --speed must be positive, --size at least 64 px")
        if self.size_px % 2:
            raise ValueError(f"--size must be even (video encoders need it), got {self.size_px}")
        if self.duration is not None and not self.duration > 0:
            raise ValueError(f"--duration must be positive, got {self.duration}")


def check_output(out) -> None:
    """ValueError unless ``out`` is a .mp4 or .gif in an existing folder."""
    out = pathlib.Path(out)
    if out.suffix.lower() not in (".mp4", ".gif"):
        raise ValueError(f"movie must end in .mp4 or .gif, got {out.name!r}")
    if not out.parent.is_dir():
        raise ValueError(f"output directory {out.parent} does not exist")


def load_track(path) -> tuple:
    """(t [S], poses [S, N, 5], robot, period_s, title) of a track written by ``smx simulate``
    (.csv with its .json sidecar, or .h5); the first trial of a multi-trial CSV."""
    from . import tracks
    path = pathlib.Path(path)
    if path.suffix.lower() == ".csv":
        trial = tracks.read_csv(path)[0]
        if not trial.arms_tracked:
            raise ValueError(f"{path} has no arm angles; a movie needs them")
        return trial.t, trial.poses, trial.params.robot, trial.gaits[0].period(), path.name
    if path.suffix.lower() in (".h5", ".hdf5"):
        t, poses, gait, robot = tracks.read_h5(path)
        return t, poses, robot, gait.period(), path.name
    raise ValueError(f"{path}: a track is .csv or .h5")


def frame_times(t: np.ndarray, opts: MovieOptions) -> np.ndarray:
    """Simulated times shown by the frames."""
    end = float(t[-1])
    if opts.duration is not None:
        end = min(end, float(t[0]) + opts.duration * opts.speed)
    n = int(math.floor((end - t[0]) * opts.fps / opts.speed + 1e-9)) + 1
    return float(t[0]) + np.arange(n) * opts.speed / opts.fps


def _capsule(seg: np.ndarray, radius: float) -> np.ndarray:
    """A capsule arm's outline (its axis segment widened by ``radius``; ends square)."""
    a, b = seg
    d = b - a
    n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-12) * radius
    e = d / max(np.linalg.norm(d), 1e-12) * radius
    return np.array([a - n - e, b - n + e, b + n + e, a + n - e])


def render(t, poses, robot: RobotParams, period_s: float, out, opts: MovieOptions = MovieOptions(),
           title: str = "") -> dict:
    """Write a movie of the track (``t`` [S], ``poses`` [S, N, 5]) to ``out`` (.mp4 or .gif).

    Returns {"path", "format", "frames", "size": (w, h), "fps"}; an .mp4 name
    becomes .gif when no packaged ffmpeg is installed.
    """
    opts.validate()
    t = np.asarray(t, float)
    poses = np.asarray(poses, float)
    if poses.ndim != 3 or poses.shape[2] != 5 or len(t) != len(poses) or len(t) < 1:
        raise ValueError("a track is poses [S, N, 5] at S times")
    out = pathlib.Path(out)
    if out.suffix.lower() not in (".mp4", ".gif"):
        raise ValueError(f"movie must end in .mp4 or .gif, got {out.name!r}")
    if not out.parent.is_dir():
        raise ValueError(f"output directory {out.parent} does not exist")
    fmt = out.suffix.lower()[1:]
    ffmpeg = None
    if fmt == "mp4":
        try:
            import imageio_ffmpeg
            ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
        except (ImportError, RuntimeError):
            out, fmt = out.with_suffix(".gif"), "gif"
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import animation
    from matplotlib.collections import LineCollection
    from matplotlib.patches import FancyArrow, Polygon

    times = frame_times(t, opts)
    idx = np.clip(np.searchsorted(t, times - 1e-12), 0, len(t) - 1)
    n = poses.shape[1]
    w = robot.body_length
    reach = w / 2 + max(robot.arm_lengths)
    xy = poses[..., :2]
    lo, hi = np.nanmin(xy, (0, 1)) - 1.3 * reach, np.nanmax(xy, (0, 1)) + 1.3 * reach
    centre, half = (lo + hi) / 2, max((hi - lo).max() / 2, 2 * reach)
    dpi = 100
    fig = plt.figure(figsize=(opts.size_px / dpi, opts.size_px / dpi), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    scale = 0.02 if half < 0.2 else 0.05
    x0, y0 = centre[0] - 0.92 * half, centre[1] - 0.92 * half
    ax.plot([x0, x0 + scale], [y0, y0], color="k", lw=2)
    ax.text(x0 + scale / 2, y0 + 0.02 * half, f"{scale * 100:.0f} cm", ha="center", fontsize=8)
    bodies, arms, trails, arrows = [], [], [], []
    for i in range(n):
        c = COLOURS[i % len(COLOURS)]
        bodies.append(ax.add_patch(Polygon(np.zeros((4, 2)), closed=True, fc=c, ec="k", lw=0.8, alpha=0.85)))
        arms.append([ax.add_patch(Polygon(np.zeros((4, 2)), closed=True, fc="0.25", ec="k", lw=0.5))
                     for _ in range(4 if robot.has_mount else 2)])  # arms, then their mounts
        trails.append(ax.add_collection(LineCollection([], colors=c, linewidths=1.5)))
        arrows.append(None)
    label = ax.text(0.03, 0.97, "", transform=ax.transAxes, va="top", fontsize=9, family="monospace")
    if title:
        ax.text(0.97, 0.02, title, transform=ax.transAxes, va="bottom", ha="right", fontsize=8)  # clear of the clock
    radius = C.arm_piece_radius(robot)
    trail_s = opts.trail_periods * period_s

    def draw(f):
        k = idx[f]
        p = poses[k]
        corners, arm_out = C.robot_outline(p, robot)
        mounts = C.mount_outline(p, robot)
        for i in range(n):
            bodies[i].set_xy(corners[i])
            for a in range(2):
                shape = arm_out[i, a]
                arms[i][a].set_xy(shape if len(shape) == 4 else _capsule(shape, radius))
                if mounts is not None:
                    arms[i][2 + a].set_xy(mounts[i, a])
            # fading trail of the body centre
            j0 = int(np.searchsorted(t, t[k] - trail_s))
            pts = xy[j0:k + 1, i]
            if len(pts) > 1:
                segs = np.stack([pts[:-1], pts[1:]], 1)
                alpha = np.linspace(0.05, 0.9, len(segs))
                rgba = np.tile(matplotlib.colors.to_rgba(COLOURS[i % len(COLOURS)]), (len(segs), 1))
                rgba[:, 3] = alpha
                trails[i].set_segments(segs)
                trails[i].set_color(rgba)
            else:
                trails[i].set_segments([])
            # body normal n = -y of the body frame
            h = p[i, 2]
            nx, ny = math.sin(h), -math.cos(h)
            if arrows[i] is not None:
                arrows[i].remove()
            arrows[i] = ax.add_patch(FancyArrow(p[i, 0], p[i, 1], 0.6 * w * nx, 0.6 * w * ny, width=0.04 * w,
                                                head_width=0.18 * w, head_length=0.18 * w, color="k",
                                                length_includes_head=True))
        text = f"t {t[k]:7.2f} s   period {t[k] / period_s:6.2f}"
        if n == 2:
            r, th, ph = C.relative_coordinates(p[0], p[1], w)
            text += f"\n|r| {float(r):.2f} W  θ {math.degrees(float(th)) % 360:5.1f}°  φ {math.degrees(float(ph)) % 360:5.1f}°"
        label.set_text(text)
        return []

    anim = animation.FuncAnimation(fig, draw, frames=len(times), blit=False)
    tmp = out.with_name(out.stem + ".part" + out.suffix)
    try:
        if fmt == "mp4":
            matplotlib.rcParams["animation.ffmpeg_path"] = ffmpeg
            writer = animation.FFMpegWriter(fps=opts.fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
        else:
            writer = animation.PillowWriter(fps=opts.fps)
        anim.save(tmp, writer=writer, dpi=dpi)
        tmp.replace(out)
    finally:
        plt.close(fig)
        if tmp.exists():
            tmp.unlink()
    return Movie(out, fmt, len(times), opts.fps, (opts.size_px, opts.size_px))
