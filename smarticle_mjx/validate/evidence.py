"""Evidence for the claims: the numbers each claim of :mod:`.claims` tests, read from the studies' stores
(and the lone robots' tracks), with the page's figures drawn on the way.

:func:`gather` returns ``(evidence, extra, figures)``: claim key -> its evidence (None where a study is
missing), the numbers written beside the page (``validation.json``), the figure files in page order.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
from typing import Any, Callable

import numpy as np

from .. import plots
from ..configs import TWO_PI
from ..reduce import binding, gliders as GL, transport
from ..reduce import analysis, rebinding as rebind
from ..reduce.rebinding import Rebinding
from ..report import amplitude_panels, analyse_store_run, pb_rows
from ..store import Store
from .claims import CLAIMS, pb_groups
from .inputs import (BindingVsAmplitude, Descent, Diagonal, LoneDrift, LoneTracks, Mirror, PbBands, Polar, Pooled,
                     Relaxation, SteadyR, Turn)


def circ_mean_deg(a) -> float:
    return float(np.degrees(GL.circular_mean(a)) % 360)


def lone_robots(singles: dict[float, LoneTracks]) -> dict[float, LoneDrift]:
    """Per amplitude: :func:`smarticle_mjx.reduce.transport.lone_robot` of its track; of several
    robots' tracks ([R, T+1, 2]: robots drawn with imperfections), each quantity's mean over robots."""
    out = {}
    for a, d in singles.items():
        xy, heading = np.asarray(d.xy), np.asarray(d.heading)
        cycles = xy.shape[-2] - 1
        if xy.ndim == 2:
            out[a] = LoneDrift(transport.lone_robot(xy, heading, d.period_s), 1, cycles)
            continue
        each = [transport.lone_robot(x, h, d.period_s) for x, h in zip(xy, heading)]
        mean = {k: float(np.mean([getattr(e, k) for e in each])) for k in each[0].as_json()}
        out[a] = LoneDrift(transport.LoneRobot(**mean), len(each), cycles)
    return out


def polar(path) -> Polar:
    """Attracted starts of the polar scan: their circular mean θ and the mirror symmetry about 270 deg
    (correlation of the attracted fraction per 10 deg bin of θ with that of the mirrored bin)."""
    sp_ = Store(path)
    d = sp_.run(sp_.runs[0], fields=("config", "valid", "touched"))
    lab = binding.labels(d["touched"][:, :, 0], d["valid"])
    th = d["config"][:, 1]
    att = lab == binding.ATTRACTED
    axis = circ_mean_deg(th[att]) if att.any() else float("nan")
    bins = np.linspace(0, TWO_PI, 37)
    idx = np.clip(np.digitize(th, bins) - 1, 0, 35)
    ok = lab != binding.INVALID
    frac = np.array([att[(idx == i) & ok].mean() if ((idx == i) & ok).any() else np.nan for i in range(36)])
    centres = (bins[:-1] + bins[1:]) / 2
    mirror = np.mod(2 * math.radians(270) - centres, TWO_PI)
    fm = frac[np.clip(np.digitize(mirror, bins) - 1, 0, 35)]
    good = np.isfinite(frac) & np.isfinite(fm)
    corr = float(np.corrcoef(frac[good], fm[good])[0, 1]) if good.sum() > 3 and np.std(frac[good]) > 0 \
        else float("nan")
    sc = sp_.config["scan"]
    return Polar(axis, corr, int(att.sum()), int(ok.sum()), int(sp_.run_attrs[sp_.runs[0]]["periods"]),
                 sc["positions"], sc["orientations"], sc["radius_W"],
                 (float(np.nanmin(frac)), float(np.nanmax(frac))))


def mirror(a90: analysis.RunAnalysis, acw: analysis.RunAnalysis) -> Mirror:
    """Mean signed body-heading turn per glider under each chirality (degrees per period, bootstrap
    intervals) and C1's mean θ counter-clockwise beside the mirrored (180 deg − θ) clockwise one."""
    def c1_theta(a):
        if a.types is None:
            return float("nan")
        s = a.types.samples[a.types.sample_kinds == GL.C1]
        return circ_mean_deg(s[:, 1]) if len(s) else float("nan")

    def turns(a) -> Turn:
        per_glider = a.transport.heading_turn_per_glider if a.transport is not None else np.zeros(0)
        return Turn(*transport.bootstrap_interval(np.degrees(per_glider)))

    return Mirror(turns(a90), turns(acw), c1_theta(a90), (180 - c1_theta(acw)) % 360, acw.valid, acw.periods,
                  acw.options.glider_min_periods)


def descent(paths: list, window: int, tolerance: float = 0.0) -> list[SteadyR]:
    """Steady |r| per amplitude of the started-bound stages (mean over the last ``window`` periods of
    pairs bound in all of them; with ``tolerance`` > 0, each pair read where it converged,
    ``reduce.gliders.converged_separation``), bootstrap interval over pairs, in increasing amplitude."""
    sep = []
    for path in paths:
        st = Store(path)
        d = st.run(st.runs[0], fields=("rel", "touched", "valid"))
        t = d["touched"][:, :, 0] & d["valid"][:, None]
        unconverged = 0
        if tolerance > 0:
            cs = GL.converged_separation(d["rel"].astype(float), t, window=window, tol=tolerance)
            per, unconverged = cs.per_pair, cs.unconverged
        else:
            per = GL.steady_separation(d["rel"].astype(float), t, window=min(window, t.shape[1])).per_pair
        m, lo, hi, n = transport.bootstrap_interval(per)
        sep.append((float(st.run_attrs[st.runs[0]]["amplitude_deg"]), m, lo, hi, n, int(d["valid"].sum()),
                    unconverged))
    sep.sort()
    return [SteadyR(*x) for x in sep]


def rebinding(path) -> list[Rebinding]:
    """Per amplitude run of a scan run with its early exit off (``quiet_periods = 0``): how often a pair
    that came apart bound again (:func:`smarticle_mjx.reduce.rebinding.rebinding`), in increasing amplitude.
    ValueError, one line, for a scan that retired lanes early (its partings are cut short)."""
    st = Store(path)
    if int(st.config["scan"].get("quiet_periods", 2)) != 0:
        raise ValueError(f"{path}: rebinding needs a scan with its early exit off (quiet_periods = 0)")
    out = []
    for run in st.runs:
        d = st.run(run, fields=("touched", "valid"))
        out.append(rebind.rebinding(d["touched"][:, :, 0], d["valid"], float(st.run_attrs[run]["amplitude_deg"])))
    return sorted(out, key=lambda r: r.amplitude_deg)


def pb(runs: list[analysis.RunAnalysis]) -> BindingVsAmplitude:
    """P_b at the end per amplitude and pooled over the claim's amplitude groups (exact intervals)."""
    amps = np.array([a.amplitude_deg for a in runs])
    n = np.array([a.binding.end.n for a in runs])
    k = np.array([int(round(a.binding.end.value * a.binding.end.n)) if a.binding.end.n else 0 for a in runs])
    pooled = []
    for sel in pb_groups(amps):
        kk, nn = int(k[sel].sum()), int(n[sel].sum())
        lo, hi = binding.binomial_interval(kk, nn)
        pooled.append(Pooled(kk / nn if nn else np.nan, float(lo), float(hi), nn))
    return BindingVsAmplitude(amps, np.array([[a.binding.end.value, a.binding.end.lo, a.binding.end.hi]
                                              for a in runs], float), n, PbBands(*pooled), runs[0].periods, tuple(runs))


def relax(paths: list, figures: pathlib.Path, made: list, reading=None) -> tuple[Relaxation, dict]:
    """The relaxation study over its complete stages, pooled: the claims' typed evidence, and the summary
    ``validation.json`` records (report.relax_summary with Fisher's exact p of its emergence against the
    lab's, every emergence reading and both chain readings); draws its two figures. ``reading``: the
    emergence reading the claims judge (reduce.emergence; None: the primary one)."""
    from ..reduce import chains as CH, emergence as EM, relaxation as RX, spreading as SP
    from ..report import lab_relax_fraction, relax_summary, trial_figure
    from ..specs import relax_config_from_json
    from ..store import read_relax
    data = read_relax(paths)
    ra, (crowd, crowd_trials) = RX.analyse_relaxation(data), RX.crowd(data)
    spreading = SP.study_spreading(data, crowd_trials)
    reading = EM.parse_reading(reading)
    em = EM.emergence(data)
    a = relax_summary(data, crowd=crowd, analysis=ra, reading=reading, emergence=em)
    a["emergence"] = em.as_json(with_runs=False)  # the page's numbers; a report of the stores keeps the runs
    chains = CH.study_chains(data)
    made += trial_figure(data, ra, figures)
    made += [p.name for p in plots.lifetime_contour(ra.episodes, ra.fit, ra.min_periods, figures)]
    p_fisher = em.of(EM.Reading.APART).fisher_p  # the bound-and-apart count's test against the lab's
    a = {**a, "p_fisher": p_fisher}
    fraction, interval = lab_relax_fraction()
    return Relaxation(ra, crowd, relax_config_from_json(data.settings), fraction, interval, p_fisher,
                      len(paths), em, chains, reading, spreading), a


class Context:
    """What the evidence builders share while one page is gathered: the stores, the lone robots' tracks,
    the study specs, the figures folder, the numbers written beside the page (``extra``), the figure
    files in page order (``made``) and each builder's result, computed once (:meth:`get`)."""

    def __init__(self, stores: dict, singles: dict, figures: pathlib.Path, specs: dict | None, reading=None):
        self.stores, self.singles, self.figures, self.specs = stores, singles, figures, specs or {}
        self.reading = reading  # the relaxation's emergence reading (reduce.emergence; None: the primary one)
        self.extra: dict = {}
        self.made: list[str] = []
        self._done: dict = {}

    def draw(self, paths) -> None:
        self.made += [p.name for p in paths if p.suffix == ".png"]

    def ready(self, name: str) -> bool:
        """The builder's studies are there (all of them, or any with ``any_study``)."""
        b = BUILDERS[name]
        have = [s in self.stores and self.stores[s] for s in b.studies]
        return (any(have) if b.any_study else all(have)) if b.studies else bool(self.singles)

    def built(self, name: str):
        """The evidence ``name`` if a claim has already asked for it and its studies were there, else None
        (for what is drawn after the claims: it never builds)."""
        return self._done.get(name)

    def get(self, name: str):
        """The evidence ``name`` builds (None when its studies are missing), built once."""
        if name not in self._done:
            self._done[name] = BUILDERS[name].build(self) if self.ready(name) else None
        return self._done[name]


@dataclasses.dataclass(frozen=True)
class Builder:
    """One kind of evidence: the studies it reads (all needed, or any with ``any_study``; none: the lone
    robots) and the function that builds it from a :class:`Context`."""

    studies: tuple[str, ...]
    build: Callable[[Context], Any]
    any_study: bool = False


BUILDERS: dict[str, Builder] = {}


def builds(name: str, studies: tuple[str, ...] = (), any_study: bool = False):
    """Register the decorated function as the builder of evidence ``name`` (claims name it:
    ``claims.claim(..., evidence=name)``)."""
    def deco(fn):
        BUILDERS[name] = Builder(tuple(studies), fn, any_study)
        return fn
    return deco


@builds("lone_robots")
def _lone(ctx: Context) -> LoneDrift:
    sing = lone_robots(ctx.singles)
    ctx.extra["single"] = {a: v.as_json() for a, v in sing.items()}
    ctx.extra["single_periods"] = sing[next(iter(sing))].cycles
    amps = sorted(sing)
    ctx.draw(plots.versus_amplitude(
        amps, {"net drift (W/cycle)": ([sing[a].robot.net_W_per_cycle for a in amps], None),
               r"$\beta_{single}$": ([sing[a].robot.beta for a in amps], [sing[a].robot.beta_err for a in amps]),
               "heading drift (deg/cycle)": ([sing[a].robot.heading_deg_per_cycle for a in amps], None)},
        ctx.figures, "single_robot"))
    return sing[90.0]


@builds("random_90", ("random_90",))
def _random_90(ctx: Context) -> analysis.RunAnalysis:
    path = ctx.stores["random_90"]
    st = Store(path)
    a90 = analyse_store_run(st, st.runs[0])
    ctx.extra["random_90"] = a90.summary()
    if a90.types is not None:
        ty = a90.types
        ctx.draw(plots.relative_coordinates(ty.samples, ty.sample_kinds, ty.clusters, ctx.figures, "relcoords_90",
                                            title=f"random scan, 90°, bound periods ≥ {a90.options.burn_in}"))
        ctx.draw(plots.lifetimes(ty.typed, a90.periods, ctx.figures, "lifetimes_90", title="random scan, 90°"))
    ctx.draw(plots.phase_diagram(path, ctx.figures, st.runs[0], formats=("png",), stem="phase_diagram_random_90"))
    if a90.transport is not None:
        tr = a90.transport.tracks[:12]
        ctx.draw(plots.tracks([t[np.isfinite(t).all(-1)] for t in tr], [f"glider {i}" for i in range(len(tr))],
                              ctx.figures, "gliders_90", title="glider tracks, 90° (first 12)"))
    return a90


@builds("polar", ("polar",))
def _polar(ctx: Context) -> Polar:
    ev = polar(ctx.stores["polar"])
    ctx.extra["polar"] = ev.as_json()
    ctx.draw(plots.phase_diagram(ctx.stores["polar"], ctx.figures, Store(ctx.stores["polar"]).runs[0],
                                 formats=("png",), stem="phase_diagram_polar_1p3"))
    return ev


@builds("diagonal", ("diagonal_90", "diagonal_random"), any_study=True)
def _diagonal(ctx: Context) -> Diagonal:
    parts, tracks, lags, runs = [], [], None, {}
    for name, what in (("diagonal_90", "started-bound C1 gliders"), ("diagonal_random", "random starts")):
        if not ctx.stores.get(name):
            continue
        path = ctx.stores[name][0] if isinstance(ctx.stores[name], list) else ctx.stores[name]
        sd = Store(path)
        a = analyse_store_run(sd, sd.runs[0])
        runs[name] = a
        ctx.extra[name] = a.summary()
        lags = a.options.fit_lags
        parts.append(f"{a.transport.gliders if a.transport else 0} of {a.valid} {what} bound ≥ "
                     f"{a.options.glider_min_periods} periods")
        if a.transport is not None:
            tracks.append(a.transport.tracks)
    bd = None
    if tracks:
        L = max(t.shape[1] for t in tracks)
        allt = np.concatenate([np.pad(t, ((0, 0), (0, L - t.shape[1]), (0, 0)), constant_values=np.nan)
                               for t in tracks])
        bd = transport.msd_exponent(allt, lag_range=tuple(lags)) if len(allt) else None
    return Diagonal(bd, lags, tuple(parts), runs)


@builds("mirror", ("cw_90", "random_90"))
def _mirror(ctx: Context) -> Mirror:
    sc = Store(ctx.stores["cw_90"])
    ev = mirror(ctx.get("random_90"), analyse_store_run(sc, sc.runs[0]))
    cw, ccw = sc.config.get("imperfections"), Store(ctx.stores["random_90"]).config.get("imperfections")
    if cw is not None:  # drawn robots: which, and whether the counter-clockwise study ran the same ones
        ev = dataclasses.replace(ev, robot_pairs=int(cw.get("pairs", 1)), same_robots=cw == ccw)
    ctx.extra["mirror"] = ev.as_json()
    return ev


@builds("descent", ("descent",))
def _descent(ctx: Context) -> Descent:
    spec = ctx.specs.get("descent")
    win = spec.steady_window if spec is not None else 10
    tol = spec.converge_tol if spec is not None else 0.0
    sep = descent(ctx.stores["descent"], win, tol)
    ctx.extra["descent"] = [dataclasses.asdict(x) for x in sep]
    ev = Descent(tuple(sep), win, Store(ctx.stores["descent"][0]).config["scan"]["periods"],
                 bool(spec is not None and spec.continuation), tol)
    if sep:
        label = "steady |r| (W), started bound"
        drop = ev.largest_drop
        ctx.draw(plots.versus_amplitude(
            [x.amplitude_deg for x in sep],
            {label: ([x.r_W for x in sep], [(x.r_W - x.lo, x.hi - x.r_W) for x in sep])},
            ctx.figures, "steady_separation", marks=None if drop is None else {label: (*drop, "largest drop")}))
    return ev


@builds("amplitude", ("amplitude",))
def _amplitude(ctx: Context) -> BindingVsAmplitude:
    sa = Store(ctx.stores["amplitude"])
    runs = [analyse_store_run(sa, r) for r in sa.runs]
    ctx.extra["amplitude"] = [a.summary() for a in runs]
    ev = pb(runs)
    ctx.extra["pb_pooled"] = ev.pooled_json()
    amps = [a.amplitude_deg for a in runs]  # figures from the unrounded numbers (until November 2026: the rounded rows)
    ctx.draw(plots.pb_curve(amps, *pb_rows(runs), ctx.figures))
    ctx.draw(plots.versus_amplitude(amps, amplitude_panels(runs), ctx.figures, "vs_amplitude"))
    return ev


@builds("relax", ("relax",))
def _relax(ctx: Context) -> Relaxation:
    ev, a = relax(ctx.stores["relax"], ctx.figures, ctx.made, ctx.reading)
    ctx.extra["relax"] = {k: v for k, v in a.items() if k not in ("episodes", "per_trial")}
    return ev


@builds("rebinding", ("rebind",))
def _rebinding(ctx: Context) -> list[Rebinding]:
    rows = rebinding(ctx.stores["rebind"])
    ctx.extra["rebinding"] = [r.as_json() for r in rows]
    ctx.draw(plots.versus_amplitude(
        [r.amplitude_deg for r in rows],
        {"rebound / parted": ([r.rate for r in rows], [(r.rate - r.lo, r.hi - r.rate) for r in rows]),
         "parted / valid": ([r.parted / r.valid if r.valid else np.nan for r in rows], None)},
        ctx.figures, "rebinding"))
    return rows


def _msd_figure(ctx: Context) -> None:
    """Every MSD curve the page has, in one figure, after the builders that measure them."""
    curves = {}
    a90 = ctx.built("random_90")
    diag = ctx.built("diagonal")
    adiag = diag.runs.get("diagonal_90") if diag is not None else None
    for label, a in (("90° square", a90), ("90° diagonal, started bound", adiag)):
        if a is not None and a.transport is not None:
            curves[label] = (a.transport.msd_lags, a.transport.msd)
    amp = ctx.built("amplitude")
    for a in (amp.runs if amp is not None else ()):
        if a.amplitude_deg in (10, 50, 90) and a.transport is not None:
            curves[f"{a.amplitude_deg:g}° (sweep)"] = (a.transport.msd_lags, a.transport.msd)
    if curves:
        ctx.draw(plots.msd_curves(curves, ctx.figures))


def gather(stores: dict, singles: dict, figures: pathlib.Path, specs: dict | None = None, reading=None,
           claims=None):
    """Evidence for every claim from the stores there are; figures drawn into ``figures``.

    Each claim names the evidence it needs (``claims.Claim.evidence``, a builder of :data:`BUILDERS`);
    each builder runs once, in the order of the first claim that needs it, when its studies are there.

    Args:
      stores: study name -> store path (scans) or list of stage store paths (started-bound and
        relaxation studies); a study not yet run is absent.
      singles: lone robots' tracks (:func:`smarticle_mjx.validate.single_robots`).
      specs: study name -> its spec (the started-bound studies' windows).
      reading: the relaxation's emergence reading the claims judge (None: the primary one).
      claims: the claims gathered for (None: every claim).

    Returns:
      (claim key -> its evidence, None where a study is missing; the numbers written beside the page;
      the figure files in page order).
    """
    figures.mkdir(parents=True, exist_ok=True)
    ctx = Context(stores, singles, figures, specs, reading)
    ev = {c.key: ctx.get(c.evidence) for c in (CLAIMS if claims is None else claims)}
    if "rebind" in stores:  # a measure beside the claims (the paper suite): the page prints its table
        ctx.get("rebinding")
    _msd_figure(ctx)
    return ev, ctx.extra, ctx.made
