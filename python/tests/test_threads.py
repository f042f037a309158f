"""The GIL is released while bpx works; Python threads share find_pairs and a World safely."""

import threading
import time

import numpy as np
from scenes import brute_pairs, uniform_density

import bpx
from bpx import _bpx


def test_gil_is_released_during_the_c_call():
    boxes = uniform_density(400_000, seed=1)
    start = time.perf_counter()
    bpx.find_pairs(boxes, threads=1)
    call = time.perf_counter() - start
    done = threading.Event()
    started = threading.Event()

    def work():
        started.set()
        _bpx.find_pairs(boxes, "auto", 1)  # nothing but the C call in this thread
        done.set()

    thread = threading.Thread(target=work)
    thread.start()
    started.wait()
    gaps, last = [], time.perf_counter()
    while not done.is_set():
        now = time.perf_counter()
        gaps.append(now - last)
        last = now
    thread.join()
    # Holding the GIL through the call would stop this loop for the whole call.
    assert len(gaps) > 100
    assert max(gaps) < 0.5 * call, (max(gaps), call)


def test_python_threads_calling_find_pairs_at_once():
    sets = [uniform_density(3000, seed=s, overlaps_per_box=2.0) for s in range(8)]
    expected = [brute_pairs(b).tobytes() for b in sets]
    results = [None] * len(sets)

    def work(k):
        for _ in range(3):
            results[k] = bpx.find_pairs(sets[k], threads=2).tobytes()

    threads = [threading.Thread(target=work, args=(k,)) for k in range(len(sets))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert results == expected


def test_one_world_shared_by_python_threads():
    # Each thread sets its own boxes and collides under a lock of its own; the world's lock
    # makes every single call safe, whichever thread makes it.
    boxes = [uniform_density(2000, seed=s, overlaps_per_box=2.0) for s in range(4)]
    expected = [brute_pairs(b).tobytes() for b in boxes]
    errors = []
    pair_lock = threading.Lock()
    with bpx.World(threads=2) as world:

        def work(k):
            try:
                for _ in range(20):
                    with pair_lock:
                        world.set_boxes(boxes[k])
                        got = world.collide().tobytes()
                    assert got == expected[k]
                    world.stats  # unlocked calls race with other threads' cycles, safely
                    len(world)
            except Exception as exc:  # pragma: no cover - reported below
                errors.append(exc)

        threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert not errors


def test_close_while_another_thread_collides():
    boxes = uniform_density(200_000, seed=2)
    world = bpx.World()
    world.set_boxes(boxes)
    outcome = []

    def work():
        try:
            for _ in range(5):
                outcome.append(len(world.collide()))
        except bpx.StateError:
            outcome.append("closed")

    t = threading.Thread(target=work)
    t.start()
    time.sleep(0.01)
    world.close()  # waits for the running collide, then the next one finds the world closed
    t.join()
    assert outcome and (outcome[-1] == "closed" or len(outcome) == 5)
    assert world.closed


def test_world_threads_give_the_same_bytes():
    boxes = uniform_density(50_000, seed=5, overlaps_per_box=2.0)
    results = set()
    for threads in [0, 1, 2, 4]:
        with bpx.World(threads=threads) as world:
            world.set_boxes(boxes)
            results.add(world.collide().tobytes())
    assert len(results) == 1
    assert np.frombuffer(results.pop(), np.uint32).size > 0
