"""Figures from stores, drawn the way the paper draws them (matplotlib)."""

from __future__ import annotations

import pathlib

import numpy as np

from .reduce import binding
from .store import Store

# the paper's phase-diagram colours: attracted red, repelled cyan, invalid white
COLOURS = {binding.ATTRACTED: "#d62728", binding.REPELLED: "#17becf", binding.INVALID: "#ffffff"}


def _mpl():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def phase_diagram(store_path, out_dir, run: str | None = None, formats=("png", "svg")) -> list[pathlib.Path]:
    """(theta, phi) phase diagram of one run, plus |r| projections for random scans.

    Returns the files written.
    """
    plt = _mpl()
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
    fig.tight_layout()
    written = []
    for fmt in formats:
        path = out_dir / f"phase_diagram_{run}.{fmt}"
        fig.savefig(path, dpi=150)
        written.append(path)
    plt.close(fig)
    return written
