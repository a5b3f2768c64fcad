#!/usr/bin/env python3
"""Summary of eval_families.sh's per-draw table (Debian's python3 with numpy).

  family_summary.py DRAWS.tsv [MORE.tsv ...] [--no-aloam] [--markdown]

Per family: the draws evaluated, the median and 90th percentile of ATE (m) and of rotation drift
(deg/100 m) for this package and for A-LOAM, and the draws where this package's ATE is worse than
A-LOAM's and more than 20 % worse. A draw counts in a column only where its figure is a number; the draws
column reads `ours/A-LOAM` evaluated. Several tables (runs of other families or seeds) are read as one;
a (family, seed) met twice counts once, the last one read. --no-aloam: A-LOAM was not run (its columns say
so); --markdown prints a Markdown table.
"""
import csv
import math
import sys

import numpy as np

WORSE_MARGIN = 1.2  # "more than 20 % worse"


def number(text):
    try:
        value = float(text)
    except (TypeError, ValueError):
        return math.nan
    return value


def stats(values):
    values = [v for v in values if math.isfinite(v)]
    if not values:
        return math.nan, math.nan
    return float(np.median(values)), float(np.percentile(values, 90))


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f, delimiter="\t"))


def summarize(rows):
    families = []
    for row in rows:
        if row["family"] not in families:
            families.append(row["family"])
    table = []
    for family in families:
        mine = [r for r in rows if r["family"] == family]
        ours_ate = [number(r["ours_ate_m"]) for r in mine]
        peer_ate = [number(r["aloam_ate_m"]) for r in mine]
        ours_rot = [number(r["ours_rot_deg_100m"]) for r in mine]
        peer_rot = [number(r["aloam_rot_deg_100m"]) for r in mine]
        pairs = [(o, p) for o, p in zip(ours_ate, peer_ate) if math.isfinite(o) and math.isfinite(p)]
        table.append({
            "family": family,
            "draws": len(mine),
            "ours_n": sum(math.isfinite(v) for v in ours_ate),
            "peer_n": sum(math.isfinite(v) for v in peer_ate),
            "ours_ate": stats(ours_ate),
            "peer_ate": stats(peer_ate),
            "ours_rot": stats(ours_rot),
            "peer_rot": stats(peer_rot),
            "pairs": len(pairs),
            "worse": sum(o > p for o, p in pairs),
            "much_worse": sum(o > WORSE_MARGIN * p for o, p in pairs),
        })
    return table


def fmt(value, digits):
    return "-" if not math.isfinite(value) else "%.*f" % (digits, value)


def print_table(table, with_peer, markdown):
    head = ["family", "draws", "ATE med ours", "ATE med A-LOAM", "ATE p90 ours", "ATE p90 A-LOAM",
            "rot med ours", "rot med A-LOAM", "rot p90 ours", "rot p90 A-LOAM", "worse", ">20% worse"]
    lines = []
    for t in table:
        peer = with_peer and t["peer_n"] > 0
        lines.append([
            t["family"], "%d/%d" % (t["ours_n"], t["peer_n"]) if with_peer else "%d" % t["ours_n"],
            fmt(t["ours_ate"][0], 3), fmt(t["peer_ate"][0], 3) if peer else "not run",
            fmt(t["ours_ate"][1], 3), fmt(t["peer_ate"][1], 3) if peer else "not run",
            fmt(t["ours_rot"][0], 1), fmt(t["peer_rot"][0], 1) if peer else "not run",
            fmt(t["ours_rot"][1], 1), fmt(t["peer_rot"][1], 1) if peer else "not run",
            "%d/%d" % (t["worse"], t["pairs"]) if peer else "-",
            "%d/%d" % (t["much_worse"], t["pairs"]) if peer else "-",
        ])
    if markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for line in lines:
            print("| " + " | ".join(line) + " |")
    else:
        widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(head)]
        print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
        for line in lines:
            print("  ".join(v.rjust(w) for v, w in zip(line, widths)))
    print("# ATE: m after rigid alignment; rot: rotation drift in deg/100 m over 1/8, 1/4 and 1/2 of each path; "
          "med / p90: median / 90th percentile over the draws; worse: draws where our ATE is larger than A-LOAM's")
    if not with_peer:
        print("# A-LOAM was not run (not built): only this package's figures")


def main():
    args = sys.argv[1:]
    paths = [a for a in args if not a.startswith("--")]
    if not paths:
        sys.exit(__doc__)
    rows = {}
    for path in paths:
        for row in read_rows(path):
            rows[(row["family"], row["seed"])] = row
    with_peer = "--no-aloam" not in args
    print_table(summarize(list(rows.values())), with_peer, "--markdown" in args)


if __name__ == "__main__":
    main()
