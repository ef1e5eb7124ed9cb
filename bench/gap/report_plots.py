"""The diagnosis page's two figures: the gap map and the residuals with
their spectra, before and after the named effect."""

from __future__ import annotations

import numpy as np

from bench.gap import localise
from bench.report import matplotlib_agg

SHORT = {
    "pose position": "pose pos",
    "pose attitude": "pose att",
    "imu accel vs valves": "accel-valves",
    "gyro vs valve torques": "gyro-torques",
}


def _map_grid(cells) -> tuple:
    """(rows, cols, z): the gap map's cells as a (stream axis) x (regime stat) grid."""
    rows = [(s, a) for s, _, _ in localise.STREAMS for a in "xyz"]
    rows += [(s, a) for s, _ in localise.DYN_STREAMS for a in "xyz"]
    cols = [(r, st) for r in localise.REGIMES for st in localise.STATS if r == "all" or st in ("mean", "variance")]
    z = np.full((len(rows), len(cols)), np.nan)
    for c in cells:
        if (c["regime"], c["stat"]) in cols:
            z[rows.index((c["stream"], c["axis"])), cols.index((c["regime"], c["stat"]))] = c["z"]
    return rows, cols, z


def gap_map_figure(cells, threshold: float):
    """The gap map on a symmetric log colour scale (linear within +-1, so a
    cell at z = 7 is coloured as clearly as one at 200), cells beyond the
    detection threshold boxed and the threshold marked on the colour bar."""
    from matplotlib.colors import SymLogNorm
    from matplotlib.patches import Rectangle

    plt = matplotlib_agg()
    rows, cols, z = _map_grid(cells)
    fig, ax = plt.subplots(figsize=(10, 5.4))
    top = float(np.nanmax(np.abs(z))) if np.isfinite(z).any() else 1.0
    lim = max(2.0 * threshold, top)
    norm = SymLogNorm(linthresh=1.0, linscale=0.5, vmin=-lim, vmax=lim, base=10)
    im = ax.imshow(z, cmap="RdBu_r", norm=norm, aspect="auto")
    ax.set_yticks(range(len(rows)), [f"{SHORT[s]} {a}" for s, a in rows])
    ax.set_xticks(range(len(cols)), [f"{r}\n{s}" for r, s in cols], fontsize=7)
    ax.set_xlabel("flight regime and statistic")
    ax.set_ylabel("stream and axis (pose pos: Hill frame; others: body)")
    for i, j in zip(*np.nonzero(np.isfinite(z))):
        beyond = abs(z[i, j]) > threshold
        dark = abs(z[i, j]) > min(lim / 3.0, 3.0 * threshold)
        ax.text(j, i, f"{z[i, j]:.1f}", ha="center", va="center", fontsize=6, color="w" if dark else "k")
        if beyond:
            # inset, so a cell between boxed neighbours does not look boxed itself
            ax.add_patch(Rectangle((j - 0.42, i - 0.38), 0.84, 0.76, fill=False, ec="k", lw=1.4))
    ticks = [v for m in (1.0, 10.0, 100.0, 1000.0) if m <= lim for v in (-m, m)] + [0.0]
    bar = fig.colorbar(im, ax=ax, ticks=sorted(ticks), format="%g", label="z [noise sigmas]: N(0, 1) under the null")
    for v in (-threshold, threshold):
        bar.ax.axhline(v, color="k", lw=1.5)
        bar.ax.text(-0.1, v, f"{v:+.1f}", transform=bar.ax.get_yaxis_transform(), ha="right", va="center", fontsize=7)
    ax.set_title(f"Gap map: whitened residuals; boxed: |z| above the detection threshold {threshold:.1f}", fontsize=10)
    fig.tight_layout()
    return fig


def _running_mean(t, v, window_s: float) -> tuple:
    """Mean of v over windows of window_s, at each window's centre."""
    ok = np.isfinite(v)
    t, v = t[ok], v[ok]
    if t.size < 2:
        return t, v
    edges = np.arange(t[0], t[-1] + window_s, window_s)
    k = np.digitize(t, edges)
    keep = [i for i in np.unique(k) if np.sum(k == i) >= 3]
    return np.array([t[k == i].mean() for i in keep]), np.array([v[k == i].mean() for i in keep])


def _welch(vals, dt: float):
    """Welch's averaged periodogram of the finite samples: (f [Hz], PSD [sigma^2/Hz]), or None."""
    from scipy.signal import welch

    x = vals[np.isfinite(vals)]
    if x.size < 16:
        return None
    f, p = welch(x, fs=1.0 / dt, nperseg=min(256, max(16, x.size // 8)))
    return f[1:], p[1:]


def _residual_row(ax_t, ax_f, row, label: str, window_s: float) -> None:
    name, t, before, after, held, dt = row
    for vals, color, text, lw in ((before, "0.35", "nominal", 1.6), (after, "C3", f"with {label}", 1.0)):
        if vals is None:
            continue
        ax_t.plot(t, vals, ".", ms=1.5, color=color, alpha=0.35)
        ax_t.plot(*_running_mean(t, vals, window_s), "-", color=color, lw=lw, label=f"{text} ({window_s:.0f} s mean)")
        spec = _welch(vals, dt)
        if spec is not None:
            ax_f.semilogy(*spec, color=color, lw=lw, ls="-" if text == "nominal" else "--", label=text)
    ax_t.axhline(0, color="k", lw=0.5)
    ax_t.set_ylabel(f"{name}\n[noise sigmas]", fontsize=8)
    for t0, t1 in _spans(t, held):
        ax_t.axvspan(t0, t1, color="C0", alpha=0.08, lw=0)
    ax_f.axhline(2.0 * dt, color="k", lw=0.6, ls=":", label="white noise")
    ax_f.set_ylabel("PSD [sigma^2/Hz]", fontsize=8)


def residuals_figure(series, label: str, what: str, origin_s: float = 0.0):
    """series: [(name, t, before, after or None, held mask, sample interval)],
    one row each: whitened residuals over time with their running mean
    (held-out blocks shaded), and their Welch spectrum against white noise."""
    plt = matplotlib_agg()
    fig, ax = plt.subplots(len(series), 2, figsize=(11, 1.9 * len(series)), sharex="col", squeeze=False)
    span = max(float(np.nanmax(r[1]) - np.nanmin(r[1])) if len(r[1]) else 0.0 for r in series)
    window_s = max(1.0, round(span / 60.0))
    for i, row in enumerate(series):
        _residual_row(ax[i, 0], ax[i, 1], row, label, window_s)
    ax[0, 0].legend(loc="upper right", fontsize=7)
    ax[0, 1].legend(loc="upper right", fontsize=7)
    ax[0, 0].set_title(what, fontsize=9)
    ax[0, 1].set_title("Welch spectra (one-sided)", fontsize=9)
    since = f" from {origin_s:.0f} s" if origin_s else ""
    ax[-1, 0].set_xlabel(f"time [s]{since} (shaded: held-out blocks)")
    ax[-1, 1].set_xlabel("frequency [Hz]")
    fig.tight_layout()
    return fig


def _spans(t, mask):
    out, start = [], None
    for ti, m in zip(t, mask):
        if m and start is None:
            start = ti
        if not m and start is not None:
            out.append((start, ti))
            start = None
    if start is not None:
        out.append((start, t[-1]))
    return out


def save(fig, path, dpi: int = 110) -> None:
    plt = matplotlib_agg()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
