"""Figures from stores, drawn the way the paper draws them (matplotlib)."""

from __future__ import annotations

import pathlib

import numpy as np

from .reduce import binding
from .store import Store

# the paper's phase-diagram colours: attracted red, repelled cyan, invalid white
COLOURS = {binding.ATTRACTED: "#d62728", binding.REPELLED: "#17becf", binding.INVALID: "#ffffff"}


def pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def phase_diagram(store_path, out_dir, run: str | None = None, formats=("png", "svg"),
                  stem: str | None = None) -> list[pathlib.Path]:
    """(theta, phi) phase diagram of one run, plus |r| projections for random scans.

    Returns the files written.
    """
    plt = pyplot()
    st = Store(store_path)
    run = run or st.runs[0]
    d = st.run(run, fields=("config", "valid", "touched"))
    lab = binding.labels(d["touched"][:, :, 0], d["valid"])
    r, th, ph = d["config"].T
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    polar = st.config["scan"]["configs"] == "polar"
    fig, axes = plt.subplots(1, 1 if polar else 3, figsize=(5.2 if polar else 14, 4.6), squeeze=False)
    ax = axes[0, 0]
    ax.set_facecolor("#f2f2f2")
    for code in (binding.INVALID, binding.REPELLED, binding.ATTRACTED):
        sel = lab == code
        name = {binding.ATTRACTED: "attracted", binding.REPELLED: "repelled", binding.INVALID: "invalid"}[code]
        ax.scatter(np.degrees(th[sel]), np.degrees(ph[sel]), s=14 if polar else 6, c=COLOURS[code],
                   edgecolors="#999999" if code == binding.INVALID else "none", linewidths=0.3,
                   label=f"{name} ({sel.sum()})")
    ax.set(xlim=(0, 360), ylim=(0, 360), xlabel=r"$\theta$ (deg)", ylabel=r"$\phi$ (deg)")
    ax.set_xticks(range(0, 361, 90))
    ax.set_yticks(range(0, 361, 90))
    amp = st.run_attrs[run]["amplitude_deg"]
    title = (f"|r| = {st.config['scan']['radius_W']} W" if polar else "random (|r|, θ, φ)") + f", α_max = {amp:g}°"
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.9)
    if not polar:
        valid = lab != binding.INVALID
        bins = np.linspace(r[valid].min(), r[valid].max(), 21) if valid.any() else 20
        for ax2, (x, xl) in zip(axes[0, 1:], ((r, "|r| (W)"), (np.degrees(th), r"$\theta$ (deg)"))):
            for code in (binding.REPELLED, binding.ATTRACTED):
                ax2.hist(x[lab == code], bins=bins if xl == "|r| (W)" else np.linspace(0, 360, 25),
                         color=COLOURS[code], alpha=0.7, label="attracted" if code == 1 else "repelled")
            ax2.set(xlabel=xl, ylabel="initial conditions")
            ax2.legend(fontsize=7)
    return save_figure(fig, out_dir, stem or f"phase_diagram_{run}", formats, dpi=150)


KIND_COLOURS = {"C1": "#1f77b4", "C2": "#ff7f0e"}


def check_out_dir(out) -> None:
    """ValueError if the output folder ``out`` exists and is not a folder (checked before anything is drawn)."""
    out = pathlib.Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out} exists and is not a directory")


def save_figure(fig, out_dir, stem, formats=("png",), dpi=130) -> list[pathlib.Path]:
    plt = pyplot()
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    paths = []
    for fmt in formats:
        p = out_dir / f"{stem}.{fmt}"
        fig.savefig(p, dpi=dpi)
        paths.append(p)
    plt.close(fig)
    return paths


def pb_curve(amplitudes, end, throughout, out_dir, stem="pb", formats=("png", "svg")):
    """P_b(alpha_max): bound at the end (blue) and throughout (red), with intervals.

    ``end`` and ``throughout``: [A, 3] rows (p, lo, hi).
    """
    plt = pyplot()
    a = np.asarray(amplitudes, float)
    fig, ax = plt.subplots(figsize=(4.8, 3.6))
    for rows, colour, label in ((end, "#1f77b4", "bound at the end"), (throughout, "#d62728", "bound throughout")):
        rows = np.asarray(rows, float)
        ax.errorbar(a, rows[:, 0], yerr=[rows[:, 0] - rows[:, 1], rows[:, 2] - rows[:, 0]], color=colour,
                    marker="o", ms=4, capsize=3, label=label)
    ax.set(xlabel=r"$\alpha_{max}$ (deg)", ylabel=r"$P_b$", ylim=(0, 1), xlim=(0, 95))
    ax.legend(fontsize=8)
    ax.set_title("probability to bind (95% Clopper–Pearson)", fontsize=9)
    return save_figure(fig, out_dir, stem, formats)


def msd_curves(curves: dict, out_dir, stem="msd", formats=("png",)):
    """MSD vs delay (log-log) per amplitude; ``curves[label] = (lags, msd)`` in periods, W^2."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(4.8, 3.6))
    for label, (lags, m) in curves.items():
        ok = np.isfinite(m) & (m > 0)
        ax.loglog(np.asarray(lags)[ok], np.asarray(m)[ok], marker=".", label=label)
    ax.set(xlabel="delay (gait periods)", ylabel=r"$\langle\sigma^2\rangle$ (W$^2$)")
    if curves:
        ax.legend(fontsize=7)
    return save_figure(fig, out_dir, stem, formats)


def relative_coordinates(rel, kinds, clusters, out_dir, stem, title="", formats=("png",)):
    """Histograms of per-period |r|, theta, phi of bound pairs, C1 and C2 stacked,
    and the (theta, phi) plane with the cluster centres."""
    from .reduce import gliders as GL
    plt = pyplot()
    rel, kinds = np.asarray(rel, float), np.asarray(kinds)
    fig, axes = plt.subplots(1, 4, figsize=(15, 3.4))
    bins = (np.linspace(np.nanmin(rel[:, 0]) if len(rel) else 0, np.nanmax(rel[:, 0]) if len(rel) else 1, 31),
            np.linspace(0, 360, 37), np.linspace(0, 360, 37))
    for i, (ax, xl) in enumerate(zip(axes[:3], ("|r| (W)", r"$\theta$ (deg)", r"$\phi$ (deg)"))):
        x = rel[:, i] if i == 0 else np.degrees(rel[:, i]) % 360
        ax.hist([x[kinds == GL.C1], x[kinds == GL.C2]], bins=bins[i], stacked=True,
                color=[KIND_COLOURS["C1"], KIND_COLOURS["C2"]],
                label=[f"C1 ({(kinds == GL.C1).sum()})", f"C2 ({(kinds == GL.C2).sum()})"])
        ax.set(xlabel=xl, ylabel="bound periods")
    axes[0].legend(fontsize=7)
    ax = axes[3]
    for k, name in ((GL.C1, "C1"), (GL.C2, "C2")):
        s = kinds == k
        ax.scatter(np.degrees(rel[s, 1]) % 360, np.degrees(rel[s, 2]) % 360, s=2, alpha=0.3,
                   color=KIND_COLOURS[name])
    c = np.degrees(clusters.centers[:, 1:]) % 360
    ax.scatter(c[:, 0], c[:, 1], marker="x", s=60, c="k", label="k-means centres")
    ax.set(xlim=(0, 360), ylim=(0, 360), xlabel=r"$\theta$ (deg)", ylabel=r"$\phi$ (deg)")
    ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    return save_figure(fig, out_dir, stem, formats)


def lifetimes(runs, periods: int, out_dir, stem, title="", formats=("png",)):
    """Lifetime distributions of bound runs by glider type (``runs``: ``reduce.gliders.TypedRuns``)."""
    from .reduce import gliders as GL
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(4.8, 3.6))
    bins = np.linspace(0.5, periods + 0.5, min(periods, 25) + 1)
    for k, name in ((GL.C1, "C1"), (GL.C2, "C2")):
        s = runs.kind == k
        ax.hist(runs.length[s], bins=bins, histtype="step", lw=1.5, color=KIND_COLOURS[name],
                label=f"{name}: {s.sum()} runs, {runs.censored[s].sum()} still bound at the end")
    ax.set(xlabel="lifetime (consecutive bound periods)", ylabel="bound runs", yscale="log")
    ax.legend(fontsize=7)
    ax.set_title(title, fontsize=9)
    return save_figure(fig, out_dir, stem, formats)


def versus_amplitude(amplitudes, panels: dict, out_dir, stem="vs_amplitude", formats=("png",), marks=None):
    """One panel per quantity vs alpha_max; ``panels[ylabel] = (values, errors)``;
    errors per point are a symmetric half-width or a (below, above) pair, or None. ``marks[ylabel]``:
    (lo, hi, label), an amplitude interval shaded and labelled in that panel."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4), squeeze=False)
    for ax, (yl, (v, e)) in zip(axes[0], panels.items()):
        if e is not None:
            e = np.asarray(e, float)
            e = np.nan_to_num(e.T if e.ndim == 2 else e, nan=0.0)
        ax.errorbar(amplitudes, v, yerr=e, marker="o", ms=4, capsize=3)
        if marks and yl in marks:
            lo, hi, label = marks[yl]
            ax.axvspan(lo, hi, color="tab:orange", alpha=0.2, label=label)
            ax.legend(fontsize=7, loc="best")
        ax.set(xlabel=r"$\alpha_{max}$ (deg)", ylabel=yl)
    return save_figure(fig, out_dir, stem, formats)


def tracks(xy_list, labels, out_dir, stem, title="", formats=("png",)):
    """Tracks (x, y in W) side by side on equal axes."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(4.8, 4.4))
    for xy, lab in zip(xy_list, labels):
        xy = np.asarray(xy, float)
        ax.plot(xy[:, 0] - xy[0, 0], xy[:, 1] - xy[0, 1], lw=1, label=lab)
    ax.set(xlabel="x (W)", ylabel="y (W)", aspect="equal")
    ax.legend(fontsize=6)
    ax.set_title(title, fontsize=9)
    return save_figure(fig, out_dir, stem, formats)


def collision_sequence(coll: dict, lane: int, periods, out_dir, stem, title="", formats=("png",)):
    """A glider's collisions over one or more gait periods: per contact kind
    (rows) and bin of the period (columns), the contact impulse along r on
    robot i (red: attractive, pulls the robots together; blue: repulsive);
    blank where there was no contact. Gait quarters are marked: in each one
    arm moves, then both dwell.

    Args:
      coll: a collision record with a lane axis (``PeriodRecords.collisions``
        or a store's ``coll_*`` datasets as steps/impulse/impulse_r).
      lane: which lane; periods: which periods (one panel each).
    """
    from .reduce import collisions as RC
    plt = pyplot()
    periods = list(np.atleast_1d(periods))
    steps = np.asarray(coll["steps"])[lane, :, 0]  # pair 0: [K, kinds, bins]
    imp = np.asarray(coll["impulse_r"], float)[lane, :, 0] * 1e3  # mN s
    used = [k for k in range(len(RC.KINDS)) if steps[periods].sum(axis=(0, 2))[k] > 0] or [0]
    lim = max(np.abs(imp[periods][:, used]).max(), 1e-9)
    bins = steps.shape[-1]
    fig, axes = plt.subplots(1, len(periods), figsize=(3.6 * len(periods) + 1.2, 0.45 * len(used) + 1.6),
                             squeeze=False, sharey=True)
    for ax, k in zip(axes[0], periods):
        grid = np.where(steps[k][used] > 0, imp[k][used], np.nan)
        im = ax.imshow(grid, aspect="auto", cmap="RdBu_r", vmin=-lim, vmax=lim, interpolation="nearest",
                       extent=(0, 1, len(used) - 0.5, -0.5))
        for q in (0.25, 0.5, 0.75):
            ax.axvline(q, color="0.6", lw=0.6)
        ax.set_yticks(range(len(used)), [f"{RC.KINDS[u]}" for u in used])
        ax.set(xlabel=f"gait phase (period {k}, {bins} bins)")
    axes[0, 0].set_ylabel("contact (robot i part – robot j part)")
    fig.colorbar(im, ax=axes[0, -1], label="impulse along r on robot i (mN·s); > 0 attracts")
    if title:
        fig.suptitle(title, fontsize=9)
    return save_figure(fig, out_dir, stem, formats)


def relaxation_trial(xy, episodes, plate_half_W, out_dir, stem, title="", formats=("png",)):
    """One relaxation trial from above: every robot's body-centre track (W,
    thin grey, start marked), each glider's two robots while bound and its
    pair-centre track (end marked) in its type's colour, and the plate's edge.

    Args:
      xy: [K+1, N, 2] body centres in W, start first (NaN after an early stop).
      episodes: the trial's episodes (``reduce.relaxation.Episode``, from ``trial_episodes``).
      plate_half_W: half the plate's side in W (drawn if finite).
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(4.8, 4.6))
    xy = np.asarray(xy, float)
    for i in range(xy.shape[1]):
        t = xy[:, i][np.isfinite(xy[:, i]).all(-1)]
        ax.plot(t[:, 0], t[:, 1], color="0.6", lw=0.7)
        ax.plot(t[:1, 0], t[:1, 1], "o", color="0.3", ms=3)
        ax.annotate(str(i), t[0], fontsize=6, color="0.2")
    shown = set()
    for e in episodes:
        tr = np.asarray(e.track)
        lab = f"{e.kind} pair {e.pair[0]}-{e.pair[1]}, {e.lifetime} periods"
        colour = KIND_COLOURS[e.kind]
        for r in e.pair:  # the two robots' own tracks while bound, then the pair centre
            seg = xy[e.start:e.start + e.lifetime + 1, r]
            ax.plot(seg[:, 0], seg[:, 1], color=colour, lw=0.8, alpha=0.6)
        ax.plot(tr[:, 0], tr[:, 1], color=colour, lw=1.8, label=lab if lab not in shown else None)
        ax.plot(tr[-1:, 0], tr[-1:, 1], "s", color=colour, ms=4)
        shown.add(lab)
    if np.isfinite(plate_half_W):
        h = plate_half_W
        ax.plot([-h, h, h, -h, -h], [-h, -h, h, h, -h], color="k", lw=0.6, ls=":")
    fin = xy[np.isfinite(xy).all(-1)]
    if len(fin):
        lo, hi = fin.min(0) - 0.5, fin.max(0) + 0.5
        ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]))
    ax.set(xlabel="x (W)", ylabel="y (W)", aspect="equal")
    if shown:
        ax.legend(fontsize=6, loc="best")
    ax.set_title(title, fontsize=9)
    return save_figure(fig, out_dir, stem, formats)


def lifetime_contour(episodes, fit, min_periods, out_dir, stem="lifetime_contour", title="", formats=("png",)):
    """Contour length vs lifetime of every bound-and-apart episode (the
    paper's SI figure), coloured by type, with the fitted line; and the
    lifetimes of C1 and C2 episodes (censored ones hatched). ``episodes``: ``reduce.relaxation.Episode``
    objects; ``fit``: its ``ContourFit``."""
    plt = pyplot()
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(8.6, 3.6))
    for kind in ("C1", "C2"):
        ee = [e for e in episodes if e.kind == kind]
        if ee:
            ax.scatter([e.lifetime for e in ee], [e.contour_W for e in ee], s=10, alpha=0.7,
                       color=KIND_COLOURS[kind], label=f"{kind} ({len(ee)})")
    if np.isfinite(fit.slope) and episodes:
        x = np.array([0, max(e.lifetime for e in episodes)])
        ax.plot(x, fit.intercept + fit.slope * x, "k-", lw=1,
                label=f"fit: {fit.slope:.3g} W/period, r = {fit.r:.2f}")
    ax.axvline(min_periods, color="0.5", ls=":", lw=0.8)
    ax.set(xlabel="lifetime (periods)", ylabel="contour length (W)")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax.set_title(title or "bound pairs apart from the rest", fontsize=9)
    top = max([e.lifetime for e in episodes] + [min_periods, 2])
    bins = np.linspace(0, top + 1, 21)
    for kind in ("C1", "C2"):
        v = [e.lifetime for e in episodes if e.kind == kind]
        c = [e.lifetime for e in episodes if e.kind == kind and e.censored]
        if v:
            ax2.hist(v, bins=bins, histtype="step", color=KIND_COLOURS[kind], label=f"{kind}")
        if c:
            ax2.hist(c, bins=bins, color=KIND_COLOURS[kind], alpha=0.3, hatch="//", label=f"{kind} censored")
    ax2.set(xlabel="lifetime (periods)", ylabel="episodes")
    if episodes:
        ax2.set_yscale("log")
    if ax2.get_legend_handles_labels()[0]:
        ax2.legend(fontsize=7)
    ax2.set_title("lifetimes by type", fontsize=9)
    return save_figure(fig, out_dir, stem, formats)


def crowd(phi, in_chain, plateau_periods, chain_lifetimes, out_dir, stem="crowd", title="", formats=("png",)):
    """The crowd over a relaxation study: area fraction phi(t) (median and quartiles over trials,
    each trial's plateau start marked), robots in chains per period (mean over trials), and the
    lifetimes of chain episodes.

    Args:
      phi: [T, K + 1] per trial (NaN where undefined); in_chain: [T, K];
      plateau_periods: [T] plateau starts (NaN: censored); chain_lifetimes: every chain episode's lifetime.
    """
    plt = pyplot()
    fig, (ax, ax2, ax3) = plt.subplots(1, 3, figsize=(11, 3.4))
    phi = np.asarray(phi, float)
    if phi.size and np.isfinite(phi).any():
        with np.errstate(all="ignore"):
            import warnings
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                q = np.nanpercentile(phi, [25, 50, 75], axis=0)
        t = np.arange(phi.shape[1])
        ax.fill_between(t, q[0], q[2], color="C0", alpha=0.25, lw=0, label="quartiles")
        ax.plot(t, q[1], "C0-", lw=1.2, label="median")
        pl = np.asarray(plateau_periods, float)
        pl = pl[np.isfinite(pl)]
        if len(pl):
            ax.axvline(np.median(pl), color="k", ls="--", lw=0.8, label=f"median plateau start {np.median(pl):.0f}")
        ax.axvline(30, color="0.5", ls=":", lw=0.8, label="lab: ~30 periods")
        ax.legend(fontsize=7)
    ax.set(xlabel="period", ylabel="area fraction φ")
    ax.set_title(title or "area fraction (n W D / hull of centres)", fontsize=9)
    ic = np.asarray(in_chain, float)
    if ic.size:
        ax2.plot(np.arange(1, ic.shape[1] + 1), ic.mean(0), "C3-", lw=1)
    ax2.set(xlabel="period", ylabel="robots in chains (mean over trials)")
    life = np.asarray(chain_lifetimes, float)
    if life.size:
        ax3.hist(life, bins=np.arange(0, life.max() + 2) if life.max() < 60 else 40, color="C2")
    ax3.axvspan(8, 10, color="0.5", alpha=0.3, label="lab: 8-10 periods")
    ax3.set(xlabel="chain lifetime (periods)", ylabel="chain episodes")
    ax3.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, out_dir, stem, formats)
