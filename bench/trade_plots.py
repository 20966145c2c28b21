"""The Pareto plot of the speed/accuracy trade (bench/trade.py): error against cost, per tier and
preset, and every tier on one axis of error against the fibers (eval error --truth)."""

import os
import statistics


def pareto(points):
    """Indices of the points that no other point beats on both (x, y), lower is better."""
    keep = []
    for i, (x, y) in enumerate(points):
        if not any((x2 <= x and y2 <= y) and (x2 < x or y2 < y) for x2, y2 in points):
            keep.append(i)
    return keep



def plot_pareto(rows, summ, args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xkey = "render_ratio" if not args.no_render else "bake_s"
    xlabel = ("render time per sample / Principled BSDF with sheen (same scene, one run)"
              if not args.no_render else "bake time, s (median)")
    panels = [("bsdf_l1", "BSDF relative L1 vs reference")]
    if not args.no_render:
        panels.append(("image_rmse", "image relative RMSE vs reference"))
    # One panel per error and tier: each tier's errors are against its own reference, and the
    # tiers' scales differ tenfold (surface presets within a few hundredths), so a shared axis
    # would stack one tier's presets on top of each other.
    tiers = [t for t in args.tiers if any(r["tier"] == t for r in rows)] or list(args.tiers)
    truth = any(r.get("error_vs_truth_closures") is not None for r in rows)
    nrow = len(panels) + (1 if truth else 0)
    fig = plt.figure(figsize=(6.5 * len(tiers), 4.6 * nrow))
    gs = fig.add_gridspec(nrow, len(tiers))
    axes = [[fig.add_subplot(gs[p, c]) for c in range(len(tiers))] for p in range(len(panels))]
    colours = {"surface": "tab:blue", "raywave": "tab:red"}
    markers = {"draft": "o", "preview": "s", "final": "^", "reference": "*"}
    for p, (ykey, ylabel) in enumerate(panels):
        for col, tier in enumerate(tiers):
            ax = axes[p][col]
            for r in rows:
                if r["tier"] == tier and r.get(xkey) is not None and r.get(ykey) is not None:
                    ax.scatter(r[xkey], r[ykey], color=colours[tier], alpha=0.2,
                               marker=markers[r["quality"]], s=18)
            sel = [s for s in summ if s["tier"] == tier and s.get(xkey) is not None
                   and s.get(ykey) is not None]
            ax.plot([s[xkey] for s in sel], [s[ykey] for s in sel], color=colours[tier],
                    label=f"{tier}: median over fabrics")
            for s in sel:
                ax.scatter(s[xkey], s[ykey], color=colours[tier], marker=markers[s["quality"]],
                           s=60, zorder=3)
                ax.annotate(s["quality"], (s[xkey], s[ykey]), textcoords="offset points",
                            xytext=(5, 4), fontsize=8)
            # The front among the presets below the reference (whose error is 0 by definition).
            cand = [s for s in sel if s["quality"] != "reference"]
            for i in pareto([(s[xkey], s[ykey]) for s in cand]):
                ax.scatter(cand[i][xkey], cand[i][ykey], s=220, facecolors="none",
                           edgecolors="black", zorder=4)
            if ykey == "image_rmse":
                floors = [r["image_noise_floor"] for r in rows
                          if r["tier"] == tier and r.get("image_noise_floor")]
                if floors:
                    ax.axhline(statistics.median(floors), color=colours[tier], ls="--", lw=1,
                               label="reference vs itself, other seed (median)")
            ax.set_title(f"{tier}: {ylabel}", fontsize=10)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
    if truth:
        # Every tier on one axis: the error of what Cycles renders (the closures) against the
        # fibers, the same truth for all, so that the tiers compare with each other.
        ax = fig.add_subplot(gs[nrow - 1, :])
        for tier in tiers:
            for r in rows:
                if (r["tier"] == tier and r.get(xkey) is not None
                        and r.get("error_vs_truth_closures") is not None):
                    ax.scatter(r[xkey], r["error_vs_truth_closures"], color=colours[tier],
                               alpha=0.2, marker=markers[r["quality"]], s=18)
            sel = [s for s in summ if s["tier"] == tier and s.get(xkey) is not None
                   and s.get("error_vs_truth_closures") is not None]
            ax.plot([s[xkey] for s in sel], [s["error_vs_truth_closures"] for s in sel],
                    color=colours[tier], label=f"{tier}: median over fabrics")
            for s in sel:
                ax.scatter(s[xkey], s["error_vs_truth_closures"], color=colours[tier],
                           marker=markers[s["quality"]], s=60, zorder=3)
                ax.annotate(s["quality"], (s[xkey], s["error_vs_truth_closures"]),
                            textcoords="offset points", xytext=(5, 4), fontsize=8)
        allsel = [s for s in summ if s.get(xkey) is not None
                  and s.get("error_vs_truth_closures") is not None]
        for i in pareto([(s[xkey], s["error_vs_truth_closures"]) for s in allsel]):
            ax.scatter(allsel[i][xkey], allsel[i]["error_vs_truth_closures"], s=220,
                       facecolors="none", edgecolors="black", zorder=4)
        floors = [r["truth_noise_l1"] for r in rows if r.get("truth_noise_l1")]
        if floors:
            ax.axhline(statistics.median(floors), color="gray", ls="--", lw=1,
                       label="the truth's own Monte Carlo error (median)")
        ax.set_title("all tiers: what renders (closures) against the fibers (eval error --truth), "
                     "relative L1", fontsize=10)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relative L1 vs fiber-level truth")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    # Two lines when one tier's panels are all the figure's width holds.
    sep = "\n" if len(tiers) == 1 else " "
    fig.suptitle("Loom: error against cost per tier and preset (median over fabrics;" + sep +
                 "errors against the tier's own reference; ringed: each tier's Pareto front" +
                 (";" + sep + "last row: every tier against the fibers)" if truth else ")"),
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "pareto.png"), dpi=110)
    plt.close(fig)
