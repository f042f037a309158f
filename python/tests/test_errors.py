"""Bad input raises a bpx.Error subclass naming what and where, and changes nothing."""

import numpy as np
import pytest
from scenes import uniform_density

import bpx


def bad(n, k, axis, kind):
    boxes = uniform_density(n, seed=9, overlaps_per_box=3.0)
    if kind == "nan":
        boxes[k, axis] = np.nan
    elif kind == "inf":
        boxes[k, 3 + axis] = np.inf
    elif kind == "-inf":
        boxes[k, axis] = -np.inf
    else:  # min > max
        boxes[k, axis] = boxes[k, 3 + axis] + 1
    return boxes


CASES = [
    ("nan", bpx.NotFiniteError),
    ("inf", bpx.NotFiniteError),
    ("-inf", bpx.NotFiniteError),
    ("min>max", bpx.MinGreaterThanMaxError),
]


@pytest.mark.parametrize("kind,cls", CASES)
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_bad_boxes_name_the_box_and_axis(backend, kind, cls, axis):
    boxes = bad(300, 123, axis, kind)
    with pytest.raises(cls) as info:
        bpx.find_pairs(boxes, backend=backend)
    e = info.value
    assert isinstance(e, bpx.InvalidBoxError) and isinstance(e, ValueError)
    assert e.index == 123 and e.axis == axis
    assert e.status == ("BPX_ERR_NOT_FINITE" if cls is bpx.NotFiniteError
                        else "BPX_ERR_MIN_GREATER_THAN_MAX")
    assert "box 123" in str(e) and f" {'xyz'[axis]} " in str(e) + " "
    assert str(e).startswith("find_pairs: ")


def snapshot(world):
    return len(world), world.pairs.tobytes(), world.stats.cycle_count


@pytest.mark.parametrize("kind,cls", CASES)
def test_world_calls_refuse_bad_boxes_and_change_nothing(kind, cls):
    good = uniform_density(300, seed=9, overlaps_per_box=3.0)
    with bpx.World(track_events=True) as world:
        world.set_boxes(good)
        world.collide()
        before = snapshot(world)
        events = [e.tobytes() for e in world.events]
        for call in (
            lambda: world.set_boxes(bad(300, 77, 1, kind)),
            lambda: world.add(bad(5, 3, 2, kind)),
            lambda: world.move([1, 2, 3, 4], bad(4, 2, 0, kind)),
        ):
            with pytest.raises(cls) as info:
                call()
            assert info.value.index is not None and info.value.axis is not None
            assert snapshot(world) == before
            assert [e.tobytes() for e in world.events] == events
        # the world still works, and its next collide is as if nothing happened
        assert world.collide().tobytes() == before[1]
        assert len(world.events.began) == 0 and len(world.events.ended) == 0


def test_two_phase_errors():
    with bpx.World() as world:
        with pytest.raises(bpx.StateError, match="update_centres"):
            world.update_centres(np.zeros((3, 3), np.float32))
        minima = -np.ones((10, 3), np.float32)
        minima[4, 2] = 0.5  # a minimum > 0: min > max
        with pytest.raises(bpx.MinGreaterThanMaxError) as info:
            world.load_extents(minima)
        assert info.value.index == 4 and info.value.axis == 2 and "object 4" in str(info.value)
        assert len(world) == 0
        minima[4, 2] = -0.5
        world.load_extents(minima)
        centres = np.zeros((10, 3), np.float32)
        world.update_centres(centres)
        pairs = world.collide().tobytes()
        centres[6, 1] = np.nan
        with pytest.raises(bpx.NotFiniteError) as info:
            world.update_centres(centres)
        assert (info.value.index, info.value.axis) == (6, 1) and "centre y" in str(info.value)
        with pytest.raises(bpx.InvalidArgumentError, match="9 centres for 10 objects"):
            world.update_centres(np.zeros((9, 3), np.float32))
        big = np.zeros((10, 3), np.float64)
        big[2, 0] = 1e39  # finite in float64, infinite in float32
        with pytest.raises(bpx.NotFiniteError, match="after conversion to float32"):
            world.update_centres(big)
        assert world.collide().tobytes() == pairs  # the last good centres


@pytest.mark.parametrize(
    "value,cls,match",
    [
        (np.zeros((5, 4), np.float32), bpx.InvalidArgumentError, r"shape \(n, 6\)"),
        (np.zeros((5, 3, 2), np.float32), bpx.InvalidArgumentError, r"got \(5, 3, 2\)"),
        (np.zeros(6, np.float32), bpx.InvalidArgumentError, r"got \(6,\)"),
        (np.zeros((5, 6), np.complex64), bpx.DTypeError, "complex64"),
        (np.zeros((5, 6), bool), bpx.DTypeError, "bool"),
        (np.zeros((5, 6), object), bpx.DTypeError, "object"),
        (np.array([["a"] * 6]), bpx.DTypeError, "<U1"),
        ([[0, 0, 0, 1, 1], [0, 0, 0, 1, 1, 1]], bpx.InvalidArgumentError, "not an array"),
    ],
)
def test_wrong_shapes_and_dtypes(value, cls, match):
    with pytest.raises(cls, match=match):
        bpx.find_pairs(value)
    with bpx.World() as world:
        with pytest.raises(cls, match=match):
            world.set_boxes(value)


def test_dtype_errors_are_type_errors_too():
    with pytest.raises(TypeError):
        bpx.find_pairs(np.zeros((2, 6), np.complex128))


def test_ids_are_checked():
    with bpx.World() as world:
        ids = world.add(uniform_density(10, seed=1))
        assert ids.tolist() == list(range(10)) and ids.dtype == np.uint32
        world.collide()
        before = snapshot(world)
        for call, match in [
            (lambda: world.remove([3, -1]), r"ids\[1\] is -1: negative"),
            (lambda: world.remove(np.array([2**32], np.int64)), "above 2"),
            (lambda: world.remove([1.0]), "not an integer dtype"),
            (lambda: world.remove([4, 4]), "World.remove: "),
            (lambda: world.remove([10]), "World.remove: "),
            (lambda: world.move([-2], np.zeros((1, 6), np.float32)), "negative"),
            (lambda: world.move([1, 2], np.zeros((1, 6), np.float32)), "2 ids for 1 boxes"),
            (lambda: world.set_filters([11], [1], [1]), "World.set_filters: "),
            (lambda: world.set_filters([1], [-1], [1]), "categories"),
            (lambda: world.set_filters([1, 2], [1, 2, 3], [1, 1]), "3 ids, 3 categories|differ"),
        ]:
            with pytest.raises((bpx.InvalidArgumentError, bpx.DTypeError), match=match):
                call()
            assert snapshot(world) == before
        with pytest.raises(bpx.InvalidArgumentError) as info:
            world.remove([0, 1, 99])
        assert info.value.index == 2  # its position in ids
        assert len(world) == 10 and len(world.collide()) == len(np.frombuffer(before[1], np.uint32)) // 2


def test_other_errors():
    with pytest.raises(bpx.UnknownBackendError, match="no backend named 'fast'"):
        bpx.find_pairs(np.zeros((1, 6), np.float32), backend="fast")
    with pytest.raises(bpx.UnknownBackendError):
        bpx.World(backend="fast")
    with pytest.raises(bpx.InvalidArgumentError, match="threads is 300"):
        bpx.World(threads=300)
    with pytest.raises(bpx.InvalidArgumentError, match="threads is -1"):
        bpx.find_pairs(np.zeros((1, 6), np.float32), threads=-1)
    with pytest.raises(bpx.InvalidArgumentError, match="no SIMD width"):
        bpx.World(simd="sse9")
    unavailable = [b for b in bpx.backends() if not b.available]
    for b in unavailable:
        with pytest.raises(bpx.BackendUnavailableError, match=b.name):
            bpx.World(backend=b.name)
    with bpx.World() as world:
        with pytest.raises(bpx.StateError, match="track_events"):
            world.events
    with pytest.raises(bpx.StateError, match="closed"):
        world.collide()
    with pytest.raises(bpx.StateError, match="closed"):
        len(world)


def test_error_hierarchy():
    assert issubclass(bpx.OutOfMemoryError, MemoryError)
    assert issubclass(bpx.DeviceMemoryError, MemoryError)
    assert issubclass(bpx.DeviceMemoryError, bpx.DeviceError)
    assert issubclass(bpx.NotFiniteError, ValueError)
    assert issubclass(bpx.StateError, RuntimeError)
    for name in bpx.__all__:
        obj = getattr(bpx, name)
        if isinstance(obj, type) and issubclass(obj, Exception):
            assert issubclass(obj, bpx.Error)
