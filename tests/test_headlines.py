"""The headline figures on the README and the docs are the result files' figures.

Each check formats a number from the JSON a benchmark or ``smx validate``
wrote, the way the page prints it, and looks for that phrase on the page
(line breaks read as spaces). A re-run that moves a number, or a page
edited by hand away from its result, fails here until the page says what
the file says.
"""

import json
import pathlib
import re
import sys

import pytest

from smarticle_mjx.scene import SceneParams
from smarticle_mjx.validate import page as V

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def _json(name: str) -> dict:
    return json.loads((RESULTS / name).read_text())


def _page(name: str) -> str:
    return re.sub(r"\s+", " ", (ROOT / name).read_text())


def _full_scan() -> list[tuple[str, str]]:
    d = _json("full_scan_75.json")
    minutes = f"{d['wall_s'] / 60:.0f}"
    return [("README.md", f"took {minutes} minutes ({d['steps_per_s'] / 1e3:.0f}k steps/s) with "
                          f"{d['peak_rss_mib']:.0f} MiB peak memory"),
            ("docs/engine.md", f"**{d['wall_s']:.0f} s ({minutes} min)**"),
            ("docs/engine.md", f"{d['peak_rss_mib']:.0f} MiB RSS"),
            ("docs/timestep.md", f"**{d['wall_s']:.0f} s ({minutes} min)**")]


def _early_exit() -> list[tuple[str, str]]:
    d = _json("early_exit.json")
    row = next(r for r in d["rows"] if r["quiet_periods"] == 2)  # the default rule
    changed = round(row["changed_bound_end"] * d["valid"])
    saved = f"{row['saved_work']:.0%}".replace("%", " %")
    return [("README.md", f"changed {changed} of {d['valid']} labels"),
            ("README.md", f"early exit saved {saved} of the work"),
            ("docs/engine.md", f"**{changed} of {d['valid']}**")]


def _claims() -> list[tuple[str, str]]:
    """The count of claims that hold, at the page's step and at the reference step."""
    result = json.loads((ROOT / "docs" / "validation" / "validation.json").read_text())
    total = len(result["rows"])
    held = sum(r["verdict"] == "holds" for r in result["rows"])
    from smarticle_mjx.validate.claims import Validation
    step = SceneParams().timestep * 1e3  # the page is made with the default model at its step
    check = V.step_check(Validation.from_json(result), result["model"], {step})[0]
    held_ref = int(re.search(r"\*\*(\d+) of \d+ claims hold\*\*", check).group(1))
    return [("docs/validation.md", f"**{held} of {total} claims hold** at this step"),
            ("docs/validation.md", f"time step {step:g} ms"),
            ("docs/validation.md", check),
            ("README.md", f"**{held} of {total} claims hold** at this step and {held_ref} of {total} with the "
                          "reference step's verdicts"),
            ("docs/fidelity.md", f"{held} of {total} hold at the {step:g} ms default, {held_ref} of {total} with the "
                                 "reference step's verdict")]


def _relax_and_lone() -> list[tuple[str, str]]:
    ex = json.loads((ROOT / "docs" / "validation" / "validation.json").read_text())["extra"]
    r = ex["relax"]
    lone = ex["single"]["90.0"]["net_W_per_cycle"]
    return [("README.md", f"gliders emerge in {r['emerged']} of {r['valid']} trials"),
            ("README.md", f"travel {r['distance']['mean']:.2f} W against 2.9 W"),
            ("README.md", f"the lone robot's drift ({lone:.0e} W per cycle against 1.5e-3)")]


def _glider_step() -> list[tuple[str, str]]:
    runs = _json("glider_step.json")["runs"]
    fmt = lambda b: f"β {b['value']:.2f} [{b['ci95'][0]:.2f}, {b['ci95'][1]:.2f}]"  # noqa: E731
    ref, half = runs["0.0625 ms (reference)"]["beta"], runs["0.5 ms"]["beta"]
    return [("README.md", f"{fmt(half)} at the 0.5 ms step"),
            ("README.md", f"{fmt(ref)} at a 0.0625 ms reference"),
            ("docs/model.md", f"{fmt(half)} at 0.5 ms against {fmt(ref)} at the 0.0625 ms reference")]


def _engine() -> list[tuple[str, str]]:
    d = _json("engine.json")
    native = [r["steps_per_s"] for r in d["throughput"] if r["backend"] == "native" and r["batch"] >= 4]
    return [("README.md", f"{min(native) / 1e3:.0f}–{max(native) / 1e3:.0f}k pair-scene steps/s on 2 cores "
                          f"at 4–{max(r['batch'] for r in d['throughput'] if r['backend'] == 'native')} lanes")]


def _agreement() -> list[tuple[str, str]]:
    mjx, warp = _json("backend_agreement.json"), _json("backend_agreement_gpu_analytic_h200.json")
    # the label check of the default numerics (SceneParams' own step: the README quotes the default's)
    labels = _json("timestep_candidates.json")[f"labels:implicitfast-{SceneParams.timestep * 1e3:g}ms"]
    return [("README.md", f"MJX and native agree on {100 * mjx['agree_bound_end']:.1f} % of bound/unbound labels "
                          f"over {mjx['configs']} configurations × {mjx['periods']} periods"),
            ("README.md", f"MuJoCo Warp and native agree on {100 * warp['warp_vs_native_agree_bound_end']:.1f} %"),
            ("README.md", f"agree with a 0.0625 ms reference on {100 * labels['agree']:.2f} % of {labels['n']} "
                          f"configurations (exact 95 % interval {100 * labels['agree_lo']:.1f}–"
                          f"{100 * labels['agree_hi']:.1f} %)")]


def _twin() -> list[tuple[str, str]]:
    """The cross-engine study: glider net speeds in the table and the prose, P_b and the lone slips."""
    d = _json("twin.json")
    out = []
    glide = {k: e["glide_32x60_s1"] for k, e in d["pairs"].items() if "glide_32x60_s1" in e}
    for key, g in glide.items():
        lo, hi = g["net_speed_interval"]
        out.append(("docs/twin.md", f"{g['net_speed_W_per_period']:.4f} [{lo:.4f}, {hi:.4f}]"))
    for key, name in (("dart", "DART's gliders"), ("mujoco", "MuJoCo's")):
        g = glide[key]
        lo, hi = g["net_speed_interval"]
        out.append(("docs/twin.md", f"{g['net_speed_W_per_period']:.4f} W per period" if key == "dart" else
                    f"{name} {g['net_speed_W_per_period']:.4f} ({lo:.4f}–{hi:.4f}, {g['gliders']} gliders)"))
    for key, e in d["pairs"].items():
        for name, v in e.items():
            if name.startswith("pb"):
                out.append(("docs/twin.md", f"{v['end'][0]:.2f} [{v['end'][1]:.2f}, {v['end'][2]:.2f}] ({v['n']})"))
    for key in ("dart fcl-mesh 0.1 ms, 90 deg", "mujoco 0.5 ms, 90 deg"):
        out.append(("docs/twin.md", f"{d['lone'][key]['slip_per_edge_W']:.1e}"))
    return out


def _warp_box_pairs() -> list[tuple[str, str]]:
    """The paper scan on Warp with analytic box pairs (0.4.2) beside MuJoCo C's at the same step, and the
    rerun of the lanes GJK/EPA had flagged."""
    gpu, cpu = _json("full_scan_gpu_analytic_h200.json"), _json("full_scan_75_0.25ms.json")
    rerun = _json("warp_flags_analytic_box_h200.json")
    bound = f"{100 * gpu['bound_end_fraction']:.2f} %"
    flagged = "none" if gpu["nonfinite_or_penetration_lanes"] == 0 else gpu["nonfinite_or_penetration_lanes"]
    return [("README.md", f"flagged {flagged} and left {bound} of its {gpu['valid']} valid lanes bound at the "
                          f"end, against MuJoCo C's "
                          f"{100 * cpu['bound_end_fraction']:.2f} %"),
            ("docs/engine.md", f"| {gpu['valid']} | **{gpu['nonfinite_or_penetration_lanes']}** | **{bound}** | "
                               f"{gpu['wall_s']:.0f} s |"),
            ("docs/engine.md", f"none flagged**, in {rerun['lane_periods']:,} lane-periods"),
            ("docs/engine.md", f"{rerun['deepest_mm_rerun_of_flagged']['min']:.2f}–"
                               f"{rerun['deepest_mm_rerun_of_flagged']['max']:.2f} mm in the flagged lanes")]


def _recount() -> list[tuple[str, str]]:
    """The discovery counted four ways (benchmarks/discovery_recount.py): the primary reading's count, interval
    and Fisher's p, the glider's distance under it, and chains followed by overlap, at the top of
    docs/relax.md and in the README."""
    d = _json("discovery_recount.json")
    r = d["emergence"]["readings"][d["emergence"]["primary"]]
    lo, hi = r["interval"]
    frac = f"{r['emerged']}/{r['trials']} = {r['fraction']:.2f} [{lo:.2f}, {hi:.2f}]"
    dist = f"{r['distance']['mean']:.2f} ± {r['distance']['sem']:.2f} W"
    ov = d["chains"]["overlap"]
    return [("docs/relax.md", frac), ("docs/relax.md", f"Fisher's p = {r['fisher_p']:.2g}"),
            ("docs/relax.md", dist), ("docs/relax.md", f"{ov['mean']:.1f} periods"),
            ("README.md", frac), ("README.md", dist)]


HEADLINES = {"discovery recount": _recount, "twin": _twin, "warp box pairs": _warp_box_pairs, "full scan": _full_scan, "early exit": _early_exit, "claims": _claims,
             "relaxation and lone robot": _relax_and_lone, "glider step": _glider_step, "engine": _engine,
             "backend agreement": _agreement}


@pytest.mark.parametrize("name", list(HEADLINES))
def test_headline_figures_are_the_result_files(name):
    missing = [f"{page}: {phrase!r}" for page, phrase in HEADLINES[name]() if phrase not in _page(page)]
    assert not missing, "pages disagree with their result files:\n" + "\n".join(missing)


def test_a_page_that_moved_away_from_its_file_is_caught(monkeypatch):
    """The check reads the file: a result file whose number changed (here the
    early-exit replay, one more label changed) no longer matches the page."""
    real = _json

    def edited(name):
        d = real(name)
        if name == "early_exit.json":
            for r in d["rows"]:
                r["changed_bound_end"] += 1 / d["valid"]
        return d

    monkeypatch.setattr(sys.modules[__name__], "_json", edited)
    with pytest.raises(AssertionError, match="changed 1 of"):
        test_headline_figures_are_the_result_files("early exit")
