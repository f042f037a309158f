"""A C-contiguous float32 array reaches bpx where it lies: checked by address and by memory."""

import tracemalloc

import numpy as np
from scenes import uniform_density

import bpx
from bpx import _bpx

N = 1_000_000


def address(array):
    return array.__array_interface__["data"][0]


def test_a_million_boxes_are_not_copied():
    boxes = uniform_density(N, seed=1)
    assert boxes.flags.c_contiguous and boxes.dtype == np.float32
    tracemalloc.start()  # NumPy reports its data buffers to tracemalloc
    try:
        before, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        pairs = bpx.find_pairs(boxes)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # bpx read the array's own memory...
    assert _bpx._last_input_address() == address(boxes)
    # ...and Python allocated no copy of its 24 MB: only the pairs (8 bytes each) and change.
    assert peak - before < pairs.nbytes + 1_000_000, (peak - before, pairs.nbytes)
    assert boxes.nbytes == 24 * N


def test_the_other_float32_layouts_are_not_copied():
    boxes = uniform_density(1000, seed=2)
    bpx.find_pairs(boxes.reshape(-1, 2, 3))
    assert _bpx._last_input_address() == address(boxes)
    with bpx.World() as world:
        world.set_boxes(boxes)
        assert _bpx._last_input_address() == address(boxes)
        minima = -np.full((1000, 3), 0.5, np.float32)
        world.load_extents(minima)
        assert _bpx._last_input_address() == address(minima)
        centres = np.ascontiguousarray(boxes[:, :3])
        world.update_centres(centres)
        assert _bpx._last_input_address() == address(centres)


def test_other_dtypes_and_layouts_are_converted_once():
    boxes = uniform_density(1000, seed=3).astype(np.float64)
    bpx.find_pairs(boxes)
    assert _bpx._last_input_address() != address(boxes)
    strided = uniform_density(1000, seed=3)[::2]
    bpx.find_pairs(strided)
    assert _bpx._last_input_address() != address(strided)


def test_pairs_wrap_the_buffer_bpx_filled():
    pairs = bpx.find_pairs(uniform_density(5000, seed=4, overlaps_per_box=2.0))
    assert pairs.flags.c_contiguous and pairs.flags.writeable and pairs.dtype == np.uint32
    base = pairs
    while isinstance(base, np.ndarray):
        base = base.base
    if isinstance(base, memoryview):
        base = base.obj
    assert isinstance(base, bytearray)  # the one bpx's emitter wrote into, not a copy of it
