"""Nothing leaks: bpx's own memory returns to where it was once worlds are closed or dropped,
and Python's stays flat over many calls, failing ones included."""

import gc
import tracemalloc

import numpy as np
import pytest
from scenes import uniform_density

import bpx
from bpx import _bpx


def churn(boxes, bad):
    bpx.find_pairs(boxes)
    bpx.find_pairs(boxes, threads=2)
    with pytest.raises(bpx.NotFiniteError):
        bpx.find_pairs(bad)
    with pytest.raises(bpx.UnknownBackendError):
        bpx.find_pairs(boxes, backend="nope")
    with bpx.World(threads=2, track_events=True) as world:
        world.set_boxes(boxes)
        world.collide()
        world.events
        world.stats
        with pytest.raises(bpx.NotFiniteError):
            world.set_boxes(bad)
        with pytest.raises(bpx.InvalidArgumentError):
            world.remove([len(boxes) + 5])
        ids = world.add(boxes[:10])
        world.move(ids, boxes[:10])
        world.remove(ids)
        world.collide()
    dropped = bpx.World()  # never closed: freed with the object
    dropped.set_boxes(boxes)
    dropped.collide()
    del dropped


def test_nothing_leaks():
    boxes = uniform_density(3000, seed=1, overlaps_per_box=2.0)
    bad = boxes.copy()
    bad[17, 4] = np.nan
    gc.collect()
    base = _bpx._allocated_bytes()
    churn(boxes, bad)  # warm up NumPy's and pytest's caches
    gc.collect()
    assert _bpx._allocated_bytes() == base
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for _ in range(30):
            churn(boxes, bad)
        gc.collect()
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert _bpx._allocated_bytes() == base
    assert grown < 64 * 1024, grown  # one pairs array is ~24 KB: 30 rounds would show
