"""figures.py: the figures of tacrl, drawn the way the paper draws them: learning curves smoothed over
15 episodes with a 95 % bootstrap band over seeds (Sec. 5.1.5; Figs. 7, 9-11, 14), the context
generalization bars (Fig. 12), what the policy sees in each context, and one episode's observations
and actions by phase (Fig. 16). Arrays in, PNG files out, for report.py (a run's own curves.png:
rundir.plot_curves).
"""

import cv2
import matplotlib

matplotlib.use("Agg")                      # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import sim  # noqa: E402
from rundir import CURVES, smooth  # noqa: E402

def bootstrap_band(curves, n=1000, seed=0):
    """curves: seeds x episodes -> mean and the 95% bootstrap interval of the mean over seeds."""
    c = np.array([x[:min(map(len, curves))] for x in curves])
    rng = np.random.default_rng(seed)
    boots = c[rng.integers(0, len(c), (n, len(c)))].mean(1)
    return c.mean(0), np.percentile(boots, 2.5, 0), np.percentile(boots, 97.5, 0)


def plot_groups(groups, keys, out, title):
    """One panel per key; in each, one line (mean over seeds) and band (95% bootstrap over seeds)
    per group of runs, against episode (the paper's Fig. 9-11). groups: {label: [run]}, each run a
    dict with 'cfg' (its config, for the seed) and 'm' ({metrics.csv column: array})."""
    fig, axs = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.6), squeeze=False)
    colours = plt.get_cmap("tab10").colors   # after 10 groups the colours come round again, dashed
    for ax, key in zip(axs[0], keys):
        for i, (name, runs) in enumerate(groups.items()):
            curves = [smooth(r["m"][key]) if key == "return" else r["m"][key] for r in runs]
            mean, lo, hi = bootstrap_band(curves)
            ep = np.arange(1, len(mean) + 1)
            seeds = sorted({r["cfg"]["seed"] for r in runs})
            label = f"{name} (seed{'s' * (len(seeds) > 1)} {', '.join(map(str, seeds))})"
            line, = ax.plot(ep, mean, lw=1.2, color=colours[i % len(colours)], ls="--" if i >= 10 else "-", label=label)
            if len(runs) > 1:
                ax.fill_between(ep, lo, hi, alpha=0.2, color=line.get_color())
        ax.set_xlabel("episode")
        ax.set_ylabel(CURVES[key])
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    handles, labels = axs[0][0].get_legend_handles_labels()
    if len(groups) <= 4 and max(map(len, labels)) <= 40:
        axs[0][0].legend(fontsize=7)
    elif len(groups) <= 4:                 # long labels: below the panels, off the data
        fig.legend(handles, labels, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, 0.0))
    else:                                  # many curves: the legend to the right, off the data
        fig.legend(handles, labels, fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)


def plot_context_bars(bars, out, title):
    """Fig. 12: mean cumulative reward (over the evaluated error ranges and trials) per context,
    one group of bars per ROI. bars: {roi label: {context: [mean, lo, hi]}}, lo-hi the interval drawn."""
    contexts = list(next(iter(bars.values())))
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    w = 0.8 / len(contexts)
    for k, ctx in enumerate(contexts):
        xs = np.arange(len(bars)) + (k - (len(contexts) - 1) / 2) * w
        m, lo, hi = np.array([bars[r][ctx] for r in bars]).T
        ax.bar(xs, m, w, yerr=[m - lo, hi - m], capsize=3, label=ctx)
    ax.set_xticks(np.arange(len(bars)))
    ax.set_xticklabels(list(bars))
    ax.axhline(0, color="k", lw=0.6)
    ax.set_ylabel("cumulative reward per episode")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_views(task, rois, contexts, out, error=(0.015, -0.010, 0.0, 0.05)):
    """What the policy sees: the first image of an episode with the same error in each context
    (columns) through each ROI (rows), so that Fig. 12's bars can be read against the pixels."""
    fig, ax = plt.subplots(len(rois), len(contexts), figsize=(2.2 * len(contexts), 2.3 * len(rois)), squeeze=False)
    for i, roi in enumerate(rois):
        for j, ctx in enumerate(contexts):
            env = sim.AssemblyEnv(task, ctx, roi=roi)
            try:
                obs, _ = env.reset(seed=0, options={"error": np.array(error)})   # the same sensor noise each time
            finally:
                env.close()
            ax[i, j].imshow(obs["image"][0], cmap="gray", vmin=0, vmax=255)   # (1, 80, 80) uint8
            ax[i, j].set_xticks([])
            ax[i, j].set_yticks([])
            ax[i, j].set_title(f"{ctx}, ROI {roi}", fontsize=8)
    fig.suptitle(f"{task}: the 80x80 image at X^_i, error {error[0] * 1000:g} / {error[1] * 1000:g} mm", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_inputs(rows, titles, out, title):
    """What the encoder reads: rows {label: (N, 80, 80) float}, one image an episode (columns, titled by
    `titles`), each row on its own grey scale from its 1st to its 99th percentile."""
    fig, ax = plt.subplots(len(rows), len(titles), figsize=(1.6 * len(titles), 1.75 * len(rows)), squeeze=False)
    for i, (label, imgs) in enumerate(rows.items()):
        lo, hi = np.percentile(imgs, (1, 99))
        for j, img in enumerate(imgs):
            ax[i, j].imshow(img, cmap="gray", vmin=lo, vmax=hi)
            ax[i, j].set_xticks([])
            ax[i, j].set_yticks([])
            ax[i, j].set_title(titles[j] if i == 0 else "", fontsize=7)
        ax[i, 0].set_ylabel(label, fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_behaviour(rec, out, title):
    """Fig. 16: one episode, observations and actions scaled to [-1, 1] per channel, over its phases.
    rec: per policy step, 'image' (T, 80, 80) and its 'saliency' (T, 80, 80), 'image_features' (T, 6),
    'goal_offset' (T, 4) X - X_g, 'f_world' (T, 6), 'action' (T, 6) and 'phase' (T,): 0 free motion, 1 search
    after contact, 2 insertion."""
    norm = lambda x: np.array(x) / np.maximum(np.abs(np.array(x)).max(0), 1e-9)   # noqa: E731
    panels = [("image features", norm(rec["image_features"])),
              ("relative pose X - X_g (x, y, z, yaw)", norm(rec["goal_offset"])),
              ("wrench (Fx, Fy, Fz, Tx, Ty, Tz)", norm(rec["f_world"])), ("action (F_d, 6-D)", np.array(rec["action"]))]
    phase = np.asarray(rec["phase"])
    t = np.arange(1, len(phase) + 1)
    # the top row: the image at the first step, where each phase begins and at the end, with its saliency
    # over it in red, opaque where the pixels move the lateral F_d most (each image on its own scale)
    shown = sorted({0, len(phase) - 1, *[int(np.argmax(phase == ph)) for ph in (1, 2) if (phase == ph).any()]})
    fig = plt.figure(figsize=(7, 10))
    grid = fig.add_gridspec(len(panels) + 1, len(shown), height_ratios=[1.6] + [1] * len(panels))
    for j, i in enumerate(shown):
        x = fig.add_subplot(grid[0, j])
        x.imshow(rec["image"][i], cmap="gray", vmin=0, vmax=255)
        sal = cv2.GaussianBlur(np.asarray(rec["saliency"][i], np.float32), (0, 0), 1.5)  # a pixel's gradient is noisy
        overlay = np.zeros((*sal.shape, 4))
        overlay[..., 0] = 1.0
        overlay[..., 3] = 0.9 * (sal / max(sal.max(), 1e-12)) ** 2        # squared: the peaks stand out
        x.imshow(overlay)
        x.set_title(f"step {i + 1} ({('free', 'contact', 'insertion')[phase[i]]})", fontsize=8)
        x.axis("off")
    ax = [fig.add_subplot(grid[k + 1, :]) for k in range(len(panels))]
    for x, (name, y) in zip(ax, panels):
        x.plot(t, y, lw=1)
        for ph, colour in ((0, "gold"), (1, "red"), (2, "green")):
            if (phase == ph).any():
                x.axvspan(t[phase == ph][0] - 0.5, t[phase == ph][-1] + 0.5, color=colour, alpha=0.12)
        x.set_ylabel(name, fontsize=8)
        x.set_ylim(-1.1, 1.1)
        x.set_xlim(0.5, len(phase) + 0.5)
    ax[-1].set_xlabel("policy step (0.2 s); yellow: free motion, red: search after contact, green: insertion")
    fig.suptitle(title + "\nimages: the task ROI, and in red the gradient saliency of the lateral F_d", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
