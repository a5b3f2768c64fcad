#!/usr/bin/env python3
"""How thick the surfaces of a saved map are: a surface mapped twice (a street revisited after drift) is
thicker than one mapped once.

Reads maps written by `aloam_offline --save-map` or the `save_map` service (binary PCD with x y z label;
label 2 = plane points). For plane points on a grid of sample cells, it fits a plane to the points within
RADIUS and takes the RMS distance to it (sqrt of the smallest eigenvalue of their scatter). Prints the
median, 90th percentile and the share of neighbourhoods thicker than --thick, per map.

Usage: map_spread.py MAP.pcd [MAP2.pcd ...] [--radius 1.5] [--min-points 8] [--thick 0.1]
"""
import argparse
import sys

import numpy as np
from scipy.spatial import cKDTree


def read_pcd(path):
    """The points of a binary PCD file as a structured numpy array."""
    with open(path, "rb") as f:
        header = {}
        while True:
            line = f.readline()
            if not line:
                raise ValueError("%s: no DATA line" % path)
            words = line.decode("ascii", "replace").split()
            if not words or words[0].startswith("#"):
                continue
            header[words[0].upper()] = words[1:]
            if words[0].upper() == "DATA":
                break
        if header["DATA"][0] != "binary":
            raise ValueError("%s: only binary PCD is read" % path)
        kinds = {("F", "4"): "<f4", ("F", "8"): "<f8", ("U", "1"): "u1", ("U", "2"): "<u2", ("U", "4"): "<u4",
                 ("I", "1"): "i1", ("I", "2"): "<i2", ("I", "4"): "<i4"}
        counts = header.get("COUNT", ["1"] * len(header["FIELDS"]))
        dtype = []
        for i, (name, size, kind, count) in enumerate(zip(header["FIELDS"], header["SIZE"], header["TYPE"], counts)):
            dtype.append((name if name != "_" else "_pad%d" % i, kinds[(kind, size)], (int(count),)))
        points = int(header["POINTS"][0])
        return np.frombuffer(f.read(), dtype=np.dtype(dtype), count=points)


def spread(xyz, radius, min_points):
    """RMS plane distance of the neighbourhood of one sample point per 1 m cell."""
    tree = cKDTree(xyz)
    _, first = np.unique(np.floor(xyz / 1.0).astype(np.int64), axis=0, return_index=True)
    out = []
    for i in first:
        near = tree.query_ball_point(xyz[i], radius)
        if len(near) < min_points:
            continue
        p = xyz[near]
        scatter = np.cov((p - p.mean(axis=0)).T, bias=True)
        out.append(np.sqrt(max(np.linalg.eigvalsh(scatter)[0], 0.0)))
    return np.array(out)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("maps", nargs="+")
    parser.add_argument("--radius", type=float, default=1.5)
    parser.add_argument("--min-points", type=int, default=8)
    parser.add_argument("--thick", type=float, default=0.1)
    args = parser.parse_args()
    print("%-40s %8s %9s %9s %9s" % ("map", "samples", "median_m", "p90_m", "thick"))
    for path in args.maps:
        cloud = read_pcd(path)
        names = cloud.dtype.names
        planes = cloud[cloud["label"][:, 0] == 2] if "label" in names else cloud
        xyz = np.stack([planes[c][:, 0].astype(np.float64) for c in ("x", "y", "z")], axis=1)
        s = spread(xyz, args.radius, args.min_points)
        if s.size == 0:
            print("%s: no neighbourhood of %d points" % (path, args.min_points), file=sys.stderr)
            return 1
        print("%-40s %8d %9.3f %9.3f %8.1f%%" % (path[-40:], s.size, np.median(s), np.percentile(s, 90),
                                                 100.0 * np.mean(s > args.thick)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
