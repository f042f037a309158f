"""Empty input gives empty results of the usual shape and dtype from every call that returns
pairs or hits; a pair count past what can be returned raises TooManyPairsError before its
memory is taken."""

import numpy as np
import pytest

import bpx
from bpx import _bpx

EMPTY_BOXES = [
    np.zeros((0, 6), np.float32),
    np.zeros((0, 2, 3), np.float32),
    np.zeros((0, 6)),  # float64: converted
    np.zeros((0, 6), np.int32),
    np.zeros(0, np.float32),
    [],
]


def is_empty_pairs(pairs):
    return pairs.shape == (0, 2) and pairs.dtype == np.uint32


@pytest.mark.parametrize("boxes", EMPTY_BOXES, ids=lambda b: f"{np.shape(b)}")
def test_find_pairs_of_no_boxes(backend, boxes):
    assert is_empty_pairs(bpx.find_pairs(boxes, backend=backend))
    assert is_empty_pairs(bpx.find_pairs(boxes, backend=backend, threads=4))


def test_find_pairs_of_no_mins_and_maxs():
    assert is_empty_pairs(bpx.find_pairs(mins=np.zeros((0, 3)), maxs=[]))


def test_empty_shapes_that_are_not_boxes_are_refused():
    for bad in (np.zeros((0, 5)), np.zeros((0, 2, 2)), np.zeros((3, 0))):
        with pytest.raises(bpx.InvalidArgumentError):
            bpx.find_pairs(bad)


@pytest.mark.parametrize("boxes", EMPTY_BOXES, ids=lambda b: f"{np.shape(b)}")
def test_world_of_no_boxes(backend, boxes):
    with bpx.World(backend, track_events=True) as world:
        assert is_empty_pairs(world.pairs)  # before any collide
        world.set_boxes(boxes)
        assert is_empty_pairs(world.collide())
        assert is_empty_pairs(world.pairs)
        began, ended = world.events
        assert is_empty_pairs(began) and is_empty_pairs(ended)
        ids = world.add(boxes)
        assert ids.shape == (0,) and ids.dtype == np.uint32
        assert len(world) == 0


def test_two_phase_world_of_no_objects():
    with bpx.World(track_events=True) as world:
        world.load_extents([])
        world.update_centres(np.zeros((0, 3), np.float32))
        assert is_empty_pairs(world.collide())
        assert all(is_empty_pairs(p) for p in world.events)


def test_events_go_empty_when_every_box_leaves():
    boxes = np.array([[0, 0, 0, 1, 1, 1], [0.5, 0.5, 0.5, 2, 2, 2]], np.float32)
    with bpx.World(track_events=True) as world:
        world.set_boxes(boxes)
        assert world.collide().tolist() == [[0, 1]]
        world.set_boxes([])
        assert is_empty_pairs(world.collide())
        began, ended = world.events
        assert is_empty_pairs(began) and ended.tolist() == [[0, 1]]
        world.set_boxes([])
        world.collide()
        assert all(is_empty_pairs(p) for p in world.events)


def test_queries_on_and_of_nothing():
    with bpx.World() as world:
        world.set_boxes([])
        ids = world.query_box([0, 0, 0, 1, 1, 1])
        assert ids.shape == (0,) and ids.dtype == np.uint32
        assert world.query_sphere([0, 0, 0], 1.0).shape == (0,)
        assert world.query_point([0, 0, 0]).shape == (0,)
        assert world.query_oriented([0, 0, 0], [1, 1, 1], np.eye(3)).shape == (0,)
        assert world.ray_cast([0, 0, 0], [1, 0, 0]) is None
        hits = world.ray_cast([0, 0, 0], [1, 0, 0], all=True)
        assert hits.ids.shape == (0,) and hits.fractions.dtype == np.float32
        assert world.sweep([0, 0, 0, 1, 1, 1], [1, 0, 0]) is None
        world.prepare_queries()
        assert world.query_box([0, 0, 0, 1, 1, 1], shared=True).shape == (0,)
        seen = []
        world.query_box([0, 0, 0, 1, 1, 1], each=lambda *hit: seen.append(hit))
        assert seen == []
    with bpx.World() as world:
        world.set_boxes([[0, 0, 0, 1, 1, 1]])
        for batch in (
            world.query_box_batch([]),
            world.query_box_batch(np.zeros((0, 2, 3))),
            world.query_sphere_batch([], 1.0),
            world.query_point_batch([]),
            world.query_oriented_batch([], [], np.zeros((0, 3, 3))),
        ):
            assert batch.offsets.tolist() == [0] and batch.ids.shape == (0,)
            assert batch.ids.dtype == np.uint32 and batch.split() == []
        for batch in (
            world.ray_cast_batch([], []),
            world.sweep_batch([], np.zeros((0, 3))),
            world.ray_cast_batch([], [], all=True),
        ):
            assert batch.offsets.tolist() == [0] and batch.ids.shape == (0,)
            assert batch.fractions.shape == (0,) and batch.fractions.dtype == np.float32


# -- TooManyPairsError ---------------------------------------------------------------------------


@pytest.fixture
def pair_limit():
    """Lowers the most pairs a result may hold (really PY_SSIZE_T_MAX / 8: beyond a 64-bit
    host's reach) for one test, so the error shows without the memory it stands for."""
    previous = _bpx._set_max_pairs(0)
    yield lambda count: _bpx._set_max_pairs(count)
    _bpx._set_max_pairs(previous)


def stack(n):
    """n boxes that all overlap: n (n - 1) / 2 pairs."""
    return np.tile(np.array([0, 0, 0, 1, 1, 1], np.float32), (n, 1))


def test_the_real_limit_is_past_any_64_bit_pair_count():
    previous = _bpx._set_max_pairs(0)
    _bpx._set_max_pairs(previous)
    if np.intp(0).itemsize == 8:
        n = bpx.MAX_BOXES
        assert previous >= n * (n - 1) // 2  # never raised for lack of room on 64-bit
    assert previous * 8 <= np.iinfo(np.intp).max


@pytest.mark.parametrize("threads", [1, 3])
def test_find_pairs_past_the_limit(backend, pair_limit, threads):
    pair_limit(44)
    before = _bpx._allocated_bytes()
    with pytest.raises(bpx.TooManyPairsError) as info:
        bpx.find_pairs(stack(10), backend=backend, threads=threads)  # 45 pairs
    e = info.value
    assert isinstance(e, bpx.Error) and isinstance(e, OverflowError)
    assert e.status == "BPX_ERR_TOO_MANY_PAIRS"
    assert "45 pairs" in str(e) and "44" in str(e) and str(e).startswith("find_pairs:")
    assert _bpx._allocated_bytes() == before  # the one-shot world is gone with its pairs
    pair_limit(45)
    assert bpx.find_pairs(stack(10), backend=backend).shape == (45, 2)


def test_world_past_the_limit(pair_limit):
    with bpx.World(track_events=True) as world:
        world.set_boxes(stack(10))
        pair_limit(44)
        with pytest.raises(bpx.TooManyPairsError, match="World.collide: 45 pairs"):
            world.collide()
        with pytest.raises(bpx.TooManyPairsError, match="World.pairs: 45 pairs"):
            world.pairs
        with pytest.raises(bpx.TooManyPairsError, match="World.events: 45 pairs"):
            world.events
        pair_limit(0)
        assert world.pairs.shape == (45, 2)  # the cycle ran; its pairs are there once they fit
        world.set_boxes(stack(3))
        assert world.collide().shape == (3, 2)
        assert world.events.ended.shape == (42, 2)


def test_the_error_comes_before_the_pairs_memory(pair_limit):
    # 2000 boxes on one spot: 1,999,000 pairs, 16 MB as an array. Refused at the limit, the
    # call never holds memory of that size (the bpx world's own blocks are C memory, outside
    # tracemalloc's view; the bytearray NumPy would wrap is not).
    import tracemalloc

    boxes = stack(2000)
    pair_limit(1_998_999)
    tracemalloc.start()
    try:
        with pytest.raises(bpx.TooManyPairsError, match="1999000 pairs"):
            bpx.find_pairs(boxes)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000
    pair_limit(1_999_000)
    assert bpx.find_pairs(boxes).shape == (1_999_000, 2)


def test_c_status_too_many_pairs_maps_to_the_class():
    e = bpx._errors._from_status("BPX_ERR_TOO_MANY_PAIRS", None, None, "x")
    assert type(e) is bpx.TooManyPairsError and "TooManyPairsError" in bpx.__all__
