"""Snapshots and contact margins from Python: a restored world replays the straight run byte
for byte; bad bytes are refused and change nothing; margins hold a pair that parts a little."""
import numpy as np
import pytest

import bpx


def random_boxes(rng, n, side=20.0):
    centres = rng.uniform(0.0, side, size=(n, 3)).astype(np.float32)
    halves = rng.uniform(0.3, 1.5, size=(n, 3)).astype(np.float32)
    return np.concatenate([centres - halves, centres + halves], axis=1)


def step(world, rng, n):
    boxes = random_boxes(rng, n)
    world.set_boxes(boxes)
    world.collide()
    events = world.events
    return world.pairs.tobytes() + events.began.tobytes() + events.ended.tobytes()


def test_restore_replays_the_straight_run():
    rng = np.random.default_rng(3)
    world = bpx.World(track_events=True)
    for _ in range(3):
        step(world, rng, 300)
    world.exclude_pairs([[0, 1], [2, 3]])
    world.set_user_data([5], [2**64 - 1])
    data = world.snapshot()
    state = rng.bit_generator.state
    straight = [step(world, rng, 300) for _ in range(4)]
    for backend in ("auto", "sap", "grid", "brute"):
        other = bpx.World(backend, track_events=True)
        other.restore(data)
        assert other.user_data(5) == 2**64 - 1
        assert other.pair_excluded(1, 0)
        rng.bit_generator.state = state
        assert [step(other, rng, 300) for _ in range(4)] == straight


def test_bad_bytes_are_refused_and_change_nothing():
    world = bpx.World()
    world.set_boxes(random_boxes(np.random.default_rng(1), 50))
    data = world.snapshot()
    target = bpx.World()
    target.set_boxes(random_boxes(np.random.default_rng(2), 7))
    before = target.snapshot()
    with pytest.raises(bpx.InvalidArgumentError, match="byte"):
        target.restore(data[:-1])
    changed = bytearray(data)
    changed[100] ^= 4
    with pytest.raises(bpx.InvalidArgumentError, match="checksum"):
        target.restore(bytes(changed))
    with pytest.raises(bpx.InvalidArgumentError):
        target.restore(b"not a snapshot at all, just some bytes here")
    assert target.snapshot() == before
    target.restore(memoryview(data))  # any bytes-like object
    assert len(target) == 50


def test_margins_hold_a_pair_that_parts_a_little():
    for end_margin, events_wanted in ((0.0, 10), (0.5, 1)):
        world = bpx.World(track_events=True, end_margin=end_margin)
        events = 0
        for cycle in range(10):
            x = 1.1 if cycle % 2 else 1.0
            world.set_boxes(np.array([[0, 0, 0, 1, 1, 1], [x, 0, 0, x + 1, 1, 1]], np.float32))
            world.collide()
            ev = world.events
            events += len(ev.began) + len(ev.ended)
        assert events == events_wanted


@pytest.mark.parametrize(
    "begin, end", [(-1.0, 0.0), (float("nan"), 0.0), (0.5, 0.25), (float("inf"), 0.0)]
)
def test_bad_margins_are_refused(begin, end):
    with pytest.raises(bpx.InvalidArgumentError, match="margin"):
        bpx.World(begin_margin=begin, end_margin=end)


def test_pair_filter_is_asked_once_per_beginning_pair():
    world = bpx.World(track_events=True)
    boxes = np.array([[0, 0, 0, 1, 1, 1], [0.5, 0, 0, 2, 1, 1], [1.5, 0, 0, 3, 1, 1]], np.float32)
    world.set_boxes(boxes)
    world.set_user_data([1], [7])
    asked = []

    def keep_out_seven(i, j, data_i, data_j):
        asked.append((i, j))
        return data_j != 7

    world.set_pair_filter(keep_out_seven)
    for _ in range(3):
        world.collide()
    assert asked == [(0, 1), (1, 2)]  # once each, in (i, j) order
    assert world.pairs.tolist() == [[1, 2]]
    world.set_pair_filter(None)
    assert world.collide().tolist() == [[0, 1], [1, 2]]


def test_pair_filter_errors():
    world = bpx.World()
    world.set_boxes(np.array([[0, 0, 0, 1, 1, 1], [0, 0, 0, 1, 1, 1]], np.float32))
    with pytest.raises(bpx.InvalidArgumentError):
        world.set_pair_filter(42)

    def meddle(i, j, di, dj):
        world.set_boxes(np.zeros((1, 6), np.float32))  # the world is busy: refused
        return True

    world.set_pair_filter(meddle)
    with pytest.raises(bpx.Error):
        world.collide()
    assert len(world) == 2

    def broken(i, j, di, dj):
        raise KeyError("no such body")

    world.set_pair_filter(broken)
    with pytest.raises(KeyError):
        world.collide()
    world.set_pair_filter(lambda i, j, di, dj: True)
    assert world.collide().tolist() == [[0, 1]]
