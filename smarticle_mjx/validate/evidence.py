"""Evidence for the claims: the numbers each claim of :mod:`.claims` tests, read from the studies' stores
(and the lone robots' tracks), with the page's figures drawn on the way.

:func:`gather` returns ``(evidence, extra, figures)``: claim key -> its evidence (None where a study is
missing), the numbers written beside the page (``validation.json``), the figure files in page order.
"""

from __future__ import annotations

import math
import pathlib

import numpy as np

from .. import plots
from ..configs import TWO_PI
from ..reduce import binding, gliders as GL, transport
from ..reduce import analysis
from ..report import amplitude_panels, analyse_store_run, round_for_report
from ..store import Store
from .claims import pb_groups


def circ_mean_deg(a) -> float:
    return float(np.degrees(GL.circular_mean(a)) % 360)


def lone_robots(singles: dict) -> dict:
    """Per amplitude: :func:`smarticle_mjx.reduce.transport.lone_robot` of its track; of several
    robots' tracks ([R, T+1, 2]: robots drawn with imperfections), each quantity's mean over robots."""
    out = {}
    for a, d in singles.items():
        xy, heading = np.asarray(d["xy"]), np.asarray(d["heading"])
        if xy.ndim == 2:
            out[a] = transport.lone_robot(xy, heading, d["period_s"])
            continue
        each = [transport.lone_robot(x, h, d["period_s"]) for x, h in zip(xy, heading)]
        out[a] = {k: float(np.mean([e[k] for e in each])) for k in each[0]}
        out[a]["robots"] = len(each)
    return out


def polar(path) -> dict:
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
    return {"axis_deg": axis, "mirror_correlation": corr, "attracted": int(att.sum()), "valid": int(ok.sum()),
            "periods": int(sp_.run_attrs[sp_.runs[0]]["periods"]), "positions": sc["positions"],
            "orientations": sc["orientations"], "radius_W": sc["radius_W"],
            "fraction_range": (float(np.nanmin(frac)), float(np.nanmax(frac)))}


def mirror(a90: analysis.RunAnalysis, acw: analysis.RunAnalysis) -> dict:
    """Mean signed body-heading turn per glider under each chirality (degrees per period, bootstrap
    intervals) and C1's mean θ counter-clockwise beside the mirrored (180 deg − θ) clockwise one."""
    def c1_theta(a):
        if a.types is None:
            return float("nan")
        s = a.types.samples[a.types.sample_kinds == GL.C1]
        return circ_mean_deg(s[:, 1]) if len(s) else float("nan")

    def turns(a):
        per_glider = a.transport.heading_turn_per_glider if a.transport is not None else np.zeros(0)
        return transport.bootstrap_interval(np.degrees(per_glider))

    return {"ccw": turns(a90), "cw": turns(acw), "c1_theta_ccw": c1_theta(a90),
            "c1_theta_cw_mirrored": (180 - c1_theta(acw)) % 360,
            "cw_summary": {"valid": acw.valid, "periods": acw.periods,
                           "options": {"glider_min_periods": acw.options.glider_min_periods}}}


def descent(paths: list, window: int) -> list[dict]:
    """Steady |r| per amplitude of the started-bound stages (mean over the last ``window`` periods of
    pairs bound in all of them, bootstrap interval over pairs), in increasing amplitude."""
    sep = []
    for path in paths:
        st = Store(path)
        d = st.run(st.runs[0], fields=("rel", "touched", "valid"))
        t = d["touched"][:, :, 0] & d["valid"][:, None]
        ss = GL.steady_separation(d["rel"].astype(float), t, window=min(window, t.shape[1]))
        m, lo, hi, n = transport.bootstrap_interval(ss["per_pair"])
        sep.append((float(st.run_attrs[st.runs[0]]["amplitude_deg"]), m, lo, hi, n, int(d["valid"].sum())))
    sep.sort()
    return [dict(zip(("amplitude_deg", "r_W", "lo", "hi", "pairs", "started"), x)) for x in sep]


def pb(runs: list[analysis.RunAnalysis]) -> dict:
    """P_b at the end per amplitude and pooled over the claim's amplitude groups (exact intervals)."""
    amps = np.array([a.amplitude_deg for a in runs])
    n = np.array([a.binding.end.n for a in runs])
    k = np.array([int(round(a.binding.end.value * a.binding.end.n)) if a.binding.end.n else 0 for a in runs])
    pooled = {}
    for g, sel in pb_groups(amps).items():
        kk, nn = int(k[sel].sum()), int(n[sel].sum())
        lo, hi = binding.binomial_interval(kk, nn)
        pooled[g] = (kk / nn if nn else np.nan, float(lo), float(hi), nn)
    return {"amplitudes_deg": amps,
            "pb_end": [[a.binding.end.value, a.binding.end.lo, a.binding.end.hi] for a in runs], "valid": n,
            "pooled": pooled, "periods": runs[0].periods}


def relax(paths: list, figures: pathlib.Path, made: list) -> dict:
    """The relaxation study's summary over its complete stages, pooled (report.relax_summary), with
    Fisher's exact test of its emergence against the lab's; draws its two figures."""
    from scipy.stats import fisher_exact
    from ..report import relax_summary, trial_figure
    from ..store import read_relax
    data = read_relax(paths)
    a = relax_summary(data)
    made += trial_figure(data, a, figures)
    made += [p.name for p in plots.lifetime_contour(a["episodes"], a["fit"], a["min_periods"], figures)]
    k, n, lab = a["emerged"], a["valid"], a["lab"]
    a["p_fisher"] = float(fisher_exact([[k, n - k], [lab["emerged"], lab["trials"] - lab["emerged"]]])[1]) \
        if n else float("nan")
    return a


def gather(stores: dict, singles: dict, figures: pathlib.Path, specs: dict | None = None):
    """Evidence for every claim from the stores there are; figures drawn into ``figures``.

    Args:
      stores: study name -> store path (scans) or list of stage store paths (started-bound and
        relaxation studies); a study not yet run is absent.
      singles: lone robots' tracks (:func:`smarticle_mjx.validate.single_robots`).
      specs: study name -> its spec (the started-bound studies' windows).
    """
    ev, extra, made = {}, {}, []
    figures.mkdir(parents=True, exist_ok=True)
    fig = lambda paths: [p.name for p in paths if p.suffix == ".png"]  # noqa: E731

    sing = lone_robots(singles)
    extra["single"] = sing
    extra["single_periods"] = np.shape(next(iter(singles.values()))["xy"])[-2] - 1  # [(R,) T+1, 2]
    ev["lone_drift"] = {**sing[90.0], "cycles": extra["single_periods"]}
    amps = sorted(sing)
    made += fig(plots.versus_amplitude(
        amps, {"net drift (W/cycle)": ([sing[a]["net_W_per_cycle"] for a in amps], None),
               r"$\beta_{single}$": ([sing[a]["beta"] for a in amps], [sing[a]["beta_err"] for a in amps]),
               "heading drift (deg/cycle)": ([sing[a]["heading_deg_per_cycle"] for a in amps], None)},
        figures, "single_robot"))

    a90 = None
    if "random_90" in stores:
        st = Store(stores["random_90"])
        a90 = analyse_store_run(st, st.runs[0])
        for key in ("both_types", "c1_basin", "c1_lifetime", "beta"):
            ev[key] = a90
        extra["random_90"] = a90.summary()
        if a90.types is not None:
            ty = a90.types
            made += fig(plots.relative_coordinates(ty.samples, ty.sample_kinds, ty.clusters, figures,
                                                   "relcoords_90", title="random scan, 90°, bound periods ≥ "
                                                   f"{a90.options.burn_in}"))
            made += fig(plots.lifetimes(ty.typed, a90.periods, figures, "lifetimes_90", title="random scan, 90°"))
        made += fig(plots.phase_diagram(stores["random_90"], figures, st.runs[0], formats=("png",),
                                        stem="phase_diagram_random_90"))
        if a90.transport is not None:
            tr = a90.transport.tracks[:12]
            made += fig(plots.tracks([t[np.isfinite(t).all(-1)] for t in tr], [f"glider {i}" for i in range(len(tr))],
                                     figures, "gliders_90", title="glider tracks, 90° (first 12)"))

    if "polar" in stores:
        ev["polar_symmetry"] = polar(stores["polar"])
        extra["polar"] = {k: ev["polar_symmetry"][k] for k in ("axis_deg", "mirror_correlation", "attracted", "valid",
                                                               "periods")}
        made += fig(plots.phase_diagram(stores["polar"], figures, Store(stores["polar"]).runs[0], formats=("png",),
                                        stem="phase_diagram_polar_1p3"))

    adiag = None
    if "diagonal_90" in stores or "diagonal_random" in stores:
        parts, tracks, lags = [], [], None
        for name, what in (("diagonal_90", "started-bound C1 gliders"), ("diagonal_random", "random starts")):
            if name not in stores:
                continue
            path = stores[name][0] if isinstance(stores[name], list) else stores[name]
            sd = Store(path)
            a = analyse_store_run(sd, sd.runs[0])
            extra[name] = a.summary()
            lags = a.options.fit_lags
            parts.append(f"{a.transport.gliders if a.transport else 0} of {a.valid} {what} bound ≥ "
                         f"{a.options.glider_min_periods} periods")
            if a.transport is not None:
                tracks.append(a.transport.tracks)
            if name == "diagonal_90":
                adiag = a
        bd = None
        if tracks:
            L = max(t.shape[1] for t in tracks)
            allt = np.concatenate([np.pad(t, ((0, 0), (0, L - t.shape[1]), (0, 0)), constant_values=np.nan)
                                   for t in tracks])
            bd = transport.msd_exponent(allt, lag_range=tuple(lags)) if len(allt) else None
        ev["diagonal_beta"] = {"beta": bd, "lags": lags, "parts": parts}

    if "cw_90" in stores and a90 is not None:
        sc = Store(stores["cw_90"])
        ev["mirror"] = extra["mirror"] = mirror(a90, analyse_store_run(sc, sc.runs[0]))

    if "descent" in stores:
        spec = (specs or {}).get("descent")
        win = spec.steady_window if spec is not None else 10
        sep = descent(stores["descent"], win)
        extra["descent"] = sep
        ev["descent"] = {"sep": sep, "window": win, "periods": Store(stores["descent"][0]).config["scan"]["periods"],
                         "continuation": bool(spec is not None and spec.continuation)}
        if sep:
            made += fig(plots.versus_amplitude(
                [x["amplitude_deg"] for x in sep],
                {"steady |r| (W), started bound": ([x["r_W"] for x in sep],
                                                   [(x["r_W"] - x["lo"], x["hi"] - x["r_W"]) for x in sep])},
                figures, "steady_separation"))

    amp_runs = []
    if "amplitude" in stores:
        sa = Store(stores["amplitude"])
        amp_runs = [analyse_store_run(sa, r) for r in sa.runs]
        extra["amplitude"] = [a.summary() for a in amp_runs]
        ev["pb_dip"] = pb(amp_runs)
        extra["pb_pooled"] = ev["pb_dip"]["pooled"]
        sums = [a.summary(round_for_report) for a in amp_runs]
        amps = [a.amplitude_deg for a in amp_runs]
        made += fig(plots.pb_curve(amps, [s_["pb_end"] for s_ in sums], [s_["pb_throughout"] for s_ in sums],
                                   figures))
        made += fig(plots.versus_amplitude(amps, amplitude_panels(sums), figures, "vs_amplitude"))

    if stores.get("relax"):
        a = relax(stores["relax"], figures, made)
        extra["relax"] = {k: v for k, v in a.items() if k not in ("episodes", "per_trial")}
        ev["relax_emergence"] = ev["relax_distance"] = ev["contour"] = {**a, "stages": len(stores["relax"])}

    curves = {}
    for label, a in (("90° square", a90), ("90° diagonal, started bound", adiag)):
        if a is not None and a.transport is not None:
            curves[label] = (a.transport.msd_lags, a.transport.msd)
    for a in amp_runs:
        if a.amplitude_deg in (10, 50, 90) and a.transport is not None:
            curves[f"{a.amplitude_deg:g}° (sweep)"] = (a.transport.msd_lags, a.transport.msd)
    if curves:
        made += fig(plots.msd_curves(curves, figures))
    return ev, extra, made
