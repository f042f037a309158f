"""Neighbour lists against the field's libraries, one thread, the same points for all.

Points uniform in a periodic cube at unit density, the cutoff giving about 30 neighbours per
point ((4/3) pi r^3 = 30). bpx returns i, j and the shifts (and, in its second row, the
distances too); vesin is asked for i and j, cKDTree gives pairs, the others their lists with
distances. Each library gives its own list (half or full, ASE's and matscipy's
and freud's full); every one is reduced to the sorted half list of (i, j) pairs and checked
equal to bpx's before its time counts. Times are the median of --rounds calls, alternating.

    python bench_neighbors.py --sizes 100000 1000000 --rounds 3
    python bench_neighbors.py --triclinic --sizes 100000 --rounds 5 --skip "ASE triclinic"
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


# Triclinic cells (--triclinic): the same density in a cell of LAMMPS tilts xy 0.3, xz 0.2,
# yz -0.25 (or --shape fcc: the primitive cell of fcc, 60-degree angles; --shape sheared: a
# strongly sheared one, which bpx reduces first), against bpx on a cube
# of the same volume and points; the peers that take a triclinic cell.
SHAPES = {
    "tilted": np.array([[1.0, 0.0, 0.0], [0.3, 1.0, 0.0], [0.2, -0.25, 1.0]]),
    "fcc": np.array([[0.0, 0.5, 0.5], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0]]),
    # strongly sheared (test_neighbors_triclinic's "sheared"): bins 23 times a cube's unreduced
    "sheared": np.array([[4.0, 0.0, 0.0], [7.5, 3.0, 0.0], [-5.0, 6.25, 2.5]]),
}


def tri_bpx_cubic(points, cell, r):
    # the orthorhombic fast path: a cube of the same volume, the same fractional points
    L = abs(np.linalg.det(cell)) ** (1 / 3)
    nl = bpx.neighbor_pairs(points @ np.linalg.inv(cell) * L, r, cell=L, threads=1,
                            distances=False)
    return nl.i, nl.j


def tri_bpx(points, cell, r):
    nl = bpx.neighbor_pairs(points, r, cell=cell, threads=1, distances=False)
    return nl.i, nl.j


def tri_bpx_distances(points, cell, r):
    nl = bpx.neighbor_pairs(points, r, cell=cell, threads=1)
    return nl.i, nl.j


def tri_vesin(points, cell, r):
    from vesin import NeighborList

    return NeighborList(cutoff=r, full_list=False).compute(
        points=points, box=cell, periodic=True, quantities="ij")


def tri_matscipy(points, cell, r):
    from matscipy.neighbours import neighbour_list

    return neighbour_list("ij", positions=points, cutoff=r, cell=cell, pbc=[True] * 3)


def tri_ase(points, cell, r):
    import ase
    from ase.neighborlist import neighbor_list

    atoms = ase.Atoms(numbers=np.ones(len(points), dtype=int), positions=points, cell=cell,
                      pbc=True)
    return neighbor_list("ij", atoms, r)


TRICLINIC_PEERS = {
    "bpx cubic (same density)": tri_bpx_cubic,
    "bpx triclinic": tri_bpx,
    "bpx triclinic + distances": tri_bpx_distances,
    "vesin triclinic": tri_vesin,
    "matscipy triclinic": tri_matscipy,
    "ASE triclinic": tri_ase,
}


def main_triclinic(args):
    shape = SHAPES[args.shape]
    print(f"# bench_neighbors --triclinic --shape {args.shape}: "
          f"{platform.processor() or platform.machine()}, bpx {bpx.__version__}, one thread, "
          f"median of {args.rounds} rounds; cell rows {shape.tolist()} scaled to unit density")
    print("| points | library | ms | pairs (i < j) | / bpx cubic | / bpx triclinic | same pairs |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | --- |")
    for n in args.sizes:
        rng = np.random.default_rng(n)
        cell = shape * (n / abs(np.linalg.det(shape))) ** (1 / 3)  # unit density
        r = (3 * args.neighbours / (4 * np.pi)) ** (1 / 3)
        points = rng.uniform(0, 1, size=(n, 3)) @ cell
        times = {name: [] for name in TRICLINIC_PEERS if name not in args.skip}
        counts, exact, want = {}, {}, {}
        for _ in range(args.rounds):
            for name in times:
                if times[name] is None:
                    continue
                start = time.perf_counter()
                try:
                    i, j = TRICLINIC_PEERS[name](points, cell, r)
                except ImportError:
                    times[name] = None
                    continue
                times[name].append(time.perf_counter() - start)
                if name not in exact:
                    keys = half_pairs(i, j)
                    group = "cubic" if "cubic" in name else "triclinic"
                    want.setdefault(group, keys)
                    counts[name] = len(keys)
                    exact[name] = bool(np.array_equal(keys, want[group]))
        base = statistics.median(times["bpx cubic (same density)"])
        tri = statistics.median(times["bpx triclinic"])
        for name, t in times.items():
            if not t:
                print(f"| {n:,} | {name} | not installed | | | | |")
                continue
            m = statistics.median(t)
            print(f"| {n:,} | {name} | {m * 1e3:,.1f} | {counts[name]:,} | {m / base:.2f} | "
                  f"{m / tri:.2f} | {'yes' if exact[name] else 'NO'} |", flush=True)


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
    parser.add_argument("--triclinic", action="store_true",
                        help="a triclinic cell against a cube of the same density")
    parser.add_argument("--shape", choices=sorted(SHAPES), default="tilted")
    args = parser.parse_args()
    if args.triclinic:
        main_triclinic(args)
        return
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
