"""The study's plots (matplotlib, Agg): PNG bytes of ghosting curves, error against history length,
the references' convergence and speed against error with its Pareto front."""
from __future__ import annotations

import io

import numpy as np


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def pareto(points: dict[str, tuple[float, float]]) -> set[str]:
    """Labels not dominated in (time lower, error lower)."""
    front = set()
    for a, (ta, ea) in points.items():
        if not any((tb <= ta and eb <= ea) and (tb < ta or eb < ea) for b, (tb, eb) in points.items() if b != a):
            front.add(a)
    return front


def history(scene: str, per_label: dict, thesis_history: int) -> bytes:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.4))
    for l, per in per_label.items():
        ns = sorted(per)
        ax.plot(ns, [min(per[n]["psnr"], 99) for n in ns], marker=".", lw=0.9, label=l)
    ax.axvline(thesis_history, color="k", ls=":", lw=0.8, label=f"thesis ({thesis_history})")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("frames of history")
    ax.set_ylabel("PSNR (dB)")
    ax.set_title(f"TAA convergence: {scene}")
    ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    return fig_bytes(fig)


def fig_bytes(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    import matplotlib.pyplot as plt
    plt.close(fig)
    return buf.getvalue()


def series(res) -> bytes:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.2))
    for l in res.per_frame:
        ax.plot(res.frames, [min(res.per_frame[l][t]["psnr"], 99) for t in res.frames], label=l)
    ax.set_xlabel("frame")
    ax.set_ylabel("PSNR (dB)")
    ax.set_title(f"Ghosting test: {res.scene}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig_bytes(fig)


def convergence(refs) -> bytes:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for name, r in refs.items():
        h = r.noise_history
        if h:
            ax.plot([x[0] for x in h], [x[2] for x in h], label=name, lw=0.9)
    ax.set_xscale("log")
    ax.set_xlabel("samples per pixel")
    ax.set_ylabel("reference noise PSNR (dB)")
    ax.legend(fontsize=5, ncol=2)
    fig.tight_layout()
    return fig_bytes(fig)


def speed(statics) -> bytes:
    """Median total cost against mean FLIP, one marker per technique, labelled beside it; the legend
    sits outside the axes so it covers no point."""
    plt = _pyplot()
    labels = list(statics[0].per_frame)
    med = {l: (float(np.median([r.ms[l] for r in statics])),
               float(np.mean([r.per_frame[l][r.frames[-1]]["flip_ldr"] for r in statics]))) for l in labels}
    fig, ax = plt.subplots(figsize=(8, 4))
    markers = "osD^vP*Xh<>p"
    for i, l in enumerate(labels):
        x, y = med[l]
        ax.scatter([x], [y], marker=markers[i % len(markers)], s=36, label=l, zorder=3)
        ax.annotate(l, (x, y), textcoords="offset points", xytext=(5, 4 if i % 2 else -9), fontsize=6)
    front = sorted(pareto(med), key=lambda l: med[l][0])
    ax.plot([med[l][0] for l in front], [med[l][1] for l in front], "k--", lw=0.8, label="Pareto front", zorder=2)
    ax.set_xscale("log")
    ax.set_xlabel("total ms per output frame (samples shaded + resolve; median over scenes)")
    ax.set_ylabel("mean FLIP (LDR)")
    ax.margins(x=0.15, y=0.12)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    return fig_bytes(fig)


def vdp_maps(res, maps: dict) -> bytes:
    """ColorVideoVDP's difference map of each judged column's last frame (maps: label -> map),
    with its JOD: where a viewer would see the ghost or the flicker."""
    plt = _pyplot()
    labels = list(maps)
    cols = min(4, len(labels))
    rows = (len(labels) + cols - 1) // cols
    h, w = next(iter(maps.values())).shape
    fig, axes = plt.subplots(rows, cols, figsize=(2.6 * cols, 2.6 * cols * h / w * rows / cols + 0.5 * rows),
                             squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, l in zip(axes.flat, labels):
        ax.imshow(np.clip(maps[l], 0, 1), cmap="magma", vmin=0, vmax=1, interpolation="nearest")
        ax.set_title(f"{l}: {res.jod[l]['sequence']:.2f} JOD", fontsize=7)
    fig.suptitle(f"ColorVideoVDP difference, last frame: {res.scene} ({res.test})", fontsize=8)
    fig.tight_layout()
    return fig_bytes(fig)


OVERVIEW_COLOURS = ("#7f7f7f", "#e377c2", "#17becf", "#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd")


def overview(results, columns: dict, thesis: dict | None = None, title: str = "") -> bytes:
    """The study's question at a glance: per scene (rows) each column's PSNR as a dot with its ±
    reference uncertainty (study.metrics.uncertainty) as a bar, and the thesis's published PSNR of
    the same column as a hollow ring where the thesis has that scene.

    results: TestResults of one static view; columns: shown name -> technique label (e.g. the thesis's
    columns, study.config.profile.thesis_roles); thesis: scene -> {shown name: PSNR}."""
    plt = _pyplot()
    rows = [r for r in results if any(l in r.per_frame for l in columns.values())]
    fig, ax = plt.subplots(figsize=(6.2, 0.34 * max(len(rows), 3) + 1.3))
    k = len(columns)
    for j, (name, label) in enumerate(columns.items()):
        colour = OVERVIEW_COLOURS[j % len(OVERVIEW_COLOURS)]
        off = (j - (k - 1) / 2) * 0.12
        ys, xs, es, ty, tx = [], [], [], [], []
        for i, r in enumerate(rows):
            if label not in r.per_frame:
                continue
            n = r.frames[-1]
            v = r.per_frame[label][n].get("psnr")
            if v is None or not np.isfinite(v):
                continue
            u = r.uncertainty.get(label, {}).get(n, {}).get("psnr")
            ys.append(i + off)
            xs.append(v)
            es.append(u if u is not None and np.isfinite(u) else 0.0)
            tv = (thesis or {}).get(r.scene, {}).get(name)
            if tv is not None:
                ty.append(i + off)
                tx.append(tv)
        ax.errorbar(xs, ys, xerr=es, fmt="o", ms=4.5, color=colour, ecolor=colour, elinewidth=1.2, capsize=2,
                    label=name, zorder=3)
        if tx:
            ax.scatter(tx, ty, s=30, facecolors="none", edgecolors=colour, linewidths=1.0, zorder=2)
    ax.set_yticks(range(len(rows)), [r.scene for r in rows], fontsize=8)
    ax.set_ylim(len(rows) - 0.5, -0.5)
    for i in range(1, len(rows)):
        ax.axhline(i - 0.5, color="#e5e5e5", lw=0.6, zorder=0)
    ax.grid(axis="x", color="#eeeeee", lw=0.6)
    ax.set_xlabel("PSNR (dB), higher is better; dot: ours ± reference uncertainty, ring: the thesis's (at 1600x900)", fontsize=7)
    ax.tick_params(axis="x", labelsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.16 - 0.3 / max(len(rows), 3)),
              ncol=min(k, 5), frameon=False, handletextpad=0.2, columnspacing=0.9)
    fig.tight_layout()
    return fig_bytes(fig)
