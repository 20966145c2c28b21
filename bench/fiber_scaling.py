#!/usr/bin/env python3
"""Memory and look-up time of the fiber tier's realization-minimising structures against full
realization on woven patches of growing size (Luan et al. 2017, Table 1's comparison).

Each size runs `loom-bake eval fibers` once per method in its own process under /usr/bin/time, so
the peak resident set is the method's own; the counted bytes are what the structures hold. Full
realization is measured while it fits in memory (loom-bake refuses beyond 12 GiB); above that
its bytes are extrapolated from the measured bytes per realized vertex, and said so.

  python3 bench/fiber_scaling.py [--spec plain] [--yarns 10,20,...] [--points 20000] [--out DIR]
"""
import argparse
import json
import os
import subprocess
import sys


def run(exe, spec, yarns, points, only):
    cmd = ["/usr/bin/time", "-f", "maxrss_kib %M", exe, "eval", "fibers", "--spec", spec,
           "--yarns", str(yarns), "--points", str(points), "--only", only]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        return None, r.stderr.strip().splitlines()[-2:] if r.stderr else []
    rss = [l for l in r.stderr.splitlines() if l.startswith("maxrss_kib")]
    d = json.loads(r.stdout.strip().splitlines()[-1])
    d["peak_rss_mib"] = int(rss[-1].split()[1]) / 1024 if rss else None
    return d, None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--exe", default=os.path.join(os.path.dirname(__file__), "..", "build", "loom-bake"))
    ap.add_argument("--spec", default="plain")
    ap.add_argument("--yarns", default="10,20,50,100,200,500,1000,2000")
    ap.add_argument("--points", type=int, default=20000)
    ap.add_argument("--compare-up-to", type=int, default=200,
                    help="largest patch also compared point by point (mismatches)")
    ap.add_argument("--out", default="out/fibers")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    per_vertex = None
    for n in [int(x) for x in a.yarns.split(",")]:
        m, _ = run(a.exe, a.spec, n, a.points, "minimising")
        r, err = run(a.exe, a.spec, n, a.points, "realized")
        both = run(a.exe, a.spec, n, a.points, "both")[0] if n <= a.compare_up_to else None
        row = {"yarns": n, "bytes_minimising": m["bytes_minimising"],
               "rss_mib_minimising": m["peak_rss_mib"],
               "us_per_lookup_minimising": 1e6 * m["seconds_minimising"] / a.points,
               "build_s_minimising": m["build_seconds_minimising"],
               "covered": m["covered"],
               "mismatches": both["mismatches"] if both else None}
        if r:
            per_vertex = r["bytes_realized"] / r["realized_vertices"]
            row.update({"bytes_realized": r["bytes_realized"], "rss_mib_realized": r["peak_rss_mib"],
                        "us_per_lookup_realized": 1e6 * r["seconds_realized"] / a.points,
                        "build_s_realized": r["build_seconds_realized"], "realized": "measured"})
        elif per_vertex:
            # vertices scale with yarns x length: from the last measured size.
            last = rows[-1]
            scale = (n / last["yarns"]) * (n / last["yarns"])
            row.update({"bytes_realized": last["bytes_realized"] * scale, "rss_mib_realized": None,
                        "us_per_lookup_realized": None, "build_s_realized": None,
                        "realized": "extrapolated (" + " ".join(err or []) + ")"})
        row["memory_ratio"] = row.get("bytes_realized", 0) / row["bytes_minimising"]
        if row.get("us_per_lookup_realized"):
            row["time_ratio"] = row["us_per_lookup_minimising"] / row["us_per_lookup_realized"]
        rows.append(row)
        print(json.dumps(row), flush=True)
    with open(os.path.join(a.out, "scaling.json"), "w") as f:
        json.dump(rows, f, indent=1)
    mib = lambda b: "%.3g" % (b / 2**20) if b is not None else "–"
    fmt = lambda x, p="%.3g": (p % x) if x is not None else "–"
    lines = ["| yarns | minimising MiB (RSS) | realized MiB (RSS) | memory ratio | "
             "us / look-up min. | us / look-up real. | time ratio | mismatches |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append("| %d | %s (%s) | %s (%s)%s | %.0f | %s | %s | %s | %s |" % (
            r["yarns"], mib(r["bytes_minimising"]), fmt(r["rss_mib_minimising"], "%.0f"),
            mib(r["bytes_realized"]), fmt(r["rss_mib_realized"], "%.0f"),
            "" if r.get("realized") == "measured" else " extrapolated", r["memory_ratio"],
            fmt(r["us_per_lookup_minimising"], "%.2f"), fmt(r["us_per_lookup_realized"], "%.2f"),
            fmt(r.get("time_ratio"), "%.2f"), fmt(r["mismatches"], "%d")))
    with open(os.path.join(a.out, "scaling.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
