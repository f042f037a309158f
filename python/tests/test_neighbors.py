"""neighbor_pairs and exact float64 find_pairs, against a NumPy brute force over every image,
scipy's cKDTree with boxsize and ASE's neighbour list on the same atoms."""

import itertools

import numpy as np
import pytest

import bpx


def brute_force(points, cutoff, period):
    """Every (i <= j, shift) with |p_j + shift * L - p_i| <= cutoff, in float64."""
    points = np.asarray(points, dtype=np.float64)
    period = np.asarray(period, dtype=np.float64)
    reach = [int(np.ceil(cutoff / L)) + 1 if L > 0 else 0 for L in period]
    # the points need not be in the cell: shifts cover where they are too
    span = np.ptp(points, axis=0) if len(points) else np.zeros(3)
    reach = [r + (int(np.ceil(s / L)) if L > 0 else 0) for r, s, L in zip(reach, span, period)]
    out = {}
    for shift in itertools.product(*[range(-r, r + 1) for r in reach]):
        shift = np.array(shift)
        image = points + shift * period
        d = np.linalg.norm(image[None, :, :] - points[:, None, :], axis=2)
        for i, j in zip(*np.nonzero(d <= cutoff)):
            if i > j or (i == j and tuple(shift) <= (0, 0, 0)):
                continue
            out[(int(i), int(j), *map(int, shift))] = d[i, j]
    return out


def as_dict(nl):
    return {
        (int(i), int(j), *map(int, s)): d
        for i, j, s, d in zip(nl.i, nl.j, nl.shifts, nl.distances)
    }


@pytest.mark.parametrize("cutoff", [0.0, 0.7, 2.5, 4.0, 7.0])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_against_brute_force(cutoff, dtype):
    rng = np.random.default_rng(int(cutoff * 10))
    period = np.array([5.0, 5.0, 0.0])  # z open; cutoffs up to past the cell
    points = rng.uniform(-6, 11, size=(40, 3)).astype(dtype)  # not wrapped
    points[:5, 0] = 0.0  # on a face
    points[5:8, 0] = 5.0
    nl = bpx.neighbor_pairs(points, cutoff, cell=[5, 5, 1], pbc=[True, True, False], vectors=True)
    want = brute_force(points, cutoff, period)
    got = as_dict(nl)
    assert got.keys() == want.keys()
    for key, d in want.items():
        assert got[key] == pytest.approx(d, rel=1e-12, abs=1e-12)
    # sorted by (i, j, shift), vectors consistent with the distances
    keys = list(zip(nl.i, nl.j, *nl.shifts.T))
    assert keys == sorted(keys)
    assert np.allclose(np.linalg.norm(nl.vectors, axis=1), nl.distances)


def test_against_ckdtree():
    spatial = pytest.importorskip("scipy.spatial")
    rng = np.random.default_rng(3)
    L = 12.0
    points = rng.uniform(0, L, size=(3000, 3))
    cutoff = 1.3
    nl = bpx.neighbor_pairs(points, cutoff, cell=L)
    tree = spatial.cKDTree(points, boxsize=L)
    want = tree.query_pairs(cutoff, output_type="ndarray")
    want = want[np.lexsort((want[:, 1], want[:, 0]))]
    assert np.array_equal(nl.pairs.astype(np.int64), want)
    # The distances are the minimum-image ones (the cutoff is under half the cell).
    diff = points[want[:, 1]] - points[want[:, 0]]
    diff -= L * np.round(diff / L)
    assert np.allclose(nl.distances, np.linalg.norm(diff, axis=1), rtol=1e-12, atol=1e-12)


def test_against_ase():
    ase = pytest.importorskip("ase")
    from ase.neighborlist import neighbor_list

    rng = np.random.default_rng(5)
    cell = np.diag([4.0, 5.0, 6.0])
    atoms = ase.Atoms("H" * 60, positions=rng.uniform(0, 1, (60, 3)) @ cell, cell=cell, pbc=True)
    for cutoff in (1.5, 3.0, 7.5):  # past half the cell and past the cell: several images
        i, j, S, d = neighbor_list("ijSd", atoms, cutoff)
        keep = (i < j) | ((i == j) & [tuple(s) > (0, 0, 0) for s in S])
        want = {(a, b, *map(int, s)): x for a, b, s, x in zip(i[keep], j[keep], S[keep], d[keep])}
        nl = bpx.neighbor_pairs(atoms.positions, cutoff, cell=atoms.cell.array)
        got = as_dict(nl)
        # ASE keeps pairs strictly below the cutoff; bpx keeps those at it too.
        assert {k for k, v in got.items() if v < cutoff} == want.keys()
        for key, x in want.items():
            assert got[key] == pytest.approx(x, rel=1e-12)


def test_boxes_box_metric():
    rng = np.random.default_rng(9)
    lo = rng.uniform(0, 8, size=(50, 3))
    boxes = np.concatenate([lo, lo + rng.uniform(0, 1.5, size=(50, 3))], axis=1)
    nl = bpx.neighbor_pairs(boxes, 0.25, cell=8)
    got = {(int(i), int(j), *map(int, s)) for i, j, s in zip(nl.i, nl.j, nl.shifts)}
    want = set()
    for i in range(50):
        for j in range(i, 50):
            for s in itertools.product(range(-2, 3), repeat=3):
                if i == j and s <= (0, 0, 0):
                    continue
                sh = np.array(s) * 8.0
                gap = np.maximum(boxes[j, :3] + sh - boxes[i, 3:], boxes[i, :3] - boxes[j, 3:] - sh)
                if gap.max() <= 0.25:
                    want.add((i, j, *s))
    assert got == want
    assert np.all(nl.distances <= 0.25)


def test_float64_exact():
    x = 1e6
    up = np.nextafter(x, 2 * x)
    boxes = np.array([[x / 2, 0, 0, x, 1, 1], [up, 0, 0, 2 * x, 1, 1]])
    assert bpx.find_pairs(boxes).shape == (0, 2)  # one float64 ulp apart
    assert bpx.find_pairs(boxes.astype(np.float32)).tolist() == [[0, 1]]  # float32 merges them
    tiny = np.array([[0, 0, 0, 1e-30, 1, 1], [np.nextafter(1e-30, 1), 0, 0, 1, 1, 1]])
    assert bpx.find_pairs(tiny).shape == (0, 2)
    ints = np.array([[16777217, 0, 0, 16777217, 0, 0], [0, 0, 0, 16777216, 0, 0]])
    assert bpx.find_pairs(ints).shape == (0, 2)  # 2^24 + 1 is not 2^24
    touching = np.array([[0, 0, 0, 2**40, 1, 1], [2**40, 0, 0, 2**41, 1, 1]], dtype=np.int64)
    assert bpx.find_pairs(touching).tolist() == [[0, 1]]
    with pytest.raises(bpx.InvalidArgumentError, match="2\\^53"):
        bpx.find_pairs(np.array([[0, 0, 0, 2**53 + 1, 1, 1]], dtype=np.int64))
    # points one ulp across a periodic face
    L = 1e6
    points = np.array([[np.nextafter(L, 0), 0, 0], [0, 0, 0]])
    assert len(bpx.neighbor_pairs(points, 0.0, cell=[L, 0, 0], pbc=[True, False, False]).i) == 0
    nl = bpx.neighbor_pairs(points, L - np.nextafter(L, 0), cell=[L, 1, 1], pbc=[1, 0, 0],
                            metric="box")
    assert nl.pairs.tolist() == [[0, 1]] and nl.shifts.tolist() == [[1, 0, 0]]


def test_empty_and_open():
    nl = bpx.neighbor_pairs(np.zeros((0, 3)), 1.0, cell=5)
    assert nl.pairs.shape == (0, 2) and nl.shifts.shape == (0, 3) and len(nl.distances) == 0
    nl = bpx.neighbor_pairs([[0, 0, 0], [1, 0, 0], [3, 0, 0]], 1.0)  # no cell: open
    assert nl.pairs.tolist() == [[0, 1]] and nl.shifts.tolist() == [[0, 0, 0]]
    assert nl.distances.tolist() == [1.0]


@pytest.mark.parametrize(
    "cell, match",
    [(0.0, "length"), (-1.0, "length"), (float("nan"), "length"), ([1, 2], "shape"),
     ([[1, 0.5, 0], [2, 1, 0], [0, 0, 1]], "singular"),
     ([[1, 0.5, 0], [0, 1, 0], [0, 0, np.nan]], "cell\\[2\\]\\[2\\]"),
     ([[1, 0.5, 0], [0, 1, 0], [0.5, 0.5, 1e-9]], "close to singular"),
     ([[1, 0.5, 0], [0, 1, 0], [0, 0, 0]], "zero on a periodic axis")],
)
def test_bad_cells(cell, match):
    with pytest.raises(bpx.InvalidArgumentError, match=match):
        bpx.neighbor_pairs([[0, 0, 0]], 1.0, cell=cell)


def test_bad_arguments():
    with pytest.raises(bpx.InvalidArgumentError, match="cutoff"):
        bpx.neighbor_pairs([[0, 0, 0]], -1.0, cell=2)
    with pytest.raises(bpx.InvalidArgumentError, match="cutoff"):
        bpx.neighbor_pairs([[0, 0, 0]], float("nan"))
    with pytest.raises(bpx.InvalidArgumentError, match="no cell"):
        bpx.neighbor_pairs([[0, 0, 0]], 1.0, pbc=[True, False, False])
    with pytest.raises(bpx.InvalidArgumentError, match="metric"):
        bpx.neighbor_pairs([[0, 0, 0]], 1.0, metric="manhattan")
    with pytest.raises(bpx.NotFiniteError) as info:
        bpx.neighbor_pairs([[0, 0, 0], [0, np.inf, 0]], 1.0)
    assert info.value.index == 1 and info.value.axis == 1
    with pytest.raises(bpx.TooManyBoxesError):
        bpx.neighbor_pairs(np.array([[0, 0, 0, 1, 1, 1.0]]), 0.0, cell=1e-12)


def test_threads_same_bytes():
    rng = np.random.default_rng(11)
    points = rng.uniform(0, 20, size=(20000, 3))
    one = bpx.neighbor_pairs(points, 1.1, cell=20, threads=1)
    three = bpx.neighbor_pairs(points, 1.1, cell=20, threads=3)
    for a, b in zip(one[:4], three[:4]):
        assert np.array_equal(a, b)
    # the image search (another backend) agrees with the cell list
    other = bpx.neighbor_pairs(points, 1.1, cell=20, backend="sap", threads=2)
    for a, b in zip(one[:4], other[:4]):
        assert np.array_equal(a, b)


def periodic_box_pairs(boxes, period, reach=2):
    """Every (i <= j, shift) with box i and the image of box j overlapping (closed intervals,
    float64), written for the purpose; a box and its own image when the shift is positive."""
    boxes = np.asarray(boxes, dtype=np.float64)
    period = np.asarray(period, dtype=np.float64)
    ranges = [range(-reach, reach + 1) if L > 0 else range(1) for L in period]
    want = set()
    for i in range(len(boxes)):
        for j in range(i, len(boxes)):
            for s in itertools.product(*ranges):
                if i == j and s <= (0, 0, 0):
                    continue
                sh = np.array(s) * period
                lo_j, hi_j = boxes[j, :3] + sh, boxes[j, 3:] + sh
                if np.all(boxes[i, :3] <= hi_j) and np.all(lo_j <= boxes[i, 3:]):
                    want.add((i, j, *s))
    return want


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("backend", ["auto", "reference", "sap", "grid"])
def test_find_pairs_periodic(dtype, backend):
    rng = np.random.default_rng(21)
    lo = rng.uniform(-2, 9, size=(60, 3))  # not wrapped into the cell
    size = rng.uniform(0, 2, size=(60, 3))
    size[:3] = [4.0, 0.5, 0.5]  # longer than half the cell on x: two images of a neighbour
    size[3] = [9.0, 0.3, 0.3]  # longer than the cell: it meets its own image
    lo[4:8, 0] = 0.0  # on the lower face
    lo[8:12, 0] = 6.0  # their images touch the upper face (boxes 4..7 at x = 0 + period)
    size[8:12, 0] = 0.0
    boxes = np.concatenate([lo, lo + size], axis=1).astype(dtype)
    cell, pbc = [6.0, 7.0, 100.0], [True, True, False]
    pairs, shifts = bpx.find_pairs(boxes, backend=backend, cell=cell, pbc=pbc, return_shifts=True)
    got = [(int(i), int(j), *map(int, s)) for (i, j), s in zip(pairs, shifts)]
    assert got == sorted(got) and len(set(got)) == len(got)
    assert set(got) == periodic_box_pairs(boxes, [6.0, 7.0, 0.0])
    assert np.all(shifts[:, 2] == 0)
    # the same pairs without the shifts, and the same as neighbor_pairs at cutoff 0
    assert np.array_equal(bpx.find_pairs(boxes, backend=backend, cell=cell, pbc=pbc), pairs)
    nl = bpx.neighbor_pairs(boxes, 0.0, cell=cell, pbc=pbc, metric="box", distances=False)
    assert np.array_equal(nl.pairs, pairs) and np.array_equal(nl.shifts, shifts)


def test_find_pairs_periodic_float64_exact():
    # Across the periodic face, one float64 ulp apart: no pair; touching: a pair.
    L = 1e6
    below = np.nextafter(L, 0)
    boxes = np.array([[0, 0, 0, 1, 1, 1], [L - 1, 0, 0, below, 1, 1]])
    assert bpx.find_pairs(boxes, cell=[L, 0, 0], pbc=[True, False, False]).shape == (0, 2)
    boxes[1, 3] = L
    pairs, shifts = bpx.find_pairs(boxes, cell=[L, 0, 0], pbc=[True, False, False],
                                   return_shifts=True)
    assert pairs.tolist() == [[0, 1]] and shifts.tolist() == [[-1, 0, 0]]
    # rounded to float32 (by the caller) the ulp is lost and the boxes touch
    boxes[1, 3] = below
    assert bpx.find_pairs(boxes.astype(np.float32), cell=L, pbc=[1, 0, 0]).tolist() == [[0, 1]]


def test_find_pairs_open_shifts_and_bad_cells():
    rng = np.random.default_rng(5)
    lo = rng.uniform(0, 10, size=(200, 3)).astype(np.float32)
    boxes = np.concatenate([lo, lo + 1], axis=1)
    pairs, shifts = bpx.find_pairs(boxes, return_shifts=True)  # no cell: the plain pairs
    assert np.array_equal(pairs, bpx.find_pairs(boxes))
    assert shifts.shape == (len(pairs), 3) and not shifts.any()
    with pytest.raises(bpx.InvalidArgumentError, match="find_pairs"):
        bpx.find_pairs(boxes, cell=[0, 5, 5])
    with pytest.raises(bpx.InvalidArgumentError, match="triclinic"):
        bpx.find_pairs(boxes, cell=[[5, 1, 0], [0, 5, 0], [0, 0, 5]])


# --- triclinic cells -------------------------------------------------------------------------

TRICLINIC = {
    "general": [[5.0, 0.0, 0.0], [1.25, 4.5, 0.0], [-0.75, 1.5, 4.0]],
    # face distances 0.6 to 2.1 against vectors of length 4 to 9
    "sheared": [[4.0, 0.0, 0.0], [7.5, 3.0, 0.0], [-5.0, 6.25, 2.5]],
    "hexagonal": [[3.0, 0.0, 0.0], [-1.5, 1.5 * np.sqrt(3), 0.0], [0.0, 0.0, 4.9]],
    "left-handed": [[1.25, 4.5, 0.0], [5.0, 0.0, 0.0], [-0.75, 1.5, 4.0]],
    "rotated": [[3.1, 1.7, -0.4], [-1.2, 3.9, 0.8], [0.9, -0.6, 4.4]],
}


def face_distances(cell):
    cell = np.asarray(cell, dtype=np.float64)
    volume = abs(np.linalg.det(cell))
    return np.array([volume / np.linalg.norm(np.cross(cell[(k + 1) % 3], cell[(k + 2) % 3]))
                     for k in range(3)])


def brute_force_triclinic(points, cutoff, cell, pbc=(True, True, True)):
    """Every (i <= j, S) with |x_j - x_i + S @ cell| <= cutoff, over every image shift that can
    reach (from the fractional coordinates, two more each way), in float64."""
    points = np.asarray(points, dtype=np.float64)
    cell = np.asarray(cell, dtype=np.float64)
    frac = points @ np.linalg.inv(cell)
    reach = cutoff / face_distances(cell)
    span = np.ptp(frac, axis=0) if len(points) else np.zeros(3)
    ranges = [range(-int(np.ceil(r + s)) - 2, int(np.ceil(r + s)) + 3) if p else range(1)
              for r, s, p in zip(reach, span, pbc)]
    out = {}
    for shift in itertools.product(*ranges):
        S = np.array(shift, dtype=np.float64)
        image = S[0] * cell[0] + S[1] * cell[1] + S[2] * cell[2]
        v = (points[None, :, :] + image) - points[:, None, :]
        d = np.sqrt((v * v).sum(axis=2))
        for i, j in zip(*np.nonzero(d <= cutoff)):
            if i > j or (i == j and tuple(shift) <= (0, 0, 0)):
                continue
            out[(int(i), int(j), *shift)] = d[i, j]
    return out


@pytest.mark.parametrize("name", sorted(TRICLINIC))
@pytest.mark.parametrize("scale", [0.3, 0.7, 1.6])  # of the thinnest face distance
def test_triclinic_against_brute_force(name, scale):
    cell = np.array(TRICLINIC[name])
    cutoff = scale * face_distances(cell).min()
    rng = np.random.default_rng(int(scale * 10) + len(name))
    frac = rng.uniform(-1, 2, size=(70, 3))  # inside and up to a cell out
    frac[:6] = [[0, 0, 0], [1, 0, 0], [0, 1, 1], [0.5, 0, 0], [0, 0.5, 1], [1, 1, 1]]  # walls
    points = frac @ cell
    nl = bpx.neighbor_pairs(points, cutoff, cell=cell, vectors=True)
    want = brute_force_triclinic(points, cutoff, cell)
    got = as_dict(nl)
    assert got.keys() == want.keys()
    for key, d in want.items():
        assert got[key] == pytest.approx(d, rel=1e-12, abs=1e-12)
    keys = list(zip(nl.i, nl.j, *nl.shifts.T))
    assert keys == sorted(keys)
    # the vectors are x_j - x_i + S @ cell, their lengths the distances (same operations)
    assert np.array_equal(np.sqrt((nl.vectors ** 2).sum(axis=1)), nl.distances)
    assert np.allclose(nl.vectors, points[nl.j] - points[nl.i] + nl.shifts @ cell,
                       rtol=0, atol=1e-12)
    # past the shortest lattice vector: every point meets its own images
    shortest = min(np.linalg.norm(np.array(S) @ cell)
                   for S in itertools.product(range(-3, 4), repeat=3) if any(S))
    if cutoff > shortest:
        assert np.count_nonzero(nl.i == nl.j) >= len(points)


def ase_half_list(atoms, cutoff):
    from ase.neighborlist import neighbor_list

    i, j, S, d, D = neighbor_list("ijSdD", atoms, cutoff)
    keep = (i < j) | ((i == j) & np.array([tuple(s) > (0, 0, 0) for s in S], dtype=bool))
    return {(int(a), int(b), *map(int, s)): (x, v)
            for a, b, s, x, v in zip(i[keep], j[keep], S[keep], d[keep], D[keep])}


@pytest.mark.parametrize("name", sorted(TRICLINIC))
def test_triclinic_against_ase(name):
    ase = pytest.importorskip("ase")
    cell = np.array(TRICLINIC[name])
    rng = np.random.default_rng(len(name))
    frac = rng.uniform(-0.5, 1.5, size=(60, 3))  # ASE takes atoms outside the cell too
    atoms = ase.Atoms("H" * 60, positions=frac @ cell, cell=cell, pbc=True)
    faces = face_distances(cell)
    # under half the thinnest face, past it (several images of a pair), past the thickest
    for cutoff in (0.4 * faces.min(), 1.3 * faces.min(), 1.2 * faces.max()):
        want = ase_half_list(atoms, cutoff)
        nl = bpx.neighbor_pairs(atoms.positions, cutoff, cell=atoms.cell.array, vectors=True)
        got = {key: (d, v) for key, d, v in zip(as_dict(nl), nl.distances, nl.vectors)}
        # ASE keeps pairs strictly below the cutoff; bpx keeps those at it too.
        assert {k for k, (d, _) in got.items() if d < cutoff} == want.keys()
        for key, (d, v) in want.items():
            assert got[key][0] == pytest.approx(d, rel=1e-12)
            assert np.allclose(got[key][1], v, rtol=0, atol=1e-11)


def test_triclinic_slab_against_ase():
    ase = pytest.importorskip("ase")
    # c open and zero in the cell, as ASE takes a slab; bpx completes it as ASE does
    cell = np.array([[4.0, 0.0, 0.0], [1.7, 3.6, 0.0], [0.0, 0.0, 0.0]])
    rng = np.random.default_rng(17)
    positions = rng.uniform(0, 1, size=(90, 3)) @ np.array([cell[0], cell[1], [0, 0, 6.0]])
    atoms = ase.Atoms("H" * 90, positions=positions, cell=cell, pbc=[True, True, False])
    for cutoff in (1.5, 4.5):
        want = ase_half_list(atoms, cutoff)
        nl = bpx.neighbor_pairs(positions, cutoff, cell=cell, pbc=[True, True, False])
        got = as_dict(nl)
        assert {k for k, d in got.items() if d < cutoff} == want.keys()
        assert not nl.shifts[:, 2].any()
        for key, (d, _) in want.items():
            assert got[key] == pytest.approx(d, rel=1e-12)


def test_triclinic_float32_threads_and_open():
    cell = np.array(TRICLINIC["sheared"])
    rng = np.random.default_rng(23)
    points = (rng.uniform(0, 3, size=(20000, 3)) @ cell).astype(np.float32)
    one = bpx.neighbor_pairs(points, 0.25, cell=cell, threads=1)  # about 22 neighbours
    three = bpx.neighbor_pairs(points, 0.25, cell=cell, threads=3)
    for a, b in zip(one[:4], three[:4]):
        assert np.array_equal(a, b)
    small = (rng.uniform(0, 1, size=(120, 3)) @ cell).astype(np.float32)
    want = brute_force_triclinic(small, 1.4, cell)
    assert as_dict(bpx.neighbor_pairs(small, 1.4, cell=cell)).keys() == want.keys()
    # no periodic axis: the cell does not matter
    open_ = bpx.neighbor_pairs(small, 1.4, cell=cell, pbc=False)
    plain = bpx.neighbor_pairs(small, 1.4)
    assert np.array_equal(open_.pairs, plain.pairs) and not open_.shifts.any()


def test_triclinic_refusals():
    cell = TRICLINIC["general"]
    boxes = np.array([[0, 0, 0, 1, 1, 1.0]])
    with pytest.raises(bpx.InvalidArgumentError, match="triclinic cell takes points"):
        bpx.neighbor_pairs(boxes, 1.0, cell=cell)
    with pytest.raises(bpx.InvalidArgumentError, match="triclinic cell takes points"):
        bpx.neighbor_pairs([[0, 0, 0]], 1.0, cell=cell, metric="box")
    with pytest.raises(bpx.TooManyBoxesError, match="2\\^29 cells"):
        bpx.neighbor_pairs([[0, 0, 0], [1e10, 0, 0]], 1.0, cell=cell)
    with pytest.raises(bpx.TooManyBoxesError):
        bpx.neighbor_pairs([[0, 0, 0]], 1e4, cell=cell)  # 2000^3 images of each bin
    with pytest.raises(bpx.NotFiniteError) as info:
        bpx.neighbor_pairs([[0, 0, 0], [0, 0, np.nan]], 1.0, cell=cell)
    assert info.value.index == 1 and info.value.axis == 2
    with pytest.raises(bpx.InvalidArgumentError, match="triclinic"):
        bpx.find_pairs(boxes, cell=cell)  # find_pairs and World: orthorhombic only
