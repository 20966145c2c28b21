"""The speed/accuracy trade, measured: for each model tier and quality preset on the weave presets
and the sample fabrics, bake time and memory, atlas size, render time as a ratio to a Principled
BSDF with sheen (same scene, samples and resolution, one Blender run), error against the
`reference` preset (BSDF relative L1 from the C++ model evaluator, image relative RMSE of the
render) and the closure-mapping error. Writes a CSV, a JSON, a Markdown summary, the Pareto plot
(error against render-time ratio) and plots of the fitted lobes. Run by scripts/trade.sh, which
builds first; see its header for the options.

Choices where the issue is silent:
  * Bake: each run re-bakes from scratch (--force: no reuse of another atlas's simulation), timed
    as a whole process by /usr/bin/time (elapsed seconds and peak RSS); median over --runs.
  * BSDF error: `loom-bake eval error` (baker/include/loom/preset_error.h), the relative L1 over
    the sphere of the BSDF averaged over 64 points of the repeat, mean over 12 views on both sides
    (`average`); the point-wise mean is in the table too.
  * Render: bench/blender_render_ratio.py, node mode (what renders here), orthographic swatch, one
    sun (--light), every preset's material and the Principled baseline rendered --repeats times
    alternating in one Blender process, all with the same seed (common random numbers, so
    that what differs between two images is mostly the material); the image error is against
    the reference preset's render, and beside it the reference rendered again with another
    seed: what Monte Carlo noise alone does at these samples. The render-time ratio is of the
    time per sample (each material also rendered at --timing-samples, 4x --samples by default:
    the difference of the two times over the difference of the sample counts), so that what a
    render costs once (sync, image loads, BVH) cancels; the whole-render ratio at --samples is
    in the table beside it.
  * The Pareto plot shows, per tier and preset, the median over fabrics of the render-time ratio
    and of the BSDF error (and the image error), the presets of a tier joined in order, each
    fabric's point faint behind; the points no other point beats on both axes are ringed. One
    panel per tier: each tier's errors are against its own reference.
"""

import argparse
import csv
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from trade_plots import plot_pareto

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
WEAVES = ("plain", "twill", "satin", "basket")
SAMPLES = ("orange_polyester_satin", "white_silk_organza", "cream_cotton_twill",
           "gray_wool_twill", "black_polyester_plain", "beige_silk_satin", "blue_cotton_satin")
QUALITIES = ("draft", "preview", "final", "reference")
TIERS = ("surface", "raywave")


def parse(argv):
    p = argparse.ArgumentParser(prog="scripts/trade.sh", description=__doc__.split("\n")[0],
                                allow_abbrev=False)
    p.add_argument("--fabrics", default=",".join(WEAVES + SAMPLES),
                   help="comma-separated weave presets and sample fabrics (default: all 11)")
    p.add_argument("--tiers", default=",".join(TIERS), help="surface,raywave")
    p.add_argument("--raywave-fabrics", default=None,
                   help="the ray-wave tier on these only (default: --fabrics); its reference "
                        "bakes take minutes each")
    p.add_argument("--qualities", default=",".join(QUALITIES),
                   help="presets to measure; reference is always baked (errors are against it)")
    p.add_argument("--runs", type=int, default=3, help="bakes per preset (median), >= 1")
    p.add_argument("--samples", type=int, default=16, help="render samples per pixel")
    p.add_argument("--timing-samples", type=int, default=None,
                   help="second sample count, for the time per sample (default 4 x --samples)")
    p.add_argument("--res", type=int, default=96, help="render resolution (square)")
    p.add_argument("--repeats", type=int, default=3, help="renders per material (median)")
    p.add_argument("--light", choices=("front", "back"), default="front")
    p.add_argument("--no-render", action="store_true", help="skip Blender (no render columns)")
    p.add_argument("--truth-rays", type=int, default=200000,
                   help="rays per view of the fiber-level truth (eval error --truth) each preset "
                        "is measured against; 0: no truth columns")
    # A single-ply fabric: its tables are the simulated ply's (a multi-ply yarn's are Eq. S.13's).
    p.add_argument("--lobes", default="orange_polyester_satin:final:30:0.3:0",
                   help="FABRIC:QUALITY:THETA_I_DEG:H:SIGMA of the lobe plot (with the "
                        "ray-wave tier), or 'none'")
    p.add_argument("--resume", action="store_true",
                   help="keep the fabrics and tiers an earlier run with the same settings and "
                        "the same loom-bake binary measured (DIR/done.json) and measure the rest")
    p.add_argument("--merge", default=None, metavar="DIR,DIR",
                   help="measure nothing: join the rows earlier runs kept in DIR/done.json "
                        "(same settings; the baker may differ, each is named) into --out")
    p.add_argument("--bake", default=os.path.join(ROOT, "build", "loom-bake"))
    p.add_argument("--out", default=os.path.join(ROOT, "out", "trade"))
    a = p.parse_args(argv)
    a.fabrics = [f for f in a.fabrics.split(",") if f]
    for f in a.fabrics:
        if f not in WEAVES + SAMPLES:
            p.error(f"--fabrics: {f!r} is not one of {', '.join(WEAVES + SAMPLES)}")
    a.raywave_fabrics = ([f for f in a.raywave_fabrics.split(",") if f]
                         if a.raywave_fabrics is not None else list(a.fabrics))
    for f in a.raywave_fabrics:
        if f not in WEAVES + SAMPLES:
            p.error(f"--raywave-fabrics: {f!r} is not one of {', '.join(WEAVES + SAMPLES)}")
    a.tiers = [t for t in a.tiers.split(",") if t]
    a.qualities = [q for q in a.qualities.split(",") if q]
    for t in a.tiers:
        if t not in TIERS:
            p.error(f"--tiers: {t!r} is not one of {', '.join(TIERS)}")
    for q in a.qualities:
        if q not in QUALITIES:
            p.error(f"--qualities: {q!r} is not one of {', '.join(QUALITIES)}")
    if not a.fabrics or not a.tiers or not a.qualities:
        p.error("--fabrics, --tiers and --qualities must each name at least one")
    if a.runs < 1 or a.samples < 1 or a.res < 8 or a.repeats < 1:
        p.error("--runs, --samples and --repeats must be >= 1 and --res >= 8")
    if a.timing_samples is None:
        a.timing_samples = 4 * a.samples
    elif a.timing_samples <= a.samples:
        p.error(f"--timing-samples: {a.timing_samples} (allowed: more than --samples, "
                f"{a.samples})")
    if a.lobes != "none":
        parts = a.lobes.split(":")
        ok = len(parts) == 5 and parts[0] in WEAVES + SAMPLES and parts[1] in QUALITIES
        try:
            ok = ok and -90 <= float(parts[2]) <= 90 and -1 <= float(parts[3]) <= 1 \
                and 0 <= float(parts[4]) <= 1e6
        except ValueError:
            ok = False
        if not ok:
            p.error(f"--lobes: expected FABRIC:QUALITY:THETA_I_DEG:H:SIGMA with a weave preset or "
                    f"sample fabric, a quality preset, theta_i in [-90, 90], h in [-1, 1], sigma in "
                    f"[0, 1e6] (1/mm), or 'none'; got {a.lobes!r}")
    if a.merge is not None:
        a.merge = [d for d in a.merge.split(",") if d]
        if not a.merge:
            p.error("--merge: name at least one directory holding a done.json")
        measuring = [o for o in ("--fabrics", "--tiers", "--raywave-fabrics", "--qualities",
                                 "--runs", "--samples", "--timing-samples", "--res",
                                 "--repeats", "--light",
                                 "--no-render", "--lobes", "--resume")
                     if any(x == o or x.startswith(o + "=") for x in argv)]
        if measuring:
            p.error(f"--merge measures nothing; {', '.join(measuring)} would be ignored (the "
                    "settings are the merged runs' own)")
        out = os.path.realpath(a.out)
        for d in a.merge:
            if os.path.realpath(d) == out:
                p.error(f"--merge: --out {a.out} is one of the merged runs; write elsewhere")
    if "reference" not in a.qualities:
        a.qualities.append("reference")
    a.qualities = [q for q in QUALITIES if q in a.qualities]
    return a


def log(msg):
    print(f"loom-trade: {msg}", flush=True)


def preset_path(fabric):
    sub = "samples" if fabric in SAMPLES else ""
    return os.path.join(ROOT, "presets", sub, fabric + ".json")


def write_spec(fabric, tier, out_dir):
    with open(preset_path(fabric), encoding="utf-8") as f:
        spec = json.load(f)
    spec.setdefault("model", {})["tier"] = tier
    spec["model"].pop("quality", None)
    path = os.path.join(out_dir, "specs", f"{fabric}_{tier}.json")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", encoding="utf-8") as f:
        json.dump(spec, f, indent=1)
    return path


def run_json(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"loom-trade: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def bake(args, spec, quality, atlas):
    secs, rss = [], []
    with tempfile.NamedTemporaryFile(mode="r") as t:
        for _ in range(args.runs):
            cmd = ["/usr/bin/time", "-f", "%e %M", "-o", t.name, args.bake, "bake", spec, "-o",
                   atlas, "--quality", quality, "--force", "--progress=none"]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                raise SystemExit(f"loom-trade: bake of {spec} at {quality} failed:\n{r.stderr}")
            t.seek(0)
            s, kb = t.read().split()[-2:]
            secs.append(float(s))
            rss.append(int(kb))
    size = sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(atlas) for f in fs)
    return {"bake_s": statistics.median(secs), "bake_runs": secs,
            "peak_rss_mib": statistics.median(rss) / 1024.0, "atlas_mib": size / 2.0**20}


def render(args, fabric, tier, atlases, out_dir):
    """One Blender run: every preset's material and the Principled baseline."""
    js = os.path.join(out_dir, "renders", f"{fabric}_{tier}.json")
    os.makedirs(os.path.dirname(js), exist_ok=True)
    cmd = ["bash", os.path.join(ROOT, "scripts", "blender.sh"), "run", "-b", "--factory-startup",
           "--python-exit-code", "1", "--python", os.path.join(HERE, "blender_render_ratio.py"),
           "--"]
    for q, a in atlases.items():
        cmd += ["--material", f"{q}={a}"]
    cmd += ["--samples", str(args.samples), "--timing-samples", str(args.timing_samples),
            "--res", str(args.res), "--repeats",
            str(args.repeats), "--light", args.light, "--reference", "reference",
            "--noise-floor", "--images", os.path.join(out_dir, "renders", f"{fabric}_{tier}"),
            "--json", js]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"loom-trade: render of {fabric} ({tier}) failed:\n{r.stdout[-3000:]}"
                         f"\n{r.stderr[-3000:]}")
    with open(js, encoding="utf-8") as f:
        return json.load(f)


def settings_key(args):
    """What makes two runs' rows comparable: the measuring settings and the baker itself."""
    h = hashlib.sha256()
    with open(args.bake, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return {"runs": args.runs, "samples": args.samples,
            "timing_samples": None if args.no_render else args.timing_samples,
            "res": args.res,
            "repeats": args.repeats, "light": args.light, "rendered": not args.no_render,
            "qualities": args.qualities, "truth_rays": args.truth_rays,
            "loom_bake_sha256": h.hexdigest()}


def load_done(args, key):
    """Rows of fabric/tier pairs already measured (--resume), or none."""
    path = os.path.join(args.out, "done.json")
    if not args.resume or not os.path.exists(path):
        return []
    with open(path, encoding="utf-8") as f:
        done = json.load(f)
    if done.get("settings") != key:
        diff = sorted(k for k in key if done.get("settings", {}).get(k) != key[k])
        raise SystemExit(f"loom-trade: --resume: {path} was measured with other settings "
                         f"({', '.join(diff)} differ); run without --resume to start afresh")
    log(f"resuming: {len({(r['fabric'], r['tier']) for r in done['rows']})} fabric/tier pairs "
        f"already measured")
    return done["rows"]


def source_commit():
    """The checkout's commit (git describe: "-dirty" when files differ from it), or None."""
    r = subprocess.run(["git", "-C", ROOT, "describe", "--always", "--dirty", "--abbrev=12"],
                       capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 and r.stdout.strip() else None


def save_done(args, key, rows):
    """done.json, written whole or not at all, after each fabric/tier pair. The commit is
    recorded for readers; only the binary's hash (in key) decides what --resume keeps."""
    path = os.path.join(args.out, "done.json")
    tmp = path + ".tmp"
    if not hasattr(args, "commit"):
        args.commit = source_commit()
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump({"settings": key, "cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d"),
                   "commit": args.commit, "rows": rows}, f, indent=1)
    os.replace(tmp, path)


def merge(args):
    """Rows of the earlier runs in args.merge, joined (--merge). Their measuring settings must
    agree (the rows are then comparable); each run's baker is recorded as a source. The settings
    and the tiers of args become the runs' own. Raises SystemExit naming what does not fit,
    before anything is written."""
    rows, sources, settings = [], [], None
    fields = ("runs", "samples", "timing_samples", "res", "repeats", "light", "rendered",
              "qualities",
              "loom_bake_sha256")
    for d in args.merge:
        path = os.path.join(d, "done.json")
        bad = f"loom-trade: --merge: {path} is not a trade run's done.json"
        try:
            with open(path, encoding="utf-8") as f:
                done = json.load(f)
        except (OSError, ValueError) as exc:
            raise SystemExit(f"{bad} ({exc})")
        if not isinstance(done, dict) or not isinstance(done.get("settings"), dict) \
                or not isinstance(done.get("rows"), list):
            raise SystemExit(f"{bad} (expected an object with \"settings\" and \"rows\")")
        key = dict(done["settings"])
        missing = [k for k in fields if k not in key]
        if missing == ["timing_samples"]:
            raise SystemExit(f"loom-trade: --merge: {path} was measured by an older trade.py, "
                             "whose render ratio was of the whole render, not per sample: its "
                             "rows do not compare; measure again")
        if missing:
            raise SystemExit(f"{bad} (settings lack {', '.join(missing)})")
        sha = key.pop("loom_bake_sha256")
        if not isinstance(sha, str) or not isinstance(key["qualities"], list) \
                or any(q not in QUALITIES for q in key["qualities"]):
            raise SystemExit(f"{bad} (settings.loom_bake_sha256 must be a string and "
                             f"settings.qualities a list of {', '.join(QUALITIES)})")
        got = done["rows"]
        for i, r in enumerate(got):
            if not isinstance(r, dict) or r.get("fabric") not in WEAVES + SAMPLES \
                    or r.get("tier") not in TIERS or r.get("quality") not in QUALITIES:
                raise SystemExit(f"{bad} (rows[{i}] needs a known fabric, tier "
                                 f"({', '.join(TIERS)}) and quality ({', '.join(QUALITIES)}))")
        if settings is None:
            settings = key
        elif key != settings:
            diff = sorted(k for k in set(key) | set(settings) if key.get(k) != settings.get(k))
            raise SystemExit(f"loom-trade: --merge: {path} was measured with other settings than "
                             f"{args.merge[0]} ({', '.join(diff)} differ)")
        have = {(r["fabric"], r["tier"]) for r in rows}
        pairs = sorted({(r["fabric"], r["tier"]) for r in got})
        twice = [f"{f} ({t})" for f, t in pairs if (f, t) in have]
        if twice:
            raise SystemExit(f"loom-trade: --merge: {path} measures {', '.join(twice)} again")
        rows += got
        # Relative to --out: results kept together (in the repository, say) stay readable.
        sources.append({"dir": os.path.relpath(d, args.out), "loom_bake_sha256": sha,
                        "cores": done.get("cores"), "date": done.get("date"),
                        "commit": done.get("commit"),
                        "lobes": os.path.exists(os.path.join(d, "lobes.png")),
                        "pairs": [f"{f} ({t})" for f, t in pairs]})
    args.runs, args.samples, args.res = settings["runs"], settings["samples"], settings["res"]
    args.timing_samples = settings["timing_samples"]
    args.repeats, args.light = settings["repeats"], settings["light"]
    args.no_render = not settings["rendered"]
    args.qualities = list(settings["qualities"])
    args.tiers = [t for t in TIERS if any(r["tier"] == t for r in rows)]
    args.lobes = "none"  # the lobe plot needs an atlas; each run wrote its own
    args.sources = sources
    return rows


def measure(args):
    key = settings_key(args)
    rows = load_done(args, key)
    wanted = {(f, t) for t in args.tiers
              for f in (args.raywave_fabrics if t == "raywave" else args.fabrics)}
    measured = {(r["fabric"], r["tier"]) for r in rows}
    atlas_root = os.path.join(args.out, "atlases")
    fabrics = list(dict.fromkeys(args.fabrics + args.raywave_fabrics))
    for fabric in fabrics:
        for tier in args.tiers:
            if fabric not in (args.raywave_fabrics if tier == "raywave" else args.fabrics):
                continue
            if (fabric, tier) in measured:
                continue
            spec = write_spec(fabric, tier, args.out)
            atlases = {}
            for q in args.qualities:
                atlas = os.path.join(atlas_root, f"{fabric}_{tier}_{q}")
                t0 = time.monotonic()
                row = {"fabric": fabric, "tier": tier, "quality": q}
                row.update(bake(args, spec, q, atlas))
                m = run_json([args.bake, "eval", "mapping", "--atlas", atlas])
                row["mapping_l1"], row["mapping_energy"] = (m["mean_relative_l1"],
                                                            m["mean_energy_error"])
                if args.truth_rays:
                    t = run_json([args.bake, "eval", "error", "--atlas", atlas, "--truth",
                                  "--rays", str(args.truth_rays)])
                    row.update(error_vs_truth_model=t["model"]["relative_l1"],
                               error_vs_truth_closures=t["closures"]["relative_l1"],
                               albedo_vs_truth_model=t["model"]["albedo_error"],
                               albedo_vs_truth_closures=t["closures"]["albedo_error"],
                               reflect_ratio_vs_truth=t["closures"]["reflect_ratio"],
                               transmit_ratio_vs_truth=t["closures"]["transmit_ratio"],
                               truth_noise_l1=t["noise_l1"])
                atlases[q] = atlas
                rows.append(row)
                log(f"{fabric} {tier} {q}: bake {row['bake_s']:.2f} s, "
                    f"{row['atlas_mib']:.1f} MiB, mapping {row['mapping_l1']:.3f} "
                    f"({time.monotonic() - t0:.0f} s)")
            for row in rows:
                if row["fabric"] != fabric or row["tier"] != tier:
                    continue
                if row["quality"] == "reference":
                    row.update(bsdf_l1=0.0, bsdf_pointwise_l1=0.0, bsdf_energy=0.0)
                    continue
                e = run_json([args.bake, "eval", "error", "--atlas", atlases[row["quality"]],
                              "--reference", atlases["reference"]])
                row.update(bsdf_l1=e["average_relative_l1"],
                           bsdf_pointwise_l1=e["pointwise_mean_relative_l1"],
                           bsdf_energy=e["energy_error"])
            if not args.no_render:
                r = render(args, fabric, tier, atlases, args.out)
                by = {x["material"]: x for x in r["rows"]}
                for row in rows:
                    if row["fabric"] == fabric and row["tier"] == tier:
                        x = by[row["quality"]]
                        p = by["principled_sheen"]
                        row.update(render_ratio=x["ratio"], render_whole_ratio=x["whole_ratio"],
                                   render_ms_per_sample=1e3 * x["per_sample_s"],
                                   render_fixed_s=x["fixed_s"], render_s=x["median_s"],
                                   image_rmse=x["relative_rmse"],
                                   image_noise_floor=r["noise_floor"],
                                   principled_ms_per_sample=1e3 * p["per_sample_s"],
                                   principled_s=p["median_s"])
                log(f"{fabric} {tier}: rendered; reference vs another seed "
                    f"{r['noise_floor']:.4f}")
            save_done(args, key, rows)
            write_outputs([r for r in rows if (r["fabric"], r["tier"]) in wanted], args)
    return [r for r in rows if (r["fabric"], r["tier"]) in wanted]


COLUMNS = ("fabric", "tier", "quality", "bake_s", "peak_rss_mib", "atlas_mib", "render_ratio",
           "render_whole_ratio", "bsdf_l1", "bsdf_pointwise_l1", "bsdf_energy", "image_rmse",
           "image_noise_floor", "mapping_l1", "mapping_energy", "render_ms_per_sample",
           "render_fixed_s", "render_s", "principled_ms_per_sample", "principled_s",
           "error_vs_truth_model", "error_vs_truth_closures", "albedo_vs_truth_model",
           "albedo_vs_truth_closures", "reflect_ratio_vs_truth", "transmit_ratio_vs_truth",
           "truth_noise_l1")


def fmt(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


def summary(rows, args):
    """Median over fabrics per (tier, quality)."""
    out = []
    for tier in args.tiers:
        for q in args.qualities:
            sel = [r for r in rows if r["tier"] == tier and r["quality"] == q]
            if not sel:
                continue
            s = {"tier": tier, "quality": q, "fabrics": len(sel)}
            for c in COLUMNS[3:]:
                vals = [r[c] for r in sel if r.get(c) is not None]
                s[c] = statistics.median(vals) if vals else None
            out.append(s)
    return out


def write_outputs(rows, args):
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "trade.csv"), "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    summ = summary(rows, args)
    meta = {"date": time.strftime("%Y-%m-%d"), "cores": os.cpu_count(), "runs": args.runs,
            "samples": args.samples, "timing_samples": args.timing_samples, "res": args.res,
            "repeats": args.repeats,
            "light": args.light, "rendered": not args.no_render}
    if getattr(args, "sources", None):
        meta["sources"] = args.sources
        del meta["cores"]  # each source's own
    with open(os.path.join(args.out, "trade.json"), "w", encoding="utf-8") as f:
        json.dump({"settings": meta, "rows": rows, "summary": summ}, f, indent=1)
    cols = ("tier", "quality", "fabrics", "bake_s", "peak_rss_mib", "atlas_mib", "render_ratio",
            "render_whole_ratio", "bsdf_l1", "image_rmse", "image_noise_floor", "mapping_l1",
            "error_vs_truth_model", "error_vs_truth_closures", "albedo_vs_truth_closures",
            "reflect_ratio_vs_truth", "transmit_ratio_vs_truth", "truth_noise_l1")
    heads = ("tier", "preset", "fabrics", "bake s", "peak RSS MiB", "atlas MiB",
             "render per sample / Principled", "whole render / Principled",
             "BSDF rel. L1 vs ref.", "image rel. RMSE vs ref.",
             "reference, other seed", "mapping rel. L1", "model rel. L1 vs fibers",
             "closures rel. L1 vs fibers", "closures albedo error vs fibers",
             "reflect / fibers", "transmit / fibers", "fibers' own MC L1")
    sources = getattr(args, "sources", None)
    when = (f"joined {meta['date']} from earlier runs" if sources
            else f"{meta['date']}, {meta['cores']} cores")
    md = [f"# Loom's speed/accuracy trade ({when})", "",
          ("Bake: one whole-process run" if args.runs == 1 else
           f"Bake: median of {args.runs} whole-process runs") +
          f". Render: node mode, {args.res}^2 px, "
          f"{args.samples} samples, {args.light}-lit swatch, median of {args.repeats}, as a "
          "ratio to a Principled BSDF with sheen in the same run: of the time per sample "
          f"(renders at {args.samples} and {args.timing_samples} samples: what a render costs "
          f"once cancels) and of the whole render at {args.samples}. Errors against the "
          "`reference` preset of the same tier: BSDF relative L1 over the sphere (repeat "
          "average, C++ model), image relative RMSE (every material rendered with one seed; "
          "'reference, other seed' is the reference rendered with another: Monte Carlo noise "
          "alone). Mapping: model vs Cycles closures. Against the fibers (`eval error "
          f"--truth`, {args.truth_rays} rays per view, 6 views): relative L1 over the sphere of "
          "the repeat-averaged BSDF, directional albedo error, reflect and transmit ratios "
          "(closures / fibers, geometric mean over views), and the truth's own Monte Carlo "
          "part of the L1.", ""]
    if sources:
        md += ["Joined from earlier runs (`--merge`), each with its own loom-bake:", ""]
        md += [f"- `{s['dir']}` ({s.get('date') or 'date not recorded'}, "
               f"{str(s['cores']) + ' cores' if s.get('cores') else 'cores not recorded'}): "
               "loom-bake sha256 "
               f"{s['loom_bake_sha256'][:12]}"
               + (f" (built from {s['commit']})" if s.get("commit") else "")
               + f", {', '.join(s['pairs'])}"
               + (f"; its lobe plot: `{os.path.join(s['dir'], 'lobes.png')}`" if s.get("lobes")
                  else "") for s in sources]
        md += [""]
    md += [
          "## Median over fabrics", "",
          "| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
    for s in summ:
        md.append("| " + " | ".join(fmt(s.get(c)) for c in cols) + " |")
    md += ["", "## Every fabric", "", "| fabric | " + " | ".join(heads[:2] + heads[3:]) + " |",
           "|" + "---|" * len(heads)]
    for r in rows:
        md.append("| " + " | ".join(fmt(r.get(c)) for c in ("fabric",) + cols[:2] + cols[3:])
                  + " |")
    md += ["", "Plots: `pareto.png` (error against render-time ratio)" +
           (", `lobes.png` (fitted lobes)" if args.lobes != "none" and "raywave" in args.tiers
            else "") + "."]
    with open(os.path.join(args.out, "trade.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(md) + "\n")
    plot_pareto(rows, summ, args)


def plot_lobes(args):
    """Each fitted lobe, their sum and the simulation, on (elevation, azimuth) of ply space."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fabric, quality, theta, h, sigma = args.lobes.split(":")
    atlas = os.path.join(args.out, "atlases", f"{fabric}_raywave_{quality}")
    if not os.path.isdir(atlas):
        spec = write_spec(fabric, "raywave", args.out)
        subprocess.run([args.bake, "bake", spec, "-o", atlas, "--quality", quality,
                        "--progress=none"], check=True, capture_output=True)
    d = run_json([args.bake, "eval", "lobes", "--atlas", atlas, "--theta-i", theta, "--h", h,
                  "--sigma", sigma, "--raw", "--snap", "--res", "48"])
    panels = [("simulated (nearest slice)", d["raw"]["values"]), ("fitted sum", d["total"])]
    panels += [(f"f_high lobe {i}  mu=({lb['mu1']:.3g}, {lb['mu2']:.3g})", lb["values"])
               for i, lb in enumerate(d["high"])]
    panels += [(f"f_refl lobe {i}  mu=({lb['mu1']:.3g}, {lb['mu2']:.3g})", lb["values"])
               for i, lb in enumerate(d["refl"])]
    vmax = max(float(np.max(np.asarray(v))) for _, v in panels[:2])
    vmin = vmax * 1e-4
    cols = 2
    nrow = (len(panels) + cols - 1) // cols
    fig, axes = plt.subplots(nrow, cols, figsize=(5.2 * cols, 3.1 * nrow), squeeze=False,
                             layout="constrained")
    im = None
    for ax, (title, vals) in zip(axes.flat, panels):
        arr = np.clip(np.asarray(vals, dtype=float), vmin, None)
        im = ax.imshow(arr, origin="lower", extent=(-180, 180, -90, 90), aspect="auto",
                       norm=matplotlib.colors.LogNorm(vmin=vmin, vmax=vmax), cmap="magma")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("azimuth in the ply's normal plane, deg", fontsize=8)
        ax.set_ylabel("elevation towards the ply axis, deg", fontsize=8)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.8, label="scattering density, 1/sr")
    fig.suptitle(f"{fabric} ({quality}): the lobes at the grid slice nearest to theta_i {theta}"
                 f" deg, h {h}: theta_i {d['theta_i_deg']:.1f} deg, h {d['h']:.2f}, sigma "
                 f"{sigma}/mm\nsimulated: {d['raw']['model']}; log scale", fontsize=9)
    fig.savefig(os.path.join(args.out, "lobes.png"), dpi=100)
    plt.close(fig)


def main(argv):
    args = parse(argv)
    rows = merge(args) if args.merge is not None else None
    os.makedirs(args.out, exist_ok=True)
    if rows is None:
        rows = measure(args)
    write_outputs(rows, args)
    lobes = args.lobes != "none" and "raywave" in args.tiers
    if lobes:
        plot_lobes(args)
    log(f"wrote {args.out}/trade.csv, trade.json, trade.md, pareto.png"
        + (", lobes.png" if lobes else ""))
    with open(os.path.join(args.out, "trade.md"), encoding="utf-8") as f:
        print(f.read())


if __name__ == "__main__":
    main(sys.argv[1:])
