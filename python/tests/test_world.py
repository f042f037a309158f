"""World: the two phases, objects by id, filters and events over many cycles, against a
Python oracle of the same world."""

import numpy as np
import pytest
from conftest import SLOW_BACKENDS
from scenes import brute_pairs, uniform_density

import bpx


def test_two_phase_mode_matches_brute_force(backend):
    n = 200 if backend in SLOW_BACKENDS else 3000
    rng = np.random.default_rng(1)
    half = rng.uniform(0.25, 0.75, (n, 3)).astype(np.float32)
    side = 2.0 * np.cbrt(n)
    centres = rng.uniform(0, side, (n, 3)).astype(np.float32)
    with bpx.World(backend=backend, track_events=True) as world:
        world.load_extents(-half)
        assert len(world) == n
        previous = set()
        for cycle in range(10):
            centres += rng.uniform(-0.2, 0.2, (n, 3)).astype(np.float32)
            world.update_centres(centres)
            # the updater's arithmetic: centre + minimum and centre - minimum, in float32
            boxes = np.concatenate([centres + (-half), centres - (-half)], axis=1)
            expected = brute_pairs(boxes)
            pairs = world.collide()
            assert pairs.tobytes() == expected.tobytes(), f"cycle {cycle}"
            now = {tuple(p) for p in pairs.tolist()}
            began, ended = world.events
            assert {tuple(p) for p in began.tolist()} == now - previous
            assert {tuple(p) for p in ended.tolist()} == previous - now
            assert world.began.tobytes() == began.tobytes()
            previous = now


class Oracle:
    """The world as Python sees it: boxes by id, filters, the last pairs."""

    def __init__(self):
        self.boxes = {}
        self.filters = {}
        self.previous = set()

    def pairs(self):
        ids = sorted(self.boxes)
        if not ids:
            return set()
        b = np.array([self.boxes[i] for i in ids], np.float32)
        out = set()
        for a, c in brute_pairs(b).tolist():
            i, j = ids[a], ids[c]
            cat_i, mask_i = self.filters.get(i, (1, 0xFFFFFFFF))
            cat_j, mask_j = self.filters.get(j, (1, 0xFFFFFFFF))
            if (cat_i & mask_j) and (cat_j & mask_i):
                out.add((i, j))
        return out


@pytest.mark.parametrize("seed", [1, 2])
def test_objects_filters_and_events_over_many_cycles(backend, seed):
    rng = np.random.default_rng(seed)
    oracle = Oracle()
    pending = set()  # ids removed since the last collide: not handed out again before it
    steps = 40 if backend in SLOW_BACKENDS else 120
    with bpx.World(backend=backend, track_events=True) as world:
        ids = world.add(uniform_density(150, seed, 3.0))
        oracle.boxes.update(zip(ids.tolist(), uniform_density(150, seed, 3.0).tolist()))
        for step in range(steps):
            action = rng.integers(0, 4)
            live = sorted(oracle.boxes)
            if action == 0 or not live:  # add a few
                new = uniform_density(int(rng.integers(1, 10)), seed * 1000 + step, 3.0)
                new += np.tile(rng.uniform(-5, 5, 3), 2).astype(np.float32)  # min and max together
                got = world.add(new)
                assert not set(got.tolist()) & pending, "an id came back before its pairs ended"
                assert not set(got.tolist()) & set(oracle.boxes)
                oracle.boxes.update(zip(got.tolist(), new.tolist()))
            elif action == 1:  # remove a few
                gone = rng.choice(live, size=min(len(live), int(rng.integers(1, 6))), replace=False)
                world.remove(gone)
                for i in gone.tolist():
                    del oracle.boxes[i]
                    oracle.filters.pop(i, None)
                    pending.add(i)
            elif action == 2:  # move a few
                moved = rng.choice(live, size=min(len(live), int(rng.integers(1, 20))), replace=False)
                new = np.array([oracle.boxes[i] for i in moved.tolist()], np.float32)
                new += rng.uniform(-1, 1, (len(moved), 1)).astype(np.float32)
                world.move(moved, new)
                oracle.boxes.update(zip(moved.tolist(), new.tolist()))
            else:  # filters
                chosen = rng.choice(live, size=min(len(live), int(rng.integers(1, 8))), replace=False)
                cats = rng.integers(1, 4, len(chosen)).astype(np.uint32)
                masks = rng.choice([0xFFFFFFFF, 1, 2, 3, 0], len(chosen)).astype(np.uint32)
                world.set_filters(chosen, cats, masks)
                oracle.filters.update(zip(chosen.tolist(), zip(cats.tolist(), masks.tolist())))
            if rng.integers(0, 3) == 0 and step != steps - 1:
                continue  # several changes between collides
            pairs = world.collide()
            now = oracle.pairs()
            assert {tuple(p) for p in pairs.tolist()} == now, f"step {step}, seed {seed}"
            assert pairs.tolist() == sorted(pairs.tolist())
            began, ended = world.events
            assert {tuple(p) for p in began.tolist()} == now - oracle.previous, f"step {step}"
            assert {tuple(p) for p in ended.tolist()} == oracle.previous - now, f"step {step}"
            oracle.previous = now
            pending.clear()


def test_set_filters_forms():
    boxes = np.zeros((4, 6), np.float32)
    boxes[:, 3:] = 1  # all four overlap
    with bpx.World() as world:
        world.set_boxes(boxes)
        assert len(world.collide()) == 6
        world.set_filters(None, [1, 2, 1, 2], [2, 1, 2, 1])  # only 1-2 pairs
        assert world.collide().tolist() == [[0, 1], [0, 3], [1, 2], [2, 3]]
        world.set_filters([0, 1], 1, 0xFFFFFFFF)  # scalars for every id
        assert world.collide().tolist() == [[0, 1], [0, 3], [1, 3], [2, 3]]


def test_stats_backend_and_repr():
    boxes = uniform_density(5000, seed=2)
    with bpx.World(backend="auto", threads=2) as world:
        world.set_boxes(boxes)
        pairs = world.collide()
        s = world.stats
        assert isinstance(s, bpx.Stats)
        assert s.box_count == 5000 and s.pair_count == len(pairs) and s.cycle_count == 1
        assert s.backend in ("prune", "grid", "sap") and world.backend == s.backend
        assert s.compare_ns > 0 and s.pair_tests >= len(pairs)
        assert "threads=2" in repr(world) and world.threads == 2
        assert world.pairs.tobytes() == pairs.tobytes()
    assert world.closed and repr(world) == "<bpx.World closed>"
    world.close()  # twice is fine


def test_profile_stages():
    boxes = uniform_density(20000, seed=3)
    for backend in ("grid", "sap", "prune"):
        with bpx.World(backend=backend, profile=True) as world, bpx.World(backend=backend) as plain:
            world.set_boxes(boxes)
            plain.set_boxes(boxes)
            assert world.collide().tobytes() == plain.collide().tobytes()  # the same pairs
            stages = world.stats.stages
            assert plain.stats.stages == ()
            assert stages and all(isinstance(t, bpx.Stage) for t in stages)
            assert stages[0].name == "update" and stages[0].backend == "world"
            # the backend's own stages after the updater's (sap's first cycle runs grid's
            # inside); the pairs are merged straight into the array handed back, untimed
            assert stages[1].backend == backend and len(stages) >= 3, stages
            assert {t.backend for t in stages[1:]} <= {backend, "grid"}, stages
            for t in stages:
                assert t.access in ("sequential", "gather", "scatter")
                assert t.bytes_read + t.bytes_written > 0 and t.ns >= 0
                assert (t.random > 0) == (t.access != "sequential") or t.random == 0
            # the updater reads and writes the six coordinates of every box
            assert stages[0].bytes_read == 24 * len(boxes) == stages[0].bytes_written


def test_results_are_owned_by_the_caller():
    boxes = uniform_density(1000, seed=4, overlaps_per_box=3)
    with bpx.World() as world:
        world.set_boxes(boxes)
        first = world.collide()
        kept = first.copy()
        world.set_boxes(boxes + 100)  # a later cycle does not touch the arrays handed out
        world.collide()
        assert first.tobytes() == kept.tobytes()
        first[:] = 0  # and writing to them does not touch the world
        assert world.pairs.tobytes() != first.tobytes() or len(first) == 0
