"""One report from a scan or sweep store: every reducer, every figure, one table.

``analyse_run`` turns one run (one amplitude) into numbers; ``write_report``
does it for every run of a store and writes ``report.md``, ``report.json``
and the figures into a folder. numpy/h5py/scipy/matplotlib only.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib

import numpy as np

from . import formatting, plots, presets, specs
from .reduce import analysis, binding, stepcheck
from .records import RelaxRecord
from .scene import SceneParams
from .store import Store


@dataclasses.dataclass(frozen=True)
class ReportOptions:
    """How the reducers cut the data (periods unless stated).

    Attributes:
      burn_in: periods skipped before per-period samples count as steady
        state (default: a third of the trial, at most 30 as in the paper).
      glider_min_periods: a glider track is a bound run at least this long
        (paper: > 30 cycles; default: min(30, K // 2)).
      steady_window: last periods over which steady |r| is averaged.
      fit_lags: MSD delays fitted for beta (default: the paper's long delays,
        5 .. 15 periods, shortened for short glider tracks to half their
        minimum length).
      clusters: k-means clusters of (|r|, theta, phi). More than the
        attractor's lobes: with 4, the C1 glider's four lobes took every
        centre and a 1.6 % C2 minority got none (1000-start scan at 90 deg).
    """

    burn_in: int | None = None
    glider_min_periods: int | None = None
    steady_window: int | None = None
    fit_lags: tuple[int, int] | None = None
    clusters: int = 8

    def resolve(self, k: int) -> "ReportOptions":
        o = self.options(k)
        return dataclasses.replace(self, burn_in=o.burn_in, glider_min_periods=o.glider_min_periods,
                                   steady_window=o.steady_window, fit_lags=o.fit_lags)

    def options(self, k: int) -> analysis.Options:
        """The reducers' options for a run of ``k`` periods (``reduce.analysis.Options.for_periods``)."""
        return analysis.Options.for_periods(k, self.burn_in, self.glider_min_periods, self.steady_window,
                                            self.fit_lags, self.clusters)


def round_for_report(x, nd=4):
    """How report.json and the report's tables round a number (None for a missing or non-finite one)."""
    return None if x is None or not np.isfinite(x) else round(float(x), nd)


def analyse_store_run(store: Store, run: str, opts: ReportOptions = ReportOptions()) -> analysis.RunAnalysis:
    """The typed, unrounded measures of one run (``reduce.analysis.RunAnalysis``), with the store's step
    check (``RunAnalysis.step``) beside its transport numbers."""
    a = store.analysis_arrays(run)
    res = analysis.analyse(a["touched"], a["valid"], a["rel"], a["com_xy"], a["heading"], a["status"],
                           opts.options(a["periods"]), run=run, amplitude_deg=a["amplitude_deg"],
                           chirality=a["chirality"], gait=a["gait"], period_s=a["period_s"])
    return dataclasses.replace(res, step=store_step_check(store))


def analyse_run(store: Store, run: str, opts: ReportOptions = ReportOptions()) -> dict:
    """Numbers and per-period arrays of one run, as the report prints and draws them.

    Returns:
      ``summary`` (JSON-ready numbers, rounded as report.json prints them) and ``arrays`` (for the
      figures); the typed, unrounded result is :func:`analyse_store_run`'s.
    """
    res = analyse_store_run(store, run, opts)
    return {"summary": res.summary(round_for_report), "arrays": res.arrays()}


def write_report(store_path, out_dir, opts: ReportOptions = ReportOptions()) -> dict:
    """All figures and the summary table of a store into ``out_dir``.

    Returns:
      the report as written to ``report.json``.
    """
    st = Store(store_path)
    if st.kind == "relax":
        return write_relax_report(store_path, out_dir, min_periods=opts.glider_min_periods or 100)
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figs: dict[str, list[str]] = {}
    results, typed = {}, []
    for run in st.runs:
        res = analyse_store_run(st, run, opts)
        typed.append(res)
        a = results[run] = {"summary": res.summary(round_for_report), "arrays": res.arrays()}
        s, arr = a["summary"], a["arrays"]
        names = [p.name for p in plots.phase_diagram(store_path, out, run)]
        if "clusters" in arr:
            names += [p.name for p in plots.relative_coordinates(
                arr["samples"], arr["sample_kinds"], arr["clusters"], out, f"relcoords_{run}",
                title=f"bound pairs, periods >= {s['options']['burn_in']}, α_max = {s['amplitude_deg']:g}°")]
            names += [p.name for p in plots.lifetimes(arr["typed"], s["periods"], out, f"lifetimes_{run}",
                                                     title=f"α_max = {s['amplitude_deg']:g}°")]
        if "coll_steps" in st.run_fields[run]:
            names += _collision_figure(st, run, out, s)
        if "tracks" in arr:
            tr = arr["tracks"][:8]
            names += [p.name for p in plots.tracks([t[np.isfinite(t).all(-1)] for t in tr],
                                                   [f"glider {i}" for i in range(len(tr))], out, f"gliders_{run}",
                                                   title=f"glider tracks, α_max = {s['amplitude_deg']:g}°")]
        figs[run] = names
    summaries = [results[r]["summary"] for r in st.runs]
    curves = {f"{s['amplitude_deg']:g}° ({s['gliders']} gliders)": results[s["run"]]["arrays"]["msd"]
              for s in summaries if "msd" in results[s["run"]]["arrays"]}
    common = []
    if curves:
        common += [p.name for p in plots.msd_curves(curves, out)]
    if len(summaries) > 1:
        # drawn from the unrounded numbers; report.json prints them rounded
        amps = [a.amplitude_deg for a in typed]
        common += [p.name for p in plots.pb_curve(amps, *pb_rows(typed), out)]
        common += [p.name for p in plots.versus_amplitude(amps, amplitude_panels(typed), out)]
    report = {"store": str(store_path), "model": st.model, **({"overrides": st.overrides} if st.overrides else {}),
              "versions": {k: st.attrs.get(k) for k in ("package", "mujoco", "jax")},
              "scan": st.config["scan"], "step_check": store_step_check(st).as_dict(), "runs": summaries,
              "figures": {"runs": figs, "common": common}}
    (out / "report.json").write_text(json.dumps(report, indent=1, default=json_default))
    (out / "report.md").write_text(markdown(report))
    return report


def store_step_check(st: Store) -> stepcheck.StepCheck:
    """Whether the store's (model, imperfections, step, integrator) passed the glider-quantity check
    (reduce.stepcheck; "not checked" where nobody measured it)."""
    spec = st.config.get("scan") or st.config.get("relax") or {}
    scene = st.config.get("scene") or {}
    integrator = stepcheck.numerics(scene.get("integrator", SceneParams.integrator),
                                    scene.get("contact_substeps", 1), scene.get("substep_gate"))
    return stepcheck.lookup(st.model, spec.get("imperfections", "none"), float(scene.get("timestep", float("nan"))),
                            integrator, st.overrides, spec.get("backend", "native"))


def step_note(c: dict) -> str:
    """One cell: what the store's step does to its transport numbers (rounded here, for the page)."""
    step = f"{c['timestep_s'] * 1e3:g} ms {c['integrator']}"
    if c["status"] == stepcheck.PASSED:
        return f"{step}: checked, passed"
    if c["status"] == stepcheck.NOT_CHECKED:
        return f"{step}: step not checked ({c['why']})"
    b = c["beta"]
    return (f"{step}: biased against {c['reference_dt_s'] * 1e3:g} ms, β {b['value']:+.2f} "
            f"[{b['ci95'][0]:+.2f}, {b['ci95'][1]:+.2f}], net speed {c['net_speed']['relative']:+.0%}")


def _collision_figure(st: Store, run: str, out: pathlib.Path, s: dict) -> list[str]:
    """The collision sequence of the longest-bound lane over its last two bound periods."""
    d = st.run(run, fields=("touched", "lifetime", "coll_steps", "coll_impulse", "coll_impulse_r"))
    lane = int(np.argmax(d["lifetime"]))
    bound = np.flatnonzero(d["touched"][lane, :, 0])
    if len(bound) == 0:
        return []
    periods = bound[-2:] if len(bound) > 1 else bound[-1:]
    coll = {"steps": d["coll_steps"], "impulse": d["coll_impulse"], "impulse_r": d["coll_impulse_r"]}
    return [p.name for p in plots.collision_sequence(
        coll, lane, periods, out, f"collisions_{run}",
        title=f"configuration {lane} (bound {int(d['lifetime'][lane])} periods), α_max = {s['amplitude_deg']:g}°")]


def pb_by_amplitude(path) -> list[tuple[float, binding.BindingProbability]]:
    """(amplitude, :func:`smarticle_mjx.reduce.binding.binding_probability`) of every run of a sweep
    store, in the store's run order: P_b at the end and throughout with 95 % exact intervals."""
    st = Store(path)
    rows = []
    for run in st.runs:
        d = st.run(run, fields=("valid", "touched"))
        rows.append((st.run_attrs[run]["amplitude_deg"], binding.binding_probability(d["touched"][:, :, 0], d["valid"])))
    return rows


def pb_table(store_path, out_dir) -> tuple[list[str], list]:
    """P_b(alpha_max) of a sweep store as a printed table and its figure in ``out_dir`` (``smx pb``)."""
    out = pathlib.Path(out_dir)
    plots.check_out_dir(out)
    rows = pb_by_amplitude(store_path)
    lines = [f"{'alpha_max':>9}  {'valid':>6}  {'P_b end [95% CI]':>24}  {'P_b throughout [95% CI]':>24}"]
    for a, p in rows:
        e, t = p.end, p.throughout
        lines.append(f"{a:>9g}  {p.n:>6}  {e.value:.3f} [{e.lo:.3f}, {e.hi:.3f}]".ljust(44)
                     + f"  {t.value:.3f} [{t.lo:.3f}, {t.hi:.3f}]")
    written = plots.pb_curve([a for a, _ in rows], [(p.end.value, p.end.lo, p.end.hi) for _, p in rows],
                             [(p.throughout.value, p.throughout.lo, p.throughout.hi) for _, p in rows], out)
    return lines, written


def amplitude_panels(runs: list[analysis.RunAnalysis]) -> dict:
    """beta, V_com and steady |r| of typed runs (unrounded), as ``plots.versus_amplitude`` panels (NaN where
    a run has no glider)."""
    nan = float("nan")
    beta = [(a.transport.beta.beta, a.transport.beta.err) if a.transport is not None else (nan, nan) for a in runs]
    v = [(a.transport.net_speed.value, a.transport.net_speed.lo, a.transport.net_speed.hi)
         if a.transport is not None else (nan, nan, nan) for a in runs]
    return {
        r"$\beta$ (gliders)": ([b for b, _ in beta], [e for _, e in beta]),
        r"$V_{com}$, net (W/period)": ([x for x, _, _ in v], [(x - lo, hi - x) for x, lo, hi in v]),
        "steady |r| (W)": ([a.separation.mean for a in runs], [a.separation.std for a in runs]),
    }


def pb_rows(runs: list[analysis.RunAnalysis]) -> tuple[list, list]:
    """P_b rows (p, lo, hi) bound at the end and bound throughout, unrounded, for ``plots.pb_curve``."""
    return ([(a.binding.end.value, a.binding.end.lo, a.binding.end.hi) for a in runs],
            [(a.binding.throughout.value, a.binding.throughout.lo, a.binding.throughout.hi) for a in runs])


def describe_configs(sc: dict, wrap: str = "{}") -> str:
    """How a scan chose its initial configurations, in words."""
    if sc["configs"] == "random":
        what = f"random, |r| in {sc['r_range_W']} W"
    elif sc["configs"] == "polar":
        what = f"|r| = {sc['radius_W']} W, {sc['positions']} × {sc['orientations']}"
    else:
        what = f"{len(sc.get('initial') or [])} explicit starts"
    return wrap.format(what)


def json_default(x):
    """``json.dumps`` default for numpy scalars and arrays."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(type(x))


def _fmt(x, nd=3):
    return formatting.num(x, f".{nd}f")


def _ci(v, lo, hi, nd=3):
    return formatting.DASH if v is None else formatting.ci(v, lo, hi, f".{nd}f")


def _pm(v, e, nd=3):
    return formatting.DASH if v is None else formatting.pm(v, e, f".{nd}f")


def markdown(report: dict) -> str:
    """The summary table and figure links of a report."""
    sc = report["scan"]
    lines = [f"# Report: `{pathlib.Path(report['store']).name}`", "",
             f"{report['runs'][0]['configs'] if report['runs'] else 0} configurations"
             + describe_configs(sc, " ({})")
             + f", {sc['periods']} periods, gait {sc['gait']} {sc['chirality']}, model {presets.describe(report.get('model'), report.get('overrides'))}, "
             f"backend {sc['backend']}; "
             f"written by {report['versions'].get('package')}, mujoco {report['versions'].get('mujoco')}.", "",
             "| α_max | valid | P_b end [95% CI] | P_b throughout [95% CI] | C1 basin | C2 basin | "
             "C1 lifetime (mean, censored) | C2 lifetime | gliders | β [95% CI] | V_com net (W/period) [95% CI] | "
             "mean step (W/period) | median turn (°/period) | persistence | steady \\|r\\| (W) | step check |",
             "|" + "---|" * 16]
    for s in report["runs"]:
        def ci(p):
            return "–" if p[0] is None else f"{p[0]:.3f} [{p[1]:.3f}, {p[2]:.3f}]"

        c1, c2 = s.get("C1") or {}, s.get("C2") or {}

        def life(c):
            return "–" if not c.get("runs") else f"{c['lifetime_mean']:.1f} ({c['censored_fraction']:.0%})"

        b, v, tu = s.get("beta") or {}, s.get("v_com") or {}, s.get("turning") or {}
        lines.append(
            f"| {s['amplitude_deg']:g}° | {s['valid']}/{s['configs']} | {ci(s['pb_end'])} | {ci(s['pb_throughout'])} | "
            f"{_fmt(c1.get('basin_fraction'))} | {_fmt(c2.get('basin_fraction'))} | {life(c1)} | {life(c2)} | "
            f"{s['gliders']} | {_ci(b.get('value'), b.get('lo'), b.get('hi'), 2)} | "
            f"{_ci(v.get('net_W_per_period'), v.get('net_lo'), v.get('net_hi'), 4)} | "
            f"{_fmt(v.get('mean_step_W_per_period'), 4)} | {_fmt(tu.get('median_direction_change_deg'), 1)} | "
            f"{_fmt(tu.get('direction_persistence'), 2)} | "
            f"{_pm(s['steady_r']['mean_W'], s['steady_r']['std_W'], 2)} ({s['steady_r']['pairs']}) | "
            f"{step_note(report['step_check']) if report.get('step_check') and s['gliders'] else '–'} |")
    o = report["runs"][0]["options"] if report["runs"] else {}
    lines += ["", "Definitions: bound in a period = the robots touched in it; basin = fraction of valid starts that "
              "end as that glider (bound in each of the last 10 periods, majority type); C1/C2 = k-means clusters "
              f"({o.get('clusters')}) of per-period (|r|, θ, φ) of bound pairs after period {o.get('burn_in')}, named "
              "by their mean φ (C1 anti-aligned); lifetime = length of a bound run, typed by its majority (censored = "
              f"still bound at the end); gliders = bound runs ≥ {o.get('glider_min_periods')} periods; β = slope of "
              f"log of the centred MSD ⟨x²⟩ − ⟨x⟩² over delays {o.get('fit_lags')} periods (95 % bootstrap interval "
              "over gliders); V_com = net gliding speed, |end − start| of a glider's once-per-period centre of mass "
              "over its bound periods (mean over gliders, 95 % bootstrap interval); mean step = mean distance per "
              "period (counts a zig-zag as speed); median turn = median |change| of the direction of travel per "
              "period; persistence = mean cosine between successive steps (1 straight, 0 random, −1 shuttle); "
              f"steady |r| = mean over the last {o.get('steady_window')} periods of "
              "pairs bound in all of them (± std over pairs, pair count).", ""]
    for s in report["runs"]:
        if s.get("clusters"):
            lines.append(f"Clusters at {s['amplitude_deg']:g}°: " + "; ".join(
                f"{c['kind']} |r| {c['r_W']:.2f} W, θ {c['theta_deg']:.0f}°, φ {c['phi_deg']:.0f}° ({c['samples']})"
                for c in s["clusters"]))
    lines += ["", "## Figures", ""]
    for name in report["figures"]["common"]:
        if name.endswith(".png"):
            lines.append(f"![{name}]({name})")
    for run, names in report["figures"]["runs"].items():
        for name in names:
            if name.endswith(".png"):
                lines.append(f"![{name}]({name})")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ relaxation

LAB_RELAX = {"emerged": 77, "trials": 151, "distance_W": (2.9, 0.2), "relaxation_periods": 30,
             "chain_lifetime": (8, 10)}


def lab_relax_fraction() -> tuple[float, tuple[float, float]]:
    """The lab's emergence fraction (77 of 151 trials) and its exact 95 % interval."""
    lo, hi = binding.binomial_interval(LAB_RELAX["emerged"], LAB_RELAX["trials"])
    return LAB_RELAX["emerged"] / LAB_RELAX["trials"], (float(lo), float(hi))


def relax_summary(data: RelaxRecord, min_periods: int = 100, apart_W: float = 2.0, crowd=None, analysis=None,
                  reading=None, emergence=None) -> dict:
    """The relaxation study's numbers (``analysis``: reduce.relaxation.analyse_relaxation's, computed when None), its
    crowd's (``crowd``: a ``CrowdSummary``, computed when None) and every emergence reading with the pairs'
    touch runs (``emergence``: reduce.emergence.emergence's, computed when None; ``reading``: the one the
    report prints, None: the primary one) beside the lab's, as the report's JSON records them."""
    from .reduce import emergence as EM, relaxation as RX
    if analysis is None:
        analysis = RX.analyse_relaxation(data, min_periods=min_periods, apart_W=apart_W)
    if emergence is None:
        emergence = EM.emergence(data, keep_periods=min(EM.KEEP_PERIODS, min_periods), periods=min_periods,
                                 apart_W=apart_W)
    a = analysis.as_json()
    a["reading"] = EM.parse_reading(reading).value
    a["emergence"] = emergence.as_json()
    a["crowd"] = dataclasses.asdict(crowd if crowd is not None else RX.crowd(data)[0])
    fraction, interval = lab_relax_fraction()
    a["lab"] = {**LAB_RELAX, "fraction": fraction, "interval": interval}
    a["settings"] = data.settings
    a["model"] = data.model
    if data.overrides:
        a["overrides"] = data.overrides
    a["period_s"] = data.period_s
    return a


def trial_figure(data: RelaxRecord, a, out: pathlib.Path) -> list[str]:
    """Tracks of the trial with the longest glider (else the first trial); ``a``: the study's
    ``reduce.relaxation.RelaxAnalysis``."""
    from .reduce import relaxation as RX
    W = float(data.body_length)
    best = max((r for r in a.per_trial if r.glider is not None), key=lambda r: r.glider.lifetime,
               default=a.per_trial[0] if a.per_trial else None)
    if best is None:
        return []
    t = int(np.flatnonzero(data.trial == best.trial)[0])
    xy = np.concatenate([data.start_poses[t][None, :, :2], data.poses[t][:, :, :2]]) / W
    eps = [e for e in RX.trial_episodes(data.poses[t], data.touched[t], data.start_poses[t],
                                        data.left_plate[t], data.periods_run[t], W, a.apart_W)
           if e.lifetime >= a.min_periods]
    title = (f"trial {best.trial}: {len(eps)} glider(s)" if eps else f"trial {best.trial}: no glider") + \
        f", {int(data.periods_run[t])} periods"
    return [p.name for p in plots.relaxation_trial(xy, eps, data.settings["plate_m"] / 2 / W, out,
                                                   "relax_tracks", title=title)]


def crowd_times(data: RelaxRecord, trials) -> dict:
    """Chains followed by overlap beside the exact rule (reduce.chains) and the crowd's fitted spreading time
    constants (reduce.spreading) of the usable trials (``trials``: their reduce.relaxation.CrowdTrial), as a
    report's JSON records them."""
    from .reduce import chains as CH, spreading as SP
    return {"chains": dataclasses.asdict(CH.study_chains(data)),
            "spreading": dataclasses.asdict(SP.study_spreading(data, trials))}


def write_relax_report(paths, out_dir, min_periods: int = 100, apart_W: float = 2.0, reading=None) -> dict:
    """Report of one relaxation store or several stages of one study:
    report.md, report.json, the tracks of one trial and the lifetime vs
    contour-length figure. ``reading``: the emergence reading the report leads with (reduce.emergence;
    None: the primary one); the JSON keeps every reading and every pair's touch runs."""
    from .store import read_relax
    data = read_relax(paths)
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from .reduce import relaxation as RX
    crowd, trials = RX.crowd(data)
    ra = RX.analyse_relaxation(data, min_periods=min_periods, apart_W=apart_W)
    a = relax_summary(data, min_periods, apart_W, crowd=crowd, analysis=ra, reading=reading)
    a.update(crowd_times(data, trials))
    figs = trial_figure(data, ra, out)
    figs += [p.name for p in plots.lifetime_contour(ra.episodes, ra.fit, min_periods, out)]
    if trials:
        figs += [p.name for p in plots.crowd(np.stack([t.phi for t in trials]), np.stack([t.in_chain for t in trials]),
                                             [np.nan if t.plateau.censored else t.plateau.period for t in trials],
                                             [e.lifetime for t in trials for e in t.chains], out)]
    episodes = [{k: v for k, v in e.items() if k != "track"} for e in a["episodes"]]
    per_trial = [{**r, "glider": None if r["glider"] is None else
                  {k: v for k, v in r["glider"].items() if k != "track"}} for r in a["per_trial"]]
    checks = {json.dumps(c, sort_keys=True, default=json_default): c
              for c in (store_step_check(Store(p)).as_dict() for p in data.paths)}
    # read_relax lets the stages of one study differ only in their trials and backend; a stage run on another
    # engine has another check (DART's own step: not checked), and then no one check speaks for the pooled glider
    step = next(iter(checks.values())) if len(checks) == 1 else None
    rep = {"stores": [str(p) for p in data.paths], "kind": "relax", **{k: v for k, v in a.items()
                                                                          if k not in ("episodes", "per_trial")},
           "episodes": episodes, "per_trial": per_trial, "figures": figs, "step_check": step}
    (out / "report.json").write_text(json.dumps(rep, indent=1, default=json_default))
    (out / "report.md").write_text(relax_markdown(rep))
    return rep


def write_any(stores, out_dir, burn_in: int | None = None, glider_min_periods: int | None = None,
              apart_W: float = 2.0, reading: str | None = None) -> dict:
    """The report of one scan or sweep store, or of relaxation stores (one, or the stages of one study),
    after checking the options. Raises ValueError or StoreError on bad input before writing anything.
    ``reading``: a relaxation report's emergence reading (reduce.emergence; None: the primary one)."""
    from .reduce.emergence import parse_reading
    from .store import Store
    reading = parse_reading(reading).value
    kinds = {Store(s).kind for s in stores}
    out = pathlib.Path(out_dir)
    plots.check_out_dir(out)
    if (burn_in is not None and burn_in < 0) or (glider_min_periods is not None and glider_min_periods < 2):
        raise ValueError("--burn-in must be >= 0 and --glider-min-periods >= 2")
    if not apart_W > 0:
        raise ValueError("--apart must be positive")
    if kinds == {"relax"}:
        return write_relax_report(stores, out, min_periods=glider_min_periods or 100, apart_W=apart_W,
                                  reading=reading)
    if len(stores) > 1:
        raise ValueError("several stores are read only as stages of one relaxation study; "
                         "report scan stores one at a time")
    return write_report(stores[0], out, ReportOptions(burn_in=burn_in, glider_min_periods=glider_min_periods))


def headline(rep: dict) -> list[str]:
    """A report's numbers in a few lines (what ``smx report`` prints)."""
    if rep.get("kind") == "relax":
        r = rep["emergence"]["readings"][rep["reading"]]
        lo, hi = r["interval"]
        others = ", ".join(f"{k} {x['emerged']}/{x['trials']}" for k, x in rep["emergence"]["readings"].items()
                           if k != rep["reading"])
        return [f"reading {r['label']}: {r['emerged']}/{r['trials']} trials formed a glider ({r['fraction']:.2f}, "
                f"95% CI {lo:.2f}-{hi:.2f}; lab 77/151); distance {r['distance']['mean']:.2f} W "
                f"(n = {r['distance']['n']}; lab 2.9 W)", f"other readings (--reading): {others}",
                *crowd_headline(rep.get("crowd"))]
    return [f"{s['run']}: P_b end {s['pb_end'][0]}, C1 basin {(s.get('C1') or {}).get('basin_fraction')}, "
            f"C2 basin {(s.get('C2') or {}).get('basin_fraction')}, gliders {s['gliders']}, "
            f"beta {(s.get('beta') or {}).get('value')}" for s in rep["runs"]]


def crowd_headline(c: dict | None) -> list[str]:
    if not c:
        return []
    pl, cl = c["plateau"], c["chain_lifetime"]
    return [f"relaxation (area-fraction plateau) median {pl['median']:.0f} periods, {pl['censored']} of {pl['n']} "
            f"without a plateau (lab ~30); chain lifetime median {cl['median']:.0f} periods over {cl['n']} chains "
            "(lab 8-10)"]


def crowd_rows(c: dict | None, f) -> list[str]:
    """The crowd's rows of a relaxation report (reduce.relaxation.CrowdSummary as stored)."""
    if not c:
        return []
    cl, pl, ps, pp, cr = c["chain_lifetime"], c["plateau"], c["phi_start"], c["phi_plateau"], c["phi_creep"]
    return [
        f"| relaxation time, area-fraction plateau (φ changes ≤ 0.02 per 10 periods, two windows running) | "
        f"median {f(pl['median'], 0)} [IQR {f(pl['q25'], 0)}–{f(pl['q75'], 0)}]; {pl['censored']} of {pl['n']} "
        "trials without a plateau | about 30 periods |",
        f"| area fraction φ = n W D / hull of the centres: start → plateau (further fall to the end) | "
        f"{f(ps['median'])} → {f(pp['median'])} ({f(cr['median'], 3)}; medians over trials) | "
        "≈ 0.5, falling by 0.24–0.35 in Savoie's cloud runs |",
        f"| chain lifetime (≥ 3 robots connected by touches, same members) | mean {f(cl['mean'], 1)}, median "
        f"{f(cl['median'], 0)} [IQR {f(cl['q25'], 0)}–{f(cl['q75'], 0)}] periods over {cl['n']} chains, "
        f"{cl['censored']} still holding at the end; {c['chained_at_end']} of {c['trials']} trials end with a chain | "
        "8–10 periods (APS 2023, G18.2) |",
        f"| neighbours of a robot in a chain (touches per period) | {f(c['neighbours_in_chain'])}; closed loops in "
        f"{f(100 * c['loop_fraction'], 0)} % of chain-periods; all robots {f(c['neighbours_all'])} | "
        "≈ 4 with closed loops (glider gait; APS 2023) |",
    ]


def time_rows(chains: dict | None, sp: dict | None, f) -> list[str]:
    """The rows of chains followed by overlap and of the crowd's spreading time constants (crowd_times)."""
    rows = []
    if chains:
        o = chains["overlap"]
        rows.append(f"| chain lifetime, followed by overlap (a chain lives while most of its robots stay) | mean "
                    f"{f(o['mean'], 1)}, median {f(o['median'], 0)} [IQR {f(o['q25'], 0)}–{f(o['q75'], 0)}] periods "
                    f"over {o['n']} chains, {o['censored']} still holding at the end | 8–10 periods (APS 2023, G18.2) |")
    if sp:
        t, c, sh = sp["phi_tau"], sp["contacts_tau"], sp["first_period_share"]
        rows.append(f"| spreading time constant τ of φ from period 1 on (median over trials; 3τ: 95 % done) | "
                    f"{f(t['median'], 1)} periods (3τ {f(3 * t['median'], 0) if t['n'] else '–'}; {sp['phi_at_bound']} "
                    f"trials unresolved); period 1 takes {f(sh['median'])} of φ's drop; contacts' τ {f(c['median'], 1)} "
                    "| about 30 periods to steady state |")
    return rows


def relax_markdown(rep: dict) -> str:
    s, lab = rep["settings"], rep["lab"]
    f = lambda x, nd=2: formatting.num(x, f".{nd}f")  # noqa: E731
    gl, fit, ty = rep["glider_lifetime"], rep["fit"], rep["typed"]
    rt = rep["relaxation_periods"]
    readings = rep["emergence"]["readings"]
    r = readings[rep["reading"]]
    d = r["distance"]
    lines = [f"# Relaxation report: {', '.join(pathlib.Path(p).name for p in rep['stores'])}", "",
             f"{rep['trials']} trials of {s['n_robots']} robots ({rep['valid']} usable), {s['periods']} periods "
             f"at α_max = {s['amplitude_deg']:g}° ({s['gait']}, {s['chirality']}), model {presets.describe(rep['model'], rep.get('overrides'))}; "
             f"{specs.relax_config_from_json(s).start_words()}; plate {s['plate_m']:g} m. The glider rows read "
             f"emergence as **{r['label']}** (docs/relax.md, \"The discovery read the paper's way\"; `--reading` "
             "picks another); the lifetime, type and contour rows read bound-and-apart episodes (a pair touching every "
             f"period, no touch with a third robot, every third robot's centre ≥ {rep['apart_W']:g} W away).", "",
             "| quantity | model | lab |", "|---|---|---|",
             f"| trials forming a glider, {r['label']} | {r['emerged']}/{r['trials']} = {f(r['fraction'])} "
             f"[{f(r['interval'][0])}, {f(r['interval'][1])}], Fisher's p = {r['fisher_p']:.2g} | "
             f"{lab['emerged']}/{lab['trials']} = "
             f"{f(lab['fraction'])} [{f(lab['interval'][0])}, {f(lab['interval'][1])}] |",
             f"| distance travelled by the glider (W) | {f(d['mean'])} ± {f(d['sem'])} (n = {d['n']}); "
             f"{step_note(rep['step_check']) if rep.get('step_check') else 'stages with different step checks (backends): step not checked'} | "
             f"{lab['distance_W'][0]} ± {lab['distance_W'][1]} |",
             f"| glider lifetime (periods) | {f(gl['mean'], 0)} ± {f(gl['sem'], 0)}, {rep['glider_censored']} of "
             f"{gl['n']} still bound at the end | ≥ 100; some C1 still bound at 300 |",
             f"| glider types | C1 {rep['glider_kinds']['C1']}, C2 {rep['glider_kinds']['C2']} | both seen |",
             f"| contour length vs lifetime, all {fit['n']} episodes | slope {f(fit['slope'], 4)} W/period, "
             f"r = {f(fit['r'])}, p = {fit['p']:.2g} | linearly correlated |",
             f"| episode lifetime C1 vs C2 (mean, median) | C1 {f(ty['C1']['mean'], 1)}, {f(ty['C1']['median'], 0)} "
             f"(n = {ty['C1']['n']}, {ty['C1']['censored']} censored); C2 {f(ty['C2']['mean'], 1)}, "
             f"{f(ty['C2']['median'], 0)} (n = {ty['C2']['n']}); one-sided Mann–Whitney p = "
             f"{ty['p_c1_longer']:.2g} | C1 lives longer |",
             f"| relaxation time (last period with a robot touching two others) | median {f(rt['median'], 0)} "
             f"[IQR {f(rt['q25'], 0)}–{f(rt['q75'], 0)}]; {rt['crowded_at_end']} trials still crowded at the end | "
             "about 30 periods |",
             *crowd_rows(rep.get("crowd"), f),
             *time_rows(rep.get("chains"), rep.get("spreading"), f),
             f"| robots that left the plate | {rep['left_plate']['robots']} in {rep['left_plate']['trials']} "
             "trials | – |",
             f"| trials stopped early (no contact for {s['quiet_periods']} periods) | {rep['stopped_early']} | – |",
             "", "Emergence under every reading (the glider's distance: net, from period 30 on for (b)–(d)):", "",
             "| reading | trials forming a glider | Fisher's p vs the lab | distance (W) | C1, C2 |", "|---|---|---|---|---|",
             *[f"| {x['label']}{' (primary)' if k == rep['emergence']['primary'] else ''} | {x['emerged']}/{x['trials']} "
               f"= {f(x['fraction'])} [{f(x['interval'][0])}, {f(x['interval'][1])}] | {x['fisher_p']:.2g} | "
               f"{f(x['distance']['mean'])} ± {f(x['distance']['sem'])} (n = {x['distance']['n']}) | "
               f"{x['kinds']['C1']}, {x['kinds']['C2']} |" for k, x in readings.items()],
             "", "Intervals: exact (Clopper–Pearson) 95 %; ± is the standard error of the mean."]
    if s["periods"] < rep["min_periods"]:
        lines.append(f"These trials ({s['periods']} periods) are shorter than the glider criterion "
                     f"({rep['min_periods']} periods): no trial can form a glider; pass --glider-min-periods.")
    lines.append("")
    lines += [f"![{n}]({n})" for n in rep["figures"]]
    return "\n".join(lines) + "\n"
