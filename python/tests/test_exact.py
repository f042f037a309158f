"""find_pairs and World against the NumPy brute force, byte for byte, for every backend."""

import numpy as np
import pytest
from conftest import SLOW_BACKENDS
from scenes import SCENES, brute_pairs, uniform_density

import bpx


def size_for(backend, n):
    return min(n, 300) if backend in SLOW_BACKENDS else n


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_scenes_match_brute_force(backend, scene):
    n = size_for(backend, 1234)  # not a multiple of any SIMD width
    boxes = SCENES[scene](n, seed=20)
    expected = brute_pairs(boxes)
    got = bpx.find_pairs(boxes, backend=backend, threads=1)
    assert got.dtype == np.uint32 and got.shape == expected.shape
    assert got.tobytes() == expected.tobytes(), f"scene {scene}, seed 20, backend {backend}"


@pytest.mark.parametrize("n", [0, 1, 2, 3, 17])
def test_tiny_sets(backend, n):
    boxes = uniform_density(n, seed=n, overlaps_per_box=4.0) if n else np.empty((0, 6), np.float32)
    got = bpx.find_pairs(boxes, backend=backend)
    assert got.shape == (len(brute_pairs(boxes)), 2)
    assert got.tobytes() == brute_pairs(boxes).tobytes()


def test_touching_boxes_collide(backend):
    boxes = np.array(
        [
            [0, 0, 0, 1, 1, 1],
            [1, 0, 0, 2, 1, 1],  # shares a face with 0
            [2, 1, 1, 3, 2, 2],  # shares a corner with 1
            [3.0001, 0, 0, 4, 1, 1],  # a gap from 2
            [-0.0, -1, -1, 0, 0, 0],  # -0.0 equals 0.0: touches 0 at a corner... and 1? no
        ],
        np.float32,
    )
    got = bpx.find_pairs(boxes, backend=backend)
    assert got.tolist() == [[0, 1], [0, 4], [1, 2]]


def test_many_cycles_of_a_world_match_brute_force(backend):
    n = size_for(backend, 800)
    rng = np.random.default_rng(7)
    boxes = uniform_density(n, seed=7, overlaps_per_box=3.0).astype(np.float64)
    with bpx.World(backend=backend, threads=2 if backend not in SLOW_BACKENDS else 1) as world:
        for cycle in range(12):
            boxes += rng.uniform(-0.3, 0.3, (n, 1)) * np.ones((1, 6))  # min and max together
            world.set_boxes(boxes)  # float64: converted once per call
            expected = brute_pairs(boxes.astype(np.float32))
            assert world.collide().tobytes() == expected.tobytes(), f"cycle {cycle}"
            assert world.stats.pair_count == len(expected)


def test_threads_give_the_same_bytes():
    boxes = uniform_density(40000, seed=3, overlaps_per_box=2.0)
    one = bpx.find_pairs(boxes, threads=1)
    for backend in ["auto", "brute", "prune", "sap", "grid"]:
        for threads in [1, 2, 3, 8]:
            if backend == "brute" and threads > 2:
                continue  # O(n^2); two thread counts show it
            got = bpx.find_pairs(boxes, backend=backend, threads=threads)
            assert got.tobytes() == one.tobytes(), (backend, threads)
    assert bpx.find_pairs(boxes).tobytes() == one.tobytes()  # threads=None


def test_layouts_and_dtypes_give_the_same_pairs():
    boxes = uniform_density(2000, seed=11, overlaps_per_box=3.0)
    expected = bpx.find_pairs(boxes).tobytes()
    fortran = np.asfortranarray(boxes)
    strided = np.zeros((2000, 12), np.float32)
    strided[:, ::2] = boxes
    variants = {
        "(n, 2, 3)": boxes.reshape(-1, 2, 3),
        "float64": boxes.astype(np.float64),
        "Fortran order": fortran,
        "strided columns": strided[:, ::2],
        "big-endian": boxes.astype(">f4"),
        "list": boxes.tolist(),
    }
    for name, variant in variants.items():
        assert bpx.find_pairs(variant).tobytes() == expected, name
    assert bpx.find_pairs(mins=boxes[:, :3], maxs=boxes[:, 3:]).tobytes() == expected
    ints = np.round(boxes * 4).astype(np.int32)
    assert bpx.find_pairs(ints).tobytes() == brute_pairs(ints.astype(np.float32)).tobytes()


def test_float64_rounding_never_loses_an_overlap():
    # Boxes that touch in float64 must still overlap after rounding to float32.
    rng = np.random.default_rng(5)
    lo = rng.uniform(-1e3, 1e3, (500, 3))
    size = rng.uniform(0.0, 50.0, (500, 3))
    boxes = np.concatenate([lo, lo + size], axis=1)
    boxes[1::2, :3] = boxes[0::2, 3:]  # box 2k+1 starts exactly where box 2k ends
    boxes[1::2, 3:] = boxes[1::2, :3] + size[1::2]
    lo64, hi64 = boxes[:, :3], boxes[:, 3:]
    hit = np.all((lo64[:, None] <= hi64[None]) & (lo64[None] <= hi64[:, None]), axis=2)
    pairs64 = {(i, j) for i, j in zip(*np.nonzero(hit)) if i < j}
    got = {tuple(p) for p in bpx.find_pairs(boxes).tolist()}
    assert pairs64 <= got
