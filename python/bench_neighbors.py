"""Neighbour lists against the field's libraries, one thread, the same points for all.

Points uniform in a periodic cube at unit density, the cutoff giving about 30 neighbours per
point ((4/3) pi r^3 = 30). bpx returns i, j and the shifts (and, in its second row, the
distances too); vesin is asked for i and j, cKDTree gives pairs, the others their lists with
distances. Each library gives its own list (half or full, ASE's and matscipy's
and freud's full); every one is reduced to the sorted half list of (i, j) pairs and checked
equal to bpx's before its time counts. Times are the median of --rounds calls, alternating.

    python bench_neighbors.py --sizes 100000 1000000 --rounds 3
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import bpx  # noqa: E402


def half_pairs(i, j):
    """Sorted unique (i < j) rows of a half or full list."""
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    lo, hi = np.minimum(i, j), np.maximum(i, j)
    keep = lo != hi
    keys = np.unique(lo[keep] * (1 << 32) + hi[keep])
    return keys


def run_bpx(points, L, r):
    # i, j and the image shifts: what the peers below return (vesin asked for "ij", cKDTree's
    # pairs) and a little more; "bpx + distances" adds the float64 distances.
    nl = bpx.neighbor_pairs(points, r, cell=L, threads=1, distances=False)
    return nl.i, nl.j


def run_bpx_distances(points, L, r):
    nl = bpx.neighbor_pairs(points, r, cell=L, threads=1)
    return nl.i, nl.j


def run_vesin(points, L, r):
    from vesin import NeighborList

    i, j = NeighborList(cutoff=r, full_list=False).compute(
        points=points, box=np.diag([L, L, L]), periodic=True, quantities="ij"
    )
    return i, j


def run_freud_aabb(points, L, r):
    import freud

    box = freud.box.Box.cube(L)
    q = freud.locality.AABBQuery(box, points).query(points, dict(r_max=r, exclude_ii=True))
    nl = q.toNeighborList()
    return nl.query_point_indices, nl.point_indices


def run_freud_cells(points, L, r):
    import freud

    box = freud.box.Box.cube(L)
    q = freud.locality.LinkCell(box, points, cell_width=r).query(
        points, dict(r_max=r, exclude_ii=True)
    )
    nl = q.toNeighborList()
    return nl.query_point_indices, nl.point_indices


def run_matscipy(points, L, r):
    from matscipy.neighbours import neighbour_list

    i, j = neighbour_list("ij", positions=points, cutoff=r, cell=np.diag([L, L, L]),
                          pbc=[True] * 3)
    return i, j


def run_ase(points, L, r):
    import ase
    from ase.neighborlist import neighbor_list

    atoms = ase.Atoms(numbers=np.ones(len(points), dtype=int), positions=points,
                      cell=[L, L, L], pbc=True)
    i, j = neighbor_list("ij", atoms, r)
    return i, j


def run_ckdtree(points, L, r):
    from scipy.spatial import cKDTree

    pairs = cKDTree(points, boxsize=L).query_pairs(r, output_type="ndarray")
    return pairs[:, 0], pairs[:, 1]


PEERS = {
    "bpx": run_bpx,
    "bpx + distances": run_bpx_distances,
    "vesin": run_vesin,
    "freud AABBQuery": run_freud_aabb,
    "freud LinkCell": run_freud_cells,
    "matscipy": run_matscipy,
    "ASE": run_ase,
    "cKDTree boxsize": run_ckdtree,
}


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--neighbours", type=float, default=30.0)
    parser.add_argument("--skip", nargs="*", default=[], help="peers to leave out")
    args = parser.parse_args()
    try:
        import freud

        freud.parallel.set_num_threads(1)
    except ImportError:
        pass
    print(f"# bench_neighbors: {platform.processor() or platform.machine()}, "
          f"bpx {bpx.__version__}, one thread, median of {args.rounds} rounds")
    print("| points | library | ms | pairs (i < j) | / bpx time | exact |")
    print("| ---: | --- | ---: | ---: | ---: | --- |")
    for n in args.sizes:
        rng = np.random.default_rng(n)
        L = float(n) ** (1 / 3)  # unit density
        r = (3 * args.neighbours / (4 * np.pi)) ** (1 / 3)
        points = rng.uniform(0, L, size=(n, 3))
        want = None
        times = {name: [] for name in PEERS if name not in args.skip}
        counts = {}
        exact = {}
        for _ in range(args.rounds):
            for name in times:
                start = time.perf_counter()
                try:
                    i, j = PEERS[name](points, L, r)
                except ImportError:
                    times[name] = None
                    continue
                if times[name] is None:
                    continue
                times[name].append(time.perf_counter() - start)
                if name not in exact:
                    keys = half_pairs(i, j)
                    if want is None:
                        want = keys
                    counts[name] = len(keys)
                    exact[name] = bool(np.array_equal(keys, want))
        base = statistics.median(times["bpx"])
        for name, t in times.items():
            if not t:
                print(f"| {n:,} | {name} | not installed | | | |")
                continue
            m = statistics.median(t)
            print(f"| {n:,} | {name} | {m * 1e3:,.1f} | {counts[name]:,} | {m / base:.2f} | "
                  f"{'yes' if exact[name] else 'NO'} |", flush=True)


if __name__ == "__main__":
    main()
