"""World over a periodic cell: pairs, image pairs, events, filters and snapshots against a
brute force over the images written here, for the CPU backends."""

import itertools

import numpy as np
import pytest

import bpx

CPU_BACKENDS = ["auto", "reference", "brute", "prune", "sap", "grid"]


def image_pairs(boxes, period, reach=2):
    """Every (i <= j, shift) with box i and box j moved by shift * period overlapping (closed
    intervals, float64 on the float32 values); a box with its own image when the shift is
    positive (first non-zero component)."""
    boxes = np.asarray(boxes, dtype=np.float64)
    period = np.asarray(period, dtype=np.float64)
    ranges = [range(-reach, reach + 1) if L > 0 else range(1) for L in period]
    out = set()
    for s in itertools.product(*ranges):
        sh = np.array(s) * period
        lo_j, hi_j = boxes[:, :3] + sh, boxes[:, 3:] + sh
        hit = np.all(boxes[:, None, :3] <= hi_j[None, :, :], axis=2) & np.all(
            lo_j[None, :, :] <= boxes[:, None, 3:], axis=2
        )
        for i, j in zip(*np.nonzero(hit)):
            if i < j or (i == j and s > (0, 0, 0)):
                out.add((int(i), int(j), *s))
    return out


def scene(rng, n, cell):
    lo = rng.uniform(-3, 13, size=(n, 3))  # not wrapped into the cell
    size = rng.uniform(0, 2.5, size=(n, 3))
    size[0] = [6.0, 0.5, 0.5]  # past half the cell on x
    size[1] = [11.0, 0.2, 0.2]  # past the whole cell on x: meets its own image
    lo[2:6, 0] = 0.0  # on the lower face
    lo[6:10, 0] = cell[0] - 1.0  # touching the upper face
    size[6:10, 0] = 1.0
    return np.concatenate([lo, lo + size], axis=1).astype(np.float32)


def as_set(pairs, shifts):
    return {(int(i), int(j), *map(int, s)) for (i, j), s in zip(pairs, shifts)}


@pytest.mark.parametrize("backend", CPU_BACKENDS)
@pytest.mark.parametrize("threads", [1, 3])
def test_pairs_and_images_against_brute_force(backend, threads):
    cell = [10.0, 9.0, 100.0]
    rng = np.random.default_rng(3)
    with bpx.World(backend, threads, cell=cell, pbc=[True, True, False]) as w:
        assert w.period == (10.0, 9.0, 0.0)
        for _ in range(3):
            boxes = scene(rng, 60, cell)
            w.set_boxes(boxes)
            got_pairs = w.collide()
            pairs, shifts = w.image_pairs()
            want = image_pairs(boxes, [10.0, 9.0, 0.0])
            assert as_set(pairs, shifts) == want
            keys = [(int(i), int(j), *map(int, s)) for (i, j), s in zip(pairs, shifts)]
            assert keys == sorted(keys)
            distinct = sorted({(i, j) for i, j, *_ in want if i < j})
            assert got_pairs.tolist() == [list(p) for p in distinct]
            assert np.array_equal(w.pairs, got_pairs)


def test_same_as_find_pairs_with_a_cell():
    rng = np.random.default_rng(4)
    boxes = scene(rng, 200, [10.0, 10.0, 10.0])
    with bpx.World(cell=10.0) as w:
        w.set_boxes(boxes)
        w.collide()
        pairs, shifts = w.image_pairs()
    want_pairs, want_shifts = bpx.find_pairs(boxes, cell=10.0, return_shifts=True)
    assert np.array_equal(pairs, want_pairs) and np.array_equal(shifts, want_shifts)


def test_events_filters_and_exclusions_on_distinct_pairs():
    cell = [10.0, 10.0, 10.0]
    with bpx.World(track_events=True, cell=cell) as w:
        # box 1 moves across the x face: it meets box 0 through the periodic image only
        boxes = np.array([[0.0, 0, 0, 1, 1, 1], [5, 0, 0, 6, 1, 1], [0, 5, 5, 1, 6, 6]], np.float32)
        w.set_boxes(boxes)
        assert w.collide().tolist() == []
        boxes[1] = [9.5, 0, 0, 10.5, 1, 1]  # its image at -0.5 .. 0.5 overlaps box 0
        w.set_boxes(boxes)
        assert w.collide().tolist() == [[0, 1]]
        assert w.events.began.tolist() == [[0, 1]]
        pairs, shifts = w.image_pairs()
        assert pairs.tolist() == [[0, 1]] and shifts.tolist() == [[-1, 0, 0]]
        boxes[1] = [10.2, 0, 0, 10.8, 1, 1]  # inside box 0's image: still one pair, no event
        w.set_boxes(boxes)
        assert w.collide().tolist() == [[0, 1]]
        assert w.events.began.tolist() == [] and w.events.ended.tolist() == []
        w.exclude_pairs([[0, 1]])
        assert w.collide().tolist() == []
        assert w.events.ended.tolist() == [[0, 1]]
        assert w.image_pairs()[0].shape == (0, 2)
        w.include_pairs([[0, 1]])
        w.set_filters(None, [1, 2, 1], [1, 1, 1])  # box 1 sees nobody with mask 1
        assert w.collide().tolist() == []


def test_snapshot_carries_the_cell():
    rng = np.random.default_rng(8)
    boxes = scene(rng, 80, [10.0, 10.0, 10.0])
    with bpx.World(track_events=True, cell=[10.0, 10.0, 10.0]) as w:
        w.set_boxes(boxes)
        w.collide()
        data = w.snapshot()
        moved = boxes + np.float32(0.3)
        w.set_boxes(moved)
        want = w.collide(), w.image_pairs(), w.events
    with bpx.World(track_events=True) as fresh:  # open, takes the snapshot's cell
        fresh.restore(data)
        assert fresh.period == (10.0, 10.0, 10.0)
        fresh.set_boxes(moved)
        got = fresh.collide(), fresh.image_pairs(), fresh.events
    assert np.array_equal(got[0], want[0])
    assert all(np.array_equal(a, b) for a, b in zip(got[1], want[1]))
    assert all(np.array_equal(a, b) for a, b in zip(got[2], want[2]))


def test_bad_cells_and_margins():
    with pytest.raises(bpx.InvalidArgumentError, match="World"):
        bpx.World(cell=[0.0, 5.0, 5.0])
    with pytest.raises(bpx.InvalidArgumentError, match="triclinic"):
        bpx.World(cell=[[5, 1, 0], [0, 5, 0], [0, 0, 5]])
    with pytest.raises(bpx.InvalidArgumentError, match="margin"):
        bpx.World(cell=5.0, end_margin=0.5)
    with bpx.World() as w:  # open: image pairs are the pairs, shift 0
        w.set_boxes(np.array([[0, 0, 0, 1, 1, 1], [1, 1, 1, 2, 2, 2]], np.float32))
        w.collide()
        pairs, shifts = w.image_pairs()
        assert pairs.tolist() == [[0, 1]] and shifts.tolist() == [[0, 0, 0]]
        assert w.period == (0.0, 0.0, 0.0)


def test_float64_boxes_are_exact_in_a_world():
    x = 1e6
    up = np.nextafter(x, 2 * x)
    apart = np.array([[x / 2, 0, 0, x, 1, 1], [up, 0, 0, 2 * x, 1, 1]])  # one float64 ulp
    with bpx.World(track_events=True) as w:
        w.set_boxes(apart)
        assert w.collide().shape == (0, 2)
        with pytest.raises(bpx.StateError, match="float64"):
            w.add(np.zeros((1, 6), np.float32))
        with pytest.raises(bpx.StateError, match="float64"):
            w.snapshot()
        w.set_boxes(apart, exact=False)  # rounded to float32: they touch
        assert w.collide().tolist() == [[0, 1]]
        w.add(np.zeros((1, 6), np.float32))  # a float32 world again
        # float64 values float32 holds take the float32 path: add and move keep working
        w.set_boxes(np.array([[0, 0, 0, 1, 1, 1], [1, 1, 1, 2, 2, 2]], np.float64))
        w.move([1], np.array([[0.5, 0.5, 0.5, 2, 2, 2]]))
        assert w.collide().tolist() == [[0, 1]]
        snapshot = w.snapshot()
        assert len(snapshot) > 0
        # integers past 2^24 and tiny values, exact
        ints = np.array([[16777217, 0, 0, 16777217, 0, 0], [0, 0, 0, 16777216, 0, 0]])
        w.set_boxes(ints)
        assert w.collide().shape == (0, 2)
        tiny = np.array([[0, 0, 0, 1e-30, 1, 1], [np.nextafter(1e-30, 1), 0, 0, 1, 1, 1]])
        w.set_boxes(tiny)
        assert w.collide().shape == (0, 2)
        w.set_boxes(tiny, exact=False)
        assert w.collide().tolist() == [[0, 1]]
        with pytest.raises(bpx.InvalidArgumentError, match="2\\^53"):
            w.set_boxes(np.array([[0, 0, 0, 2**53 + 1, 1, 1]], dtype=np.int64))
        with pytest.raises(bpx.NotFiniteError):
            w.set_boxes(np.array([[0, 0, 0, np.nan, 1, 1], [0, 0, 0, 1, 1, 1.5]]))


@pytest.mark.parametrize("backend", CPU_BACKENDS)
def test_float64_world_against_brute_force(backend):
    rng = np.random.default_rng(12)
    lo = rng.uniform(0, 10, size=(150, 3))
    boxes = np.concatenate([lo, lo + rng.uniform(0, 1.5, size=(150, 3))], axis=1)
    # each odd box starts one float64 ulp past its even neighbour's end on x, the same on y, z
    boxes[1::2] = boxes[0::2]
    boxes[1::2, 0] = np.nextafter(boxes[0::2, 3], np.inf)
    boxes[1::2, 3] = boxes[1::2, 0] + 1.0
    with bpx.World(backend, 2) as w:
        w.set_boxes(boxes)
        got = w.collide()
    want = [
        [i, j]
        for i in range(150)
        for j in range(i + 1, 150)
        if np.all(boxes[i, :3] <= boxes[j, 3:]) and np.all(boxes[j, :3] <= boxes[i, 3:])
    ]
    assert got.tolist() == want
    assert [0, 1] not in want
    with bpx.World(backend) as w:  # rounded to float32, the neighbours touch
        w.set_boxes(boxes, exact=False)
        assert [0, 1] in w.collide().tolist()
    # a periodic float64 world: the same as find_pairs with the cell
    with bpx.World(backend, cell=10.0) as w:
        w.set_boxes(boxes)
        w.collide()
        pairs, shifts = w.image_pairs()
    want_pairs, want_shifts = bpx.find_pairs(boxes, cell=10.0, return_shifts=True)
    assert np.array_equal(pairs, want_pairs) and np.array_equal(shifts, want_shifts)
