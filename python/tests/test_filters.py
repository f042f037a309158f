"""Groups, excluded pairs, user data and any-hit queries, against NumPy oracles: the pairs of
random boxes under random groups, exclusions and filters, every cycle and for any thread count;
exclusions and user data that go with a removed box; any-hit answers within the full answers;
bad input refused with the world unchanged."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from conftest import SLOW_BACKENDS
from scenes import SCENES, brute_pairs, uniform_density
from test_query import Scene, make_queries, oracle_box, oracle_cast, oracle_sphere

import bpx
from bpx import _bpx

ALL = 0xFFFFFFFF


# -- the pair oracle ------------------------------------------------------------------------------


def oracle_pairs(boxes, categories, masks, groups, excluded):
    """(k, 2) uint32 pairs of boxes 0 .. n-1: excluded pairs never; then a shared non-zero group
    (positive: always, negative: never); then categories and masks."""
    out = []
    for i, j in brute_pairs(boxes).tolist():
        if (i, j) in excluded:
            continue
        if groups[i] == groups[j] != 0:
            if groups[i] > 0:
                out.append((i, j))
            continue
        if (categories[i] & masks[j]) and (categories[j] & masks[i]):
            out.append((i, j))
    return np.array(out, np.uint32).reshape(-1, 2)


@pytest.mark.parametrize("seed", [1, 2])
def test_groups_exclusions_and_filters_match_the_oracle_every_cycle(backend, seed):
    n = 120 if backend in SLOW_BACKENDS else 600
    cycles = 6 if backend in SLOW_BACKENDS else 15
    rng = np.random.default_rng(seed)
    boxes = uniform_density(n, seed, overlaps_per_box=4.0)
    categories = np.ones(n, np.uint32)
    masks = np.full(n, ALL, np.uint32)
    groups = np.zeros(n, np.int32)
    excluded = set()
    worlds = [bpx.World(backend=backend, threads=t) for t in (1, 3)]
    try:
        for cycle in range(cycles):
            boxes = boxes + np.tile(rng.uniform(-0.3, 0.3, (n, 3)), 2).astype(np.float32)
            some = rng.choice(n, n // 10, replace=False)
            categories[some] = rng.choice([1, 2, 4, 3], len(some))
            masks[some] = rng.choice([ALL, 1, 2, 6, 0], len(some))
            grouped = rng.choice(n, n // 5, replace=False)
            groups[grouped] = rng.integers(-3, 4, len(grouped))
            # exclude some overlapping pairs (so that exclusions matter) and some random ones
            overlapping = brute_pairs(boxes)
            new = overlapping[rng.choice(len(overlapping), len(overlapping) // 8, replace=False)]
            random = rng.integers(0, n, (20, 2))
            new = np.concatenate([new, random[random[:, 0] != random[:, 1]]])
            new[::2] = new[::2, ::-1]  # (j, i) is the same pair as (i, j)
            excluded |= {(min(p), max(p)) for p in new.tolist()}
            ended = [p for p in sorted(excluded) if rng.uniform() < 0.1]
            excluded -= set(ended)
            for world in worlds:
                world.set_boxes(boxes)
                world.set_filters(some, categories[some], masks[some])
                world.set_groups(grouped, groups[grouped])
                world.exclude_pairs(new)
                world.include_pairs(np.array(ended, np.int64).reshape(-1, 2))
            want = oracle_pairs(boxes, categories, masks, groups, excluded)
            got = [world.collide() for world in worlds]
            assert got[0].tobytes() == want.tobytes(), f"cycle {cycle}"
            assert got[1].tobytes() == want.tobytes(), f"cycle {cycle}, 3 threads"
        for i, j in rng.integers(0, n, (50, 2)).tolist():
            assert worlds[0].pair_excluded(i, j) == ((min(i, j), max(i, j)) in excluded)
    finally:
        for world in worlds:
            world.close()


def test_group_rule():
    boxes = np.array([[0, 0, 0, 1, 1, 1]] * 4, np.float32)  # every box overlaps every other
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.set_filters(None, [1, 2, 4, 8], 0)  # no box pairs by the category rule
        assert world.collide().tolist() == []
        world.set_groups([0, 1], 5)  # a scalar applies to every id
        assert world.collide().tolist() == [[0, 1]]
        world.set_filters(None, [1] * 4, ALL)
        world.set_groups(None, [-2, -2, 0, -2])
        assert world.collide().tolist() == [[0, 2], [1, 2], [2, 3]]
        world.exclude_pairs([[2, 0]])  # before a positive group, too
        world.set_groups(None, [7, 0, 7, 0])
        assert world.collide().tolist() == [[0, 1], [0, 3], [1, 2], [1, 3], [2, 3]]
        world.set_groups(None, np.array([-(2**31), 2**31 - 1, 0, 0]))  # int32's range
        world.include_pairs([[0, 2], [0, 2], [1, 3]])  # twice, and one never excluded
        assert len(world.collide()) == 6


def test_exclusions_and_user_data_go_with_a_removed_box():
    with bpx.World(track_events=True) as world:
        ids = world.add([[0, 0, 0, 1, 1, 1], [0.5, 0, 0, 1.5, 1, 1], [0.8, 0, 0, 2, 1, 1]])
        assert ids.tolist() == [0, 1, 2]
        world.exclude_pairs([[0, 1], [2, 1]])
        world.set_user_data([1], 7)
        world.set_groups([1], 3)
        assert world.collide().tolist() == [[0, 2]]
        assert world.pair_excluded(1, 0) and world.pair_excluded(1, 2)
        assert not world.pair_excluded(0, 2) and not world.pair_excluded(1, 1)
        world.remove([1])
        world.collide()
        assert not world.pair_excluded(0, 1) and not world.pair_excluded(1, 2)
        assert world.user_data(1) == 0  # an id not in use
        again = world.add([[0.5, 0, 0, 1.5, 1, 1]])
        assert again.tolist() == [1]  # the id comes back: a new box, with nothing of the old
        assert world.user_data(1) == 0
        assert world.collide().tolist() == [[0, 1], [0, 2], [1, 2]]


def test_user_data_round_trip():
    values = [0, 1, 2**32, 2**63, 2**64 - 1, 12345678901234567890]
    with bpx.World() as world:
        world.set_boxes(uniform_density(10))
        world.set_user_data(None, values)  # Python ints beyond int64 beside small ones
        got = world.user_data(np.arange(6))
        assert got.dtype == np.uint64 and got.tolist() == values
        assert world.user_data(4) == 2**64 - 1 and type(world.user_data(4)) is int
        world.set_user_data([7, 8], 2**64 - 1)  # a scalar applies to every id
        world.set_user_data(np.array([9]), np.array([5], np.uint64))
        assert world.user_data([6, 7, 8, 9]).tolist() == [0, 2**64 - 1, 2**64 - 1, 5]
        assert world.user_data([10, 2**32 - 1]).tolist() == [0, 0]  # not in use
        assert world.user_data([]).shape == (0,)
        world.set_boxes(uniform_density(10, seed=2))  # the same ids: the data stays
        assert world.user_data(4) == 2**64 - 1


# -- any-hit queries ------------------------------------------------------------------------------


def check_any(world, scene, q):
    """Each kind's any-hit answer is one of the full answer's hits, empty exactly when it is;
    the batches equal the single queries. Returns the number of hits found."""
    k = len(q["origins"])
    found = 0
    singles = {kind: [] for kind in ("box", "sphere", "ray", "sweep")}
    for j in range(k):
        for kind, got, want in (
            ("box", world.query_box(q["boxes"][j], any=True), oracle_box(scene, q["boxes"][j])),
            ("sphere", world.query_sphere(q["centres"][j], q["radii"][j], any=True),
             oracle_sphere(scene, q["centres"][j], q["radii"][j])),
        ):
            assert got.dtype == np.uint32 and len(got) == min(1, len(want))
            assert set(got.tolist()) <= set(want.tolist())
            singles[kind].append(got.tolist())
            found += len(got)
        o, d, m, b = q["origins"][j], q["directions"][j], q["max_fractions"][j], q["boxes"][j]
        for kind, got, (ids, fractions) in (
            ("ray", world.ray_cast(o, d, m, any=True), oracle_cast(scene, o, o, d, m, False)),
            ("sweep", world.sweep(b, d, m, any=True),
             oracle_cast(scene, b[:3], b[3:], d, m, False)),
        ):
            assert (got is None) == (len(ids) == 0)
            if got is not None:
                assert isinstance(got, bpx.Hit)
                assert (got.id, got.fraction) in set(zip(ids.tolist(), fractions.tolist()))
            singles[kind].append([] if got is None else [got.id])
            found += got is not None
    for kind, batch in (
        ("box", world.query_box_batch(q["boxes"], any=True)),
        ("sphere", world.query_sphere_batch(q["centres"], q["radii"], any=True)),
        ("ray", world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"], any=True)),
        ("sweep", world.sweep_batch(q["boxes"], q["directions"], q["max_fractions"], any=True)),
    ):
        assert batch.counts.tolist() == [len(s) for s in singles[kind]]
        assert batch.ids.tolist() == sum(singles[kind], [])
    return found


@pytest.mark.parametrize("kind", ["uniform", "touching", "identical", "dense", "points_planes"])
def test_any_hit_is_one_of_all_hits(kind):
    boxes = SCENES[kind](300, seed=5)
    q = make_queries(boxes, 40, seed=12)
    with bpx.World() as world:
        world.set_boxes(boxes)
        assert check_any(world, Scene(boxes), q) > 20


def test_any_hit_honours_filters_and_is_the_same_for_any_thread_count():
    boxes = uniform_density(2000, seed=6, overlaps_per_box=3.0)
    q = make_queries(boxes, 300, seed=13)
    answers = []
    for threads in (1, 4):
        with bpx.World(threads=threads) as world:
            world.set_boxes(boxes)
            world.set_filters(np.arange(0, 2000, 3), 2, ALL)  # every third box in category 2
            batch = world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"],
                                         any=True, mask=2)
            assert np.all(batch.ids % 3 == 0)
            full = world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"],
                                        all=True, mask=2)
            assert np.array_equal(batch.counts, np.minimum(full.counts, 1))
            sweeps = world.sweep_batch(q["boxes"], q["directions"], q["max_fractions"], any=True)
            regions = world.query_box_batch(q["boxes"], any=True, mask=2)
            answers.append([a.tobytes() for r in (batch, sweeps, regions) for a in r])
    assert answers[0] == answers[1]


# -- bad input ------------------------------------------------------------------------------------


def snapshot(world):
    """What a refused call must not change: pairs, exclusions, user data."""
    n = len(world)
    return (
        world.collide().tobytes(),
        [world.pair_excluded(i, j) for i in range(4) for j in range(4)],
        world.user_data(np.arange(n)).tobytes(),
    )


@pytest.fixture
def small_world():
    """Boxes 0 .. 9 with 5 removed, overlapping in a row; (0, 1) excluded, user data set."""
    with bpx.World() as world:
        world.add([[k, 0, 0, k + 1.5, 1, 1] for k in range(10)])
        world.remove([5])
        world.collide()
        world.exclude_pairs([[0, 1]])
        world.set_user_data(None, np.arange(5, dtype=np.uint64) + 100)
        yield world


BAD = [
    (lambda w: w.exclude_pairs([[3, 3]]), bpx.InvalidArgumentError, 0, "with itself"),
    (lambda w: w.exclude_pairs([[2, 3], [4, 4]]), bpx.InvalidArgumentError, 1, "with itself"),
    (lambda w: w.exclude_pairs([[2, 3], [0, 99]]), bpx.InvalidArgumentError, 1,
     "99 is not a box in use"),
    (lambda w: w.exclude_pairs([[4, 5]]), bpx.InvalidArgumentError, 0, "5 is not a box in use"),
    (lambda w: w.exclude_pairs([[2, 3], [0, -1]]), bpx.InvalidArgumentError, 1, "-1 is negative"),
    (lambda w: w.exclude_pairs([[2, 2**32]]), bpx.InvalidArgumentError, 0, "above 2**32 - 1"),
    (lambda w: w.exclude_pairs([[2, 3.0]]), bpx.DTypeError, None, "not an integer dtype"),
    (lambda w: w.exclude_pairs([2, 3]), bpx.InvalidArgumentError, None,
     r"expected shape (k, 2), got (2,)"),
    (lambda w: w.exclude_pairs(np.zeros((2, 3), int)), bpx.InvalidArgumentError, None,
     "expected shape (k, 2)"),
    (lambda w: w.include_pairs([[0, 1], [1, 1]]), bpx.InvalidArgumentError, 1, "with itself"),
    (lambda w: w.include_pairs([[0, 1], [1, 5]]), bpx.InvalidArgumentError, 1, "not a box in use"),
    (lambda w: w.set_groups([0, 99], [1, 2]), bpx.InvalidArgumentError, 1, "not a box in use"),
    (lambda w: w.set_groups([0, 5], [1, 2]), bpx.InvalidArgumentError, 1, "not a box in use"),
    (lambda w: w.set_groups([0, 1], [1]), bpx.InvalidArgumentError, None, "2 ids for 1 values"),
    (lambda w: w.set_groups(None, -1), bpx.InvalidArgumentError, None, "groups must be an array"),
    (lambda w: w.set_groups([0], [2**31]), bpx.InvalidArgumentError, 0, "above 2**31 - 1"),
    (lambda w: w.set_groups([0], [-(2**31) - 1]), bpx.InvalidArgumentError, 0, "below -2**31"),
    (lambda w: w.set_groups([0], [1.5]), bpx.DTypeError, None, "not an integer dtype"),
    (lambda w: w.set_groups([-1], [1]), bpx.InvalidArgumentError, 0, "negative"),
    (lambda w: w.set_groups([[0]], [1]), bpx.InvalidArgumentError, None, "1-D"),
    (lambda w: w.set_user_data([0], [-1]), bpx.InvalidArgumentError, 0, "negative"),
    (lambda w: w.set_user_data([0, 1], [1, 2**64]), bpx.InvalidArgumentError, 1,
     "above 2**64 - 1"),
    (lambda w: w.set_user_data([0, 1], 2**64), bpx.InvalidArgumentError, None,
     "values is 18446744073709551616: above 2**64 - 1"),
    (lambda w: w.exclude_pairs([[0, 1], [2, 2**64]]), bpx.InvalidArgumentError, 1,
     "pairs[1] is 18446744073709551616"),
    (lambda w: w.set_user_data([0, 1], [1.0, 2.0]), bpx.DTypeError, None, "not an integer"),
    (lambda w: w.set_user_data([0, 5], [1, 2]), bpx.InvalidArgumentError, 1, "not a box in use"),
    (lambda w: w.set_user_data(None, [1] * 11), bpx.InvalidArgumentError, 5, "not a box in use"),
    (lambda w: w.set_user_data([0, 1, 2], [1, 2]), bpx.InvalidArgumentError, None,
     "3 ids for 2 values"),
    (lambda w: w.user_data(-1), bpx.InvalidArgumentError, 0, "negative"),
    (lambda w: w.user_data(1.0), bpx.DTypeError, None, "not an integer"),
    (lambda w: w.pair_excluded(0, -1), bpx.InvalidArgumentError, None, "j is -1"),
    (lambda w: w.pair_excluded(0, [1, 2]), bpx.InvalidArgumentError, None, "expected one id"),
    (lambda w: w.pair_excluded(0.0, 1), bpx.DTypeError, None, "not an integer"),
    (lambda w: w.ray_cast([0, 0, 0], [1, 0, 0], all=True, any=True), bpx.InvalidArgumentError,
     None, "World.ray_cast: all and any exclude each other"),
    (lambda w: w.sweep_batch(np.zeros((2, 6)), np.ones((2, 3)), all=True, any=True),
     bpx.InvalidArgumentError, None, "World.sweep_batch: all and any"),
]


@pytest.mark.parametrize("case", range(len(BAD)))
def test_bad_input_is_refused_and_changes_nothing(small_world, case):
    call, cls, index, text = BAD[case]
    before = snapshot(small_world)
    with pytest.raises(cls) as info:
        call(small_world)
    assert type(info.value) is cls and isinstance(info.value, ValueError)
    assert info.value.index == index
    assert text in str(info.value), str(info.value)
    assert snapshot(small_world) == before


def test_empty_calls_change_nothing(small_world):
    before = snapshot(small_world)
    small_world.exclude_pairs([])
    small_world.include_pairs(np.empty((0, 2), np.uint32))
    small_world.set_groups([], [])
    small_world.set_user_data([], [])
    assert snapshot(small_world) == before


def test_the_c_layer_checks_its_buffers():
    with bpx.World() as world:
        world.set_boxes(uniform_density(4))
        c = world._c
        with pytest.raises(bpx.InvalidArgumentError, match="int32"):
            c.set_groups(None, np.zeros(4, np.uint32))
        with pytest.raises(bpx.InvalidArgumentError, match="uint64"):
            c.set_user_data(None, np.zeros(4, np.int64))
        with pytest.raises(bpx.InvalidArgumentError, match="2 items per row"):
            c.exclude_pairs(np.zeros(3, np.uint32))
        with pytest.raises(bpx.InvalidArgumentError, match="uint32"):
            c.user_data(np.zeros(3, np.int32))
        with pytest.raises(bpx.InvalidArgumentError):  # bpx refuses closest with any
            c.query(_bpx.QUERY_RAY, True, True, np.ones((1, 7), np.float32),
                    np.ones(1, np.uint32), np.ones(1, np.uint32), False)
        c.set_user_data(None, np.full(4, 2**64 - 1, np.uint64))  # 'L' or 'Q': either is uint64
        assert np.frombuffer(c.user_data(np.arange(4, dtype=np.uint32)), np.uint64)[3] == 2**64 - 1


def test_closed_world():
    world = bpx.World()
    world.set_boxes(uniform_density(4))
    world.close()
    for call in (
        lambda: world.set_groups(None, [1, 1, 1, 1]),
        lambda: world.exclude_pairs([[0, 1]]),
        lambda: world.include_pairs([[0, 1]]),
        lambda: world.pair_excluded(0, 1),
        lambda: world.set_user_data([0], 1),
        lambda: world.user_data(0),
        lambda: world.query_box([0, 0, 0, 1, 1, 1], any=True),
    ):
        with pytest.raises(bpx.StateError, match="closed"):
            call()


def test_python_threads_share_one_world():
    # Each thread excludes and includes its own pairs and sets its own boxes' user data while
    # others collide: every call waits for the world's lock, none races another.
    n, per = 400, 8
    with bpx.World(threads=2) as world:
        world.set_boxes(uniform_density(n, seed=3, overlaps_per_box=3.0))
        errors = []

        def work(t):
            try:
                mine = np.arange(t * n // per, (t + 1) * n // per)
                pairs = np.stack([mine[:-1], mine[1:]], axis=1)
                for step in range(20):
                    world.exclude_pairs(pairs)
                    world.set_user_data(mine, np.uint64(t * 1000 + step))
                    world.collide()
                    assert all(world.pair_excluded(i, j) for i, j in pairs[:5].tolist())
                    world.include_pairs(pairs[::2])
                    assert set(world.user_data(mine).tolist()) == {t * 1000 + step}
            except Exception as exc:  # pragma: no cover - reported below
                errors.append(exc)

        threads = [threading.Thread(target=work, args=(t,)) for t in range(per)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert not errors, errors
        excluded = set()
        for t in range(per):
            mine = np.arange(t * n // per, (t + 1) * n // per)
            excluded |= {tuple(p) for p in np.stack([mine[:-1], mine[1:]], axis=1)[1::2].tolist()}
        assert all(world.pair_excluded(i, j) for i, j in excluded)
        assert not excluded & {tuple(p) for p in world.collide().tolist()}
