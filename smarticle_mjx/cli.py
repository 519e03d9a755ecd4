"""``smx``: the command line. Thin: parse, build a config, call the library."""

from __future__ import annotations

import math
import pathlib
import sys
from typing import Optional

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Batched simulation of smarticles and the gliders they form.")


class UserError(Exception):
    """Bad input: reported as one line, exit code 2."""


def _fail(msg: str) -> None:
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(2)


def _gait(amplitude: float, chirality: str, gait: str, period: Optional[float]):
    from .gait import GaitSpec
    return GaitSpec(amplitude_deg=amplitude, chirality=chirality, kind=gait, period_s=period)


@app.command()
def simulate(
    scene: str = typer.Option("pair", help="single, pair or seven (the scenes in models/)"),
    config: Optional[str] = typer.Option(None, help="pair start as '|r|,theta,phi' (|r| in W, angles in deg)"),
    amplitude: float = typer.Option(90.0, help="alpha_max in degrees"),
    chirality: str = typer.Option("ccw", help="ccw or cw"),
    gait: str = typer.Option("square", help="square or diagonal (time-symmetric)"),
    period: Optional[float] = typer.Option(None, help="gait period in s (default: 1.6 s x amplitude / 90)"),
    periods: int = typer.Option(10, help="number of gait periods"),
    track_stride: int = typer.Option(20, help="write every this many time steps"),
    out: pathlib.Path = typer.Option(pathlib.Path("track.csv"), help="output .csv (+ .json sidecar) or .h5"),
    overwrite: bool = typer.Option(False, help="replace an existing output file"),
):
    """Simulate one scene and write its track (the measured-data format)."""
    from . import configs, scene as scene_mod, tracks
    from .engine.simulate import simulate as run

    try:
        params = scene_mod.SceneParams()
        g = _gait(amplitude, chirality, gait, period)
        g.validate(params.robot.servo_speed, params.robot.arm_limit_deg)
        if periods < 1 or track_stride < 1:
            raise UserError("--periods and --track-stride must be positive")
        if out.exists() and not overwrite:
            raise UserError(f"{out} exists; pass --overwrite to replace it")
        if out.suffix.lower() not in (".csv", ".h5", ".hdf5"):
            raise UserError(f"--out must end in .csv, .h5 or .hdf5, got {out.name!r}")
        if not out.parent.exists():
            raise UserError(f"output directory {out.parent} does not exist")
        a0 = g.setpoints(0.0, params.robot.servo_speed)
        if config is not None:
            try:
                r, th, ph = (float(v) for v in config.split(","))
            except ValueError:
                raise UserError(f"--config must be three numbers '|r|,theta,phi', got {config!r}") from None
            poses = configs.pair_poses(r, math.radians(th), math.radians(ph), a0[0], a0[1], params.robot)
        else:
            poses = [(x, y, h, a0[0], a0[1]) for x, y, h, _, _ in scene_mod.standard_poses(scene, params.robot)]
        res = run(params, poses, g, periods, track_stride=track_stride)
        meta = tracks.sidecar(len(poses), g, params.plate_friction, 1.0 / (track_stride * params.timestep))
        t = [0.0, *res.track_t]
        track = [res.poses[0], *res.track]
        written = tracks.write_track(out, t, track, meta,
                                     records={"touched": res.touched, "poses": res.poses, "min_dist": res.min_dist})
    except (UserError, ValueError) as e:
        _fail(str(e))
    n_touch = int(res.touched.any(1).sum()) if res.touched.size else 0
    typer.echo(f"{len(poses)} robots, {periods} periods of {res.period:.3g} s; "
               f"pairs touched in {n_touch}/{periods} periods; wrote {', '.join(map(str, written))}")


@app.command()
def models(
    out: pathlib.Path = typer.Option(pathlib.Path("models"), help="directory for the reference scenes"),
    check: bool = typer.Option(False, help="only report whether the stored scenes are up to date"),
):
    """Regenerate (or --check) the reference MJCF scenes in models/."""
    from .scene import reference_models

    stale = []
    for name, xml in reference_models().items():
        path = out / name
        if path.exists() and path.read_text() == xml:
            continue
        stale.append(name)
        if not check:
            if not out.is_dir():
                _fail(f"directory {out} does not exist")
            path.write_text(xml)
    if check and stale:
        _fail(f"stale models: {', '.join(stale)}; run `smx models`")
    typer.echo(("updated: " + ", ".join(stale)) if stale and not check else "models up to date")


def main():  # pragma: no cover
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
