"""The calibration report: DIR/report.md, report.json and figures.

report.json carries its layout's ``schema`` (``SCHEMA``) and the package that wrote it; :func:`read` reads a
report of this schema and refuses any other in one line, and :func:`rewrite` formats a stored report again
(``smx report DIR``) without calibrating again.
"""

from __future__ import annotations

import json
import pathlib
import shutil

import numpy as np

from ..plots import check_out_dir, pyplot
from ..report import json_default
from .data import Trial
from .drift import MIN_SPREAD_DEG
from .effects import BY_NAME
from .heldout import HeldoutComparison
from .observables import LABELS, reproduced
from .phase import OFFSET_SYSTEMATIC
from .residuals import BINS, DEG


def _num(x, spec=".3g"):
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "–"
    return format(float(x), spec)


def _figures(result, heldout: list[Trial], tracks_before, tracks_after, out: pathlib.Path) -> list[str]:
    plt = pyplot()
    names = []
    # residual by block, before and after
    b, a = result["before"]["where_heldout"], result["after"]["where_heldout"]
    keys = list(b)
    fig, ax = plt.subplots(figsize=(5, 3.2))
    x = np.arange(len(keys))
    ax.bar(x - 0.2, [b[k] for k in keys], 0.4, label="nominal model")
    ax.bar(x + 0.2, [a.get(k, np.nan) for k in keys], 0.4, label="with added effects")
    ax.axhline(1, color="k", lw=0.8, ls=":")
    ax.set_xticks(x, keys)
    ax.set(ylabel="held-out error (mean sq. normalised)", yscale="log")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "residual_blocks.png", dpi=130)
    plt.close(fig)
    names.append("residual_blocks.png")
    # diagnosis ranking (first round)
    rk = result["rounds"][0]["ranking"] if result["rounds"] else []
    if rk:
        fig, ax = plt.subplots(figsize=(5, 3.2))
        ax.barh([r["effect"] for r in rk][::-1], [r["grid_gain"] for r in rk][::-1])
        ax.set(xlabel="share of the training χ² removed on a coarse grid", xlim=(0, 1))
        fig.tight_layout()
        fig.savefig(out / "diagnosis.png", dpi=130)
        plt.close(fig)
        names.append("diagnosis.png")
    # arm angles and body wobble of the first held-out trial
    tr = heldout[0]
    ph = np.mod(tr.t / tr.periods[0], 1.0)  # robot 0's gait phase: the plot shows robot 0
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.4))
    if tr.arms is not None:
        for k, ax in zip((0, 1), axes[:2]):
            ax.plot(ph, tr.arms[:, 0, k] * DEG, ".", ms=2, color="k", label="measured")
            ax.plot(ph, tracks_before[0][:, 0, 3 + k] * DEG, ".", ms=2, color="#d62728", label="nominal")
            ax.plot(ph, tracks_after[0][:, 0, 3 + k] * DEG, ".", ms=2, color="#1f77b4", label="fitted")
            ax.set(xlabel="gait phase", ylabel=f"arm {k + 1} (deg)", title=tr.name)
        axes[0].legend(fontsize=7, markerscale=4)
    ax = axes[2]
    for trk, c, lab in ((tr.pose, "k", "measured"), (tracks_before[0], "#d62728", "nominal"),
                        (tracks_after[0], "#1f77b4", "fitted")):
        ax.plot((trk[:, 0, 0] - tr.pose[0, 0, 0]) * 1e3, (trk[:, 0, 1] - tr.pose[0, 0, 1]) * 1e3, lw=0.8, color=c,
                label=lab)
    ax.set(xlabel="x (mm)", ylabel="y (mm)", aspect="equal", title="robot 0 body track")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "heldout_trial.png", dpi=130)
    plt.close(fig)
    names.append("heldout_trial.png")
    return names


def check_output(out, overwrite: bool = False) -> None:
    """ValueError unless the report folder ``out`` can be written (an existing report only with ``overwrite``)."""
    out = pathlib.Path(out)
    check_out_dir(out)
    if (out / "report.md").exists() and not overwrite:
        raise ValueError(f"{out} already holds a report; pass --overwrite to replace it")
    if not out.exists() and not out.parent.is_dir():
        raise ValueError(f"output directory {out.parent} does not exist")


SCHEMA = 1  # report.json's layout; reports written before schema 1 existed carry none


def write(cal, heldout: HeldoutComparison, out_dir, overrides: dict | None = None) -> dict:
    """Write the report of a ``stages.calibrate`` result ``cal`` (a ``Calibration``) with its held-out
    comparison (``heldout.compare_heldout``); ``overrides``: the scene fields the command changed
    (``--set``), recorded as given. Formats only: nothing is fitted or simulated. Returns the JSON written."""
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from .. import __version__
    result = {"schema": SCHEMA, "package": f"smarticle-mjx {__version__}", **cal.summary,
              **({"overrides": dict(overrides)} if overrides else {})}
    result["metrics_heldout"] = heldout.metrics_json()
    result["figures"] = _figures(result, list(heldout.trials), heldout.before, heldout.after, out)
    (out / "report.json").write_text(json.dumps(result, indent=1, default=json_default))
    (out / "report.md").write_text(markdown(result))
    return result


def is_report(path) -> bool:
    """Whether ``path`` is a calibration report's folder (it holds a report.json written by :func:`write`:
    one with a ``verdict`` and ``added``, of any schema)."""
    f = pathlib.Path(path) / "report.json"
    if not f.is_file():
        return False
    try:
        r = json.loads(f.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(r, dict) and "verdict" in r and "added" in r


def read(path) -> dict:
    """A calibration report's JSON (``path``: its folder or its report.json); ValueError in one line for a file
    that is not one, or one of another schema."""
    p = pathlib.Path(path)
    f = p / "report.json" if p.is_dir() else p
    try:
        r = json.loads(f.read_text())
    except (OSError, ValueError) as e:
        raise ValueError(f"{f} is not a readable calibration report ({e.__class__.__name__})") from None
    if not isinstance(r, dict) or "verdict" not in r:
        raise ValueError(f"{f} is not a calibration report (no verdict)")
    got = r.get("schema")
    if got != SCHEMA:
        made = r.get("package", "a version before report schemas")
        raise ValueError(f"{f} has calibration report schema {got if got is not None else 'none'} (written by {made}); "
                         f"this version reads schema {SCHEMA}: calibrate the data again")
    return r


def rewrite(path, out_dir) -> pathlib.Path:
    """report.md formatted again from a stored report (:func:`read`), with its figures, into ``out_dir``
    (which may be the report's own folder); nothing is calibrated or simulated."""
    src = pathlib.Path(path)
    src = src.parent if src.name == "report.json" else src
    r = read(src)
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for name in r.get("figures", []):
        if (src / name).exists() and (out / name).resolve() != (src / name).resolve():
            shutil.copyfile(src / name, out / name)
    if out.resolve() != src.resolve():
        (out / "report.json").write_text((src / "report.json").read_text())
    (out / "report.md").write_text(markdown(r))
    return out / "report.md"


# what decides a servo lag or dead time where the delay test does not
HELDOUT_RULE = ("a lag or dead time is kept only if, fitted with the nominal parameters, it lowers the held-out "
                "error by 20 % or more")


def arm_offset_markdown(ao: dict | None) -> list[str]:
    """The report's lines on arms resting off their commanded corners (``armoffset.ArmOffsetReading``), or
    none where no arm was read (reports before the reading, arms not tracked, too few rests)."""
    if not ao or not ao.get("applicable"):
        return []
    lines = ["## Arms at rest against their commanded corners, without the model", "",
             "Where each tracked arm rests (the middle third of each run of frames nearest one commanded corner), "
             "averaged over the upper and lower corners: a servo that falls short of its corners falls short of "
             "both alike (the shortfall), an arm read or mounted off by a constant rests off both the same way "
             f"(the offset; present beyond {ao['min_offset_deg']:g}° and {ao['z']:g} standard errors). "
             + ("**An arm rests off its corners**: outside the library's effects, it is taken out of that arm's "
                "track before any fit, and named as unexplained in the verdict. Whether the tracker misreads the "
                "arm or the arm is mounted off its servo, the data cannot say; a mounted one moves the robot as "
                "the model's arm does not."
                if ao.get("taken_out") else "No arm rests off its corners."), "",
             "| robot | arm | offset (°) | standard error (°) | shortfall (°) | rests |", "|---|---|---|---|---|---|"]
    lines += [f"| {a['robot']} | {a['arm'] + 1} | {a['offset_deg']:+.2f}{' (present)' if a['present'] else ''} | "
              f"{a['se_deg']:.2f} | {a['shortfall_deg']:+.2f} | {a['rests']} |" for a in ao["arms"]]
    return lines + [""]


def offset_markdown(ot: dict | None) -> list[str]:
    """The report's lines on the phase offset read off the robots' own curves (``phase.OffsetTest``), or
    none where it was not read (one robot, or fewer than two pairs)."""
    if not ot or ot["n"] < 2:
        return []
    return ["## Phase offset between the robots, without the model", "",
            f"The shift that aligns each robot's {ot['read_from']} with robot 0's, pair by pair: "
            f"{ot['mean']:+.4f} ± {ot['se']:.4f} periods over {ot['n']} pairs (Student's t at 95 %: "
            f"{ot['t95']:.2f}). "
            + (f"**An offset between the robots**: every fit of a phase offset holds it there, reported with "
               f"[{ot['interval'][0]:+.4f}, {ot['interval'][1]:+.4f}] (the spread and "
               f"{OFFSET_SYSTEMATIC} period the reading may miss by)"
               + ("; clear of zero, it is added as measured, with no fit asked to confirm it." if ot.get("established")
                  else "; within reach of zero, a fit must confirm it.") if ot["present"] else
               "No offset between the robots: a phase offset is not fitted."), ""]


def drag_markdown(dt: dict | None) -> list[str]:
    """The report's lines on arms dragging on the plate, read off the body's heading (``armdrag.DragTest``),
    or none where it could not be read (no quarter resolved by enough frames)."""
    if not dt or not dt.get("applicable"):
        return []
    return ["## Arms on the plate, without the model", "",
            "Between the kicks at the ends of a swing, an arm clear of the plate leaves its body at rest; an arm "
            "that drags on the plate turns it, the same way at every repeat. The body's heading rate there: "
            f"{dt['rate_deg_s']:.2f} deg/s (median over {dt['groups']} kinds of gait quarter, largest "
            f"{dt['max_rate_deg_s']:.2f}), at most {dt['upper_deg_s']:.2f} (twice its standard error above); "
            f"chi² {dt['chi2']:.1f} against zero, p = {dt['p']:.2g} (present at p < {dt['rule']['p_present']:g} "
            f"and above {dt['rule']['rate_floor_deg_s']:g} deg/s; absent where a turn of "
            f"{dt['rule']['detectable_deg_s']:g} deg/s would have shown). "
            f"**{dt['action'][0].upper() + dt['action'][1:]}.**", ""]


def final_guard_markdown(guard: dict | None) -> list[str]:
    """The report's line where the final model's held-out error ended above the nominal fit's (``stages.
    FinalGuard``): the effects were dropped; nothing where it did not."""
    if not guard:
        return []
    return [f"**The effects added ({', '.join(guard['dropped'])}) raised the held-out error to "
            f"{guard['final_err_heldout']:.3g}, above the nominal parameters' own {guard['nominal_err_heldout']:.3g}; "
            "none is kept** (the calibration never ends worse than its nominal fit).", ""]


def markdown(r: dict) -> str:
    b, a = r["before"], r["after"]
    an = r.get("after_nominal") or b
    warn = (r.get("conventions") or {}).get("warning")
    lines = ["# Calibration report", ""] + ([f"**Conventions: {warn}.**", ""] if warn else []) + [
             f"**Verdict: {r['verdict']}.** Held-out error (mean squared residual in units of its measurement "
             f"error; about 1 = within error) {b['err_heldout']:.2f} → {a['err_heldout']:.2f} "
             f"({1 - a['err_heldout'] / max(b['err_heldout'], 1e-12):+.0%}); after the nominal parameters alone "
             f"{an['err_heldout']:.2f}.", "",
             f"{len(r['trials']['train'])} training trials, {len(r['trials']['heldout'])} held out; "
             f"{r['model_runs']} batched model runs"
             + ("; the model ran " + " and ".join(f"MuJoCo's `{i}` integrator at {1e3 * dt:g} ms"
                                                  for i, dt in r["numerics"]) if r.get("numerics") else "")
             + ("; model changed by --set " + ", ".join(f"{k}={v}" for k, v in r["overrides"].items())
                if r.get("overrides") else "") + ".", ""]
    lines += final_guard_markdown(r.get("final_guard"))
    nom = r.get("nominal")
    measured = (nom or {}).get("measured") or {}
    if nom:
        bound = ("Measured values (the sidecar's `measured`, value ± sd) are the preset column and enter the fit "
                 "as Gaussian priors; a fit pulled more than 3 sd from one is a finding (bold). "
                 if measured else
                 "No measured values in the sidecar: only the bounds (docs/calibration.md, × preset) and the data "
                 "hold the nominal parameters; give weighed masses, ruler lengths or a servo speed as `measured` "
                 "to pin them. ")
        lines += ["## Nominal parameters (fitted first)", "", bound,
                  f"Bounded least squares over {nom['evaluations']} model runs; training error "
                  f"{nom['err_before']:.3g} → {nom['err_after']:.3g}. Bold: the 95 % interval excludes the preset "
                  "value and the parameter is neither on a bound nor correlated above 0.9 with another (the data "
                  "say it differs). No interval: on a bound.", "",
                  "| parameter | preset | fitted | 95 % interval | flags |", "|---|---|---|---|---|"]
        for k, v in nom["values"].items():
            lo, hi = nom["interval"][k]
            pre = nom["preset"][k]
            flags = (["at a bound"] if k in nom["at_bound"] else []) + \
                [f"r = {c[2]:+.2f} with {c[1] if c[0] == k else c[0]}" for c in nom["correlated"] if k in c[:2]]
            finding = any(f["param"] == k for f in r.get("nominal_findings", []))
            mark = "**" if finding else ""
            if k in measured:
                m, sd = measured[k]
                flags.append(f"measured {_num(m, '.4g')} ± {_num(sd, '.2g')}: {(v - m) / sd:+.1f} sd")
            lines.append(f"| {mark}{k}{mark} | {_num(pre, '.4g')} | {mark}{_num(v, '.4g')}{mark} | "
                         f"[{_num(lo, '.4g')}, {_num(hi, '.4g')}] | {'; '.join(flags)} |")
        lines.append("")
    dt = r.get("delay_test")
    if dt:
        lines += ["## Arm delay by amplitude (structure before numbers)", ""]
        if dt["applicable"]:
            lines += ["The measured arm delay's excess over the preset model's, fitted as constant + slope × "
                      "amplitude: a servo lag or dead time adds the same time at every amplitude, a slower servo a "
                      f"time that grows with it. Constant {dt['constant_ms']:+.1f} ± {dt['constant_se_ms']:.1f} ms, "
                      f"slope {dt['per_rad_ms']:+.1f} ± {dt['per_rad_se_ms']:.1f} ms/rad: "
                      + ("**a constant delay the model's servo lacks**; a lag or dead time fitted with the nominal "
                         "parameters is then kept if it lowers the training χ² by more than k ln n, its interval "
                         "excludes 0 and the held-out error does not rise." if dt["constant_delay"] else
                         "no constant delay (a lag or dead time is not tried)." if dt.get("no_constant_delay") else
                         f"undecided ({HELDOUT_RULE})."), "",
                      "| amplitude | excess over the preset model (ms) | standard error (ms) |", "|---|---|---|"]
            lines += [f"| {a:g}° | {e:+.1f} | {s_:.1f} |" for a, e, s_ in zip(dt["amplitudes_deg"], dt["excess_ms"],
                                                                             dt["se_ms"])]
        else:
            lines += [f"Not applicable (arm delays on fewer than two amplitudes at least 1.5× apart): {HELDOUT_RULE}."]
        rt = r.get("rise_test") or {}
        if rt.get("reading"):
            lines += ["", "The arm rise (a quarter to three quarters of a swing) beyond the preset model's, split the "
                      f"same way: constant {rt['constant_ms']:+.1f} ± {rt['constant_se_ms']:.1f} ms, slope "
                      f"{rt['per_rad_ms']:+.1f} ± {rt['per_rad_se_ms']:.1f} ms/rad. A lag smears a swing and "
                      "lengthens the short ones' rise; a dead time moves it whole. It reads a **"
                      + ("lag" if rt["reading"] == "servo_lag" else "dead time")
                      + "**, which is kept should a lag and a dead time both pass."]
        lines.append("")
    lines += arm_offset_markdown(r.get("arm_offset"))
    lines += offset_markdown(r.get("offset_test"))
    lines += drag_markdown(r.get("drag_test"))
    lines += hypotheses_markdown(r.get("nominal_hypotheses") or [])
    lines += drift_markdown(r.get("drift"), r.get("plate_level"))
    lines += observables_markdown(r.get("observables"))
    if r["added"]:
        lines += ["## Added effects", "",
                  "The 95 % interval carries the model robot's mismatch with the measured one: the statistical "
                  "interval (beside it) widened by a log-normal factor per effect, estimated on independently "
                  "built robots (docs/calibration.md, \"Sizes that carry the model's mismatch\"); a plate "
                  "tilt's carries the robots' slide mismatch instead.", "",
                  "| effect | parameter | fitted | 95 % interval | statistical 95 % | mismatch (ln sd) |",
                  "|---|---|---|---|---|---|"]
        for e in r["added"]:
            stat = e.get("interval_statistical") or e["interval"]
            for k, v in e["values"].items():
                lo, hi = e["interval"][k]
                slo, shi = stat[k]
                sd = (e.get("mismatch_log_sd") or {}).get(k)
                bound = " (on the library's bound: the data want at least this)" if k in (e.get("at_bound") or []) \
                    else ""
                lines.append(f"| {e['title']} | {k} ({e['units'][k]}) | {_num(v, '.4g')}{bound} | "
                             f"[{_num(lo, '.4g')}, {_num(hi, '.4g')}] | [{_num(slo, '.4g')}, {_num(shi, '.4g')}] | "
                             + ("slide mismatch" if e["effect"] == "plate_tilt" and sd is None else
                                "–" if sd is None else f"{sd:.2f}") + " |")
        lines.append("")
    else:
        lines += ["No effect from the library was added.", ""]
    if a["err_heldout"] > r["criteria"]["unexplained_error"]:
        where = sorted(a["where_heldout"].items(), key=lambda kv: -kv[1])
        lines += ["## Unexplained residual", "",
                  "No effect in the library explains what remains. Its signature (held-out mean squared normalised "
                  "residual per block; 1 = measurement error): " + ", ".join(f"{k} {v:.1f}" for k, v in where) + ".", ""]
    lines += ["## Diagnosis (first round)", "",
              "Each candidate on a coarse grid of its parameters: the share of the training χ² it removes (the rank), "
              "beside the share a linear step along its probe signature would remove; then the fit of the leading "
              "candidates:", "",
              "| effect | grid gain | linear signature | what it moves | fitted alone: held-out change | accepted |",
              "|---|---|---|---|---|---|"]
    tried = {t["effect"]: t for rd in r["rounds"][:1] for t in rd["tried"]}
    for row in (r["rounds"][0]["ranking"] if r["rounds"] else []):
        t = tried.get(row["effect"])
        gain = f"{t['heldout_gain']:+.0%}" if t else "–"
        lines.append(f"| {row['effect']} | {row['grid_gain']:.0%} | {row['explained']:.0%} | "
                     f"{BY_NAME[row['effect']].signature} | {gain} | "
                     f"{'yes' if t and t['accepted'] else 'no'} |")
    lines += ["", f"Criteria: add an effect only if it lowers the training χ² by more than k ln n (BIC) and the "
              f"held-out error by ≥ {r['criteria']['min_heldout_gain']:.0%}; call the residual unexplained above "
              f"{r['criteria']['unexplained_error']}.", "", "## Metrics on held-out trials", "",
              "| metric | measured | nominal model | with effects |", "|---|---|---|---|"]
    mb, ma = r["metrics_heldout"]["before"], r["metrics_heldout"]["after"]
    lines.append(f"| arm-angle RMS error (deg) | – | {_num(mb['arm_rms_deg'])} | {_num(ma['arm_rms_deg'])} |")
    lines.append(f"| trajectory error at the end (mm) | – | {_num(mb['trajectory_error_mm'])} | "
                 f"{_num(ma['trajectory_error_mm'])} |")
    for key, label in (("step_mm", "per-cycle step (mm)"), ("rotation_deg", "per-cycle rotation (deg)")):
        lines.append(f"| {label}: mean | {_num(mb[key]['measured'])} | {_num(mb[key]['model'])} | "
                     f"{_num(ma[key]['model'])} |")
        lines.append(f"| {label}: Wasserstein to measured / KS p | – | {_num(mb[key]['wasserstein'])} / "
                     f"{_num(mb[key]['ks_p'], '.2g')} | {_num(ma[key]['wasserstein'])} / {_num(ma[key]['ks_p'], '.2g')} |")
    for key, label in (("drift_mm_per_s", "drift speed (mm/s)"), ("heading_drift_deg_per_cycle", "heading drift (deg/cycle)"),
                       ("msd_beta", "MSD exponent β (per-cycle positions)")):
        lines.append(f"| {label} | {_num(mb[key]['measured'])} | {_num(mb[key]['model'])} | {_num(ma[key]['model'])} |")
    if "pair_wasserstein" in mb:
        for k in ("r_W", "theta_deg", "phi_deg"):
            lines.append(f"| pair {k}: Wasserstein to measured | – | {_num(mb['pair_wasserstein'][k])} | "
                         f"{_num(ma['pair_wasserstein'][k])} |")
    lines += ["", "Error per block, held-out (mean squared normalised residual): " + ", ".join(
        f"{k} {b['where_heldout'][k]:.2f} → {a['where_heldout'].get(k, float('nan')):.2f}" for k in b["where_heldout"]),
        "", f"Blocks: arms = arm angle by gait phase ({BINS} bins); wobble = body motion within a cycle in the body "
        "frame; step = per-cycle step in the plate frame; increments = frame-to-frame jitter.", ""]
    lines += [f"![{n}]({n})" for n in r["figures"]]
    return "\n".join(lines) + "\n"


def drift_markdown(dr: dict | None, pl: dict | None) -> list[str]:
    """The report's plate-frame drift section: the model-free test, the tilt whose model drift matches, the
    gaits' directions and, per gait, the tilt that gait alone gives (or that it was left out: its model robot
    drifts uphill)."""
    lines: list[str] = []
    if dr is not None and not dr.get("dof") and (pl or {}).get("reason"):
        return ["## Plate-frame drift (model-free tilt test)", "",
                f"Not read: no gait's lone-robot headings span {MIN_SPREAD_DEG:g}°. An anisotropic plate was not "
                f"tried: {pl['reason']}.", ""]
    if dr and dr.get("dof"):
        tf = dr.get("tilt_fit") or {}
        lines += ["## Plate-frame drift (model-free tilt test)", "",
                  "Per gait, every lone robot's per-cycle step fitted as R(heading) s + v over all trials: s is the "
                  "body-frame step (whatever the model gets wrong about the robot), v a drift fixed to the plate "
                  f"(a tilt). χ² of v = 0: {dr['chi2']:.1f} on {dr['dof']} dof, p = {dr['p']:.2g} "
                  f"(a finding below p = {dr['threshold_p']:g}).", "",
                  "| α_max | v (mm/cycle) | standard error | cycles | heading spread |", "|---|---|---|---|---|"]
        for g in dr["groups"]:
            lines.append(f"| {g['amplitude_deg']:g}° | ({g['v_mm'][0]:+.4f}, {g['v_mm'][1]:+.4f}) | "
                         f"({g['se_mm'][0]:.4f}, {g['se_mm'][1]:.4f}) | {g['cycles']} | {g['spread_deg']:.0f}° |")
        pl = pl or {}
        if pl.get("reason"):
            lines += ["", f"An anisotropic plate was not tried: {pl['reason']}."]
        elif pl.get("anisotropic_plate_tried"):
            lines += ["", f"The drift's p is below {pl['threshold_p']:g}: the plate may be other than level and "
                      "isotropic, so an anisotropic plate was tried."]
        if tf.get("ok"):
            lines += ["", f"Tilt whose model drift matches: ({tf['tilt_deg'][0]:+.3f}, {tf['tilt_deg'][1]:+.3f})° "
                      f"± ({tf['se_deg'][0]:.3f}, {tf['se_deg'][1]:.3f})°, drift χ² {tf['chi2_before']:.1f} → "
                      f"{tf['chi2_after']:.1f}; {'added' if tf.get('accepted') else 'not added'} (kept when "
                      "the drift test finds drift, the tilt's 95 % region excludes a level plate, the drift χ² at "
                      "least halves and the gaits' drifts point one way)."]
            th = dr.get("tilt_heldout")
            if th:
                lines += ["", f"Held-out error with the model as it stood before the tilt: {th['without']:.3g}; with "
                          f"the tilt: {th['with_tilt']:.3g}"
                          + (". **It rose**: the drift is there, but the model's tilt does not carry it to the "
                             "held-out trials"
                             + (", so the tilt was not kept (no effect that raises the held-out error is, whatever "
                                "test proposed it)" if tf.get("refused") else "")
                             + ". On the stress suite a tilt named this way was the hidden effect in "
                             "a third of the sets (a plate slipperier along one axis or a grip that depends on the "
                             "robot's heading drifts alike); check it at more headings." if th["rose"] else ".")]
            beyond = bool(tf.get("gate_beyond_model"))
            pm = (tf.get("plate_models_beyond_model") if beyond else dr.get("plate_models")) or {}
            if "follows_the_robot" in tf and pm.get("applicable"):
                lines += ["", "Does the drift follow each gait's own step (as a plate slipperier along one axis or "
                          "arms dragging on the plate make it) rather than one vector (a tilt's)? Read on "
                          + ("the drift the model leaves beyond its own on a level plate (the model drags its arms "
                             "on the plate or holds an anisotropic plate, whose drift follows the step)" if beyond
                             else "the data alone")
                          + f": one vector χ² {pm['chi2_one_vector']:.1f}"
                          + (f" (p {pm['p_one_vector']:.2g})" if pm.get("p_one_vector") is not None else "")
                          + f", one anisotropy χ² {pm['chi2_anisotropy']:.1f}: "
                          + ("**it follows the step**, so no tilt is named from it." if tf["follows_the_robot"]
                             else "one vector, as a tilt's.")]
            di = dr.get("directions") or {}
            if di.get("compared"):
                lines += ["", f"Directions of the {di['groups']} gaits' significant drifts: up to "
                          f"{di['max_angle_deg']:.0f}° from their mean ({di['mean_deg']:.0f}°); "
                          + ("one way, as a tilt pulls." if di["consistent"] else
                             "**they point different ways**: not a tilt, which pulls every gait downhill, but a "
                             "plate that is not level in another way (slipperier along one axis, a grip that depends "
                             "on the robot's heading), which the library's tilt does not describe.")]
            disc = tf.get("discrepancy")
            if disc:
                mi = tf["magnitude_interval"]
                lines += ["", f"Magnitude {tf['magnitude_deg']:.3g}° toward {tf['direction_deg']:.0f}°; 95 % interval "
                          f"with the model robot's mismatch [{mi[0]:.3g}, {mi[1]:.3g}]° (a log-sd of "
                          f"{disc['log_sd']:.2f}: {disc['log_sd_gaits']:.2f} from the gaits' disagreement, "
                          f"{disc['log_sd_slide']:.2f} from how differently the model robot slides)"
                          + ("" if tf.get("size_determined") else "; **the size is not determined by this model**")
                          + ". The drift a tilt "
                          "causes scales with how the robot slides, which a model robot built differently gets wrong: "
                          "the direction is read off the drift, the size only as well as the model slides like the "
                          "robot.", "", "| gait | tilt from this gait alone (°) | slide per cycle, measured / model (mm) |",
                          "|---|---|---|"]
                for g in disc["per_group"]:
                    tg = g.get("tilt_deg")
                    sl = g.get("slide_mm")
                    lines.append(f"| {g['amplitude_deg']:g}° {g['chirality']} | "
                                 + (f"({tg[0]:+.3g}, {tg[1]:+.3g})" if tg else "–") + " | "
                                 + (f"{sl[0]:.3g} / {sl[1]:.3g}" if sl else "–") + " |")
                for g in tf.get("uphill_groups", []):
                    lines.append(f"| {g['amplitude_deg']:g}° {g['chirality']} | left out: the model robot drifts "
                                 "uphill on a tilted plate here, so this gait does not size a tilt | – |")
        elif tf.get("uphill_groups"):
            lines += ["", "No tilt fitted: in no gait does the model robot drift downhill on a tilted plate "
                      "(pulled the way the data drift, it drifts against that way), so the model cannot size one."]
        lines.append("")
    return lines


def hypotheses_markdown(hyps: list) -> list[str]:
    """The nominal stage's joint hypotheses: each fitted with the nominal parameters (and, in the second pass,
    with the effect accepted first), its values, gains and whether it was added; or why it was not tried."""
    if not hyps:
        return []
    lines = ["## Joint hypotheses (fitted with the nominal parameters)", "",
             "Effects that a nominal fit alone would absorb, each fitted jointly with the nominal parameters; the "
             "one accepted with the largest held-out gain is added, then each other one is fitted beside it and "
             "judged against it the same way (docs/calibration.md, \"Two joint hypotheses at once\").", "",
             "| effect | fitted beside | fitted | held-out gain | BIC gain | rule | added |", "|---|---|---|---|---|---|---|"]
    for h in hyps:
        beside = h.get("beside") or "–"
        if not h.get("tried", True):
            lines.append(f"| {h['effect']} | {beside} | not tried: {h.get('reason', '')} | – | – | – | no |")
            continue
        vals = ", ".join(f"{k} {_num(v, '.3g')}" for k, v in (h.get("values") or {}).items())
        lines.append(f"| {h['effect']} | {beside} | {vals} | {h['heldout_gain']:+.0%} | {h['bic_gain']:.1f} | "
                     f"{h.get('rule', '')} | {'**yes**' if h['accepted'] else 'no'} |")
    return lines + [""]


def observables_markdown(obs: dict | None) -> list[str]:
    """The table of observables: measured, and the model at each stage (calibrate.observables)."""
    if not obs or not any(obs.values()):
        return []
    stages = [k for k in next(r for rows in obs.values() for r in rows) if k not in ("gait", "measured", "robot")]
    lines = ["## What the fitted values mean on the tracks", "",
             "Quantities read off the tracks the same way for the data and for the model (all trials): the **arm "
             "delay** from the command's switch to the arm crossing its midpoint (ms, mean over swings after the "
             "first half period), the **phase lead** of a robot's swings over robot 0's (periods), the **plate "
             "drift** with the body-frame step taken out (mm/s, x and y), the length of that **body-frame step** "
             "(mm/cycle), the lone robots' **rotation** (deg/cycle) and the **arm rise** from a quarter to three "
             "quarters of a swing (ms: a lag lengthens it, a dead time does not). A structural effect's share is the "
             "final model minus the final model without it. ± is one standard error; ✓: the model agrees with "
             "the measured value within 95 %.", "",
             "| observable | gait | measured | " + " | ".join(stages) + " |", "|---|---|---|" + "---|" * len(stages)]

    def one(m, ref=None):
        if m is None:
            return "–"
        ok = "" if ref is None else (" ✓" if reproduced(ref, m) else "")
        if "v" in m:
            return (f"({m['v'][0]:+.4f}, {m['v'][1]:+.4f}) ± ({m['se'][0]:.4f}, {m['se'][1]:.4f}){ok}")
        return f"{m['mean']:.4g} ± {_num(m['se'], '.2g')}{ok}"

    for kind, rows in obs.items():
        for r in rows:
            label = LABELS[kind] + (f", robot {r['robot']}" if "robot" in r else "")
            lines.append(f"| {label} | {r['gait']} | {one(r['measured'])} | "
                         + " | ".join(one(r.get(k), r["measured"]) for k in stages) + " |")
    return lines + [""]
