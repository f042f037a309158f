"""Point and oriented-box queries, and the prepared world's queries: shared ones (any number of
Python threads at once) and each= callbacks; every answer against a NumPy oracle."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from scenes import touching, uniform_density
from test_query import ALL, Scene, make_queries, oracle_box, oracle_cast, oracle_sphere

import bpx
from bpx import _bpx

# -- oracles --------------------------------------------------------------------------------------


def oracle_point(scene, point, category=ALL, mask=ALL):
    p = np.asarray(point, np.float32).astype(np.float64)
    return oracle_box(scene, np.concatenate([p, p]), category, mask)


def oracle_oriented(scene, centre, half, rotation, category=ALL, mask=ALL):
    """query.h's separating-axis test in double, in the C code's order of operations."""
    c = np.asarray(centre, np.float32).astype(np.float64)
    h = np.asarray(half, np.float32).astype(np.float64)
    r = np.asarray(rotation, np.float32).astype(np.float64).reshape(3, 3)
    a = np.abs(r)
    e = 0.5 * (scene.hi - scene.lo)
    t = c - 0.5 * (scene.lo + scene.hi)
    ok = scene.seen(category, mask).copy()
    for i in range(3):
        reach = a[i, 0] * h[0] + a[i, 1] * h[1] + a[i, 2] * h[2]
        ok &= ~(np.abs(t[:, i]) > e[:, i] + reach)
    for j in range(3):
        d = t[:, 0] * r[0, j] + t[:, 1] * r[1, j] + t[:, 2] * r[2, j]
        reach = e[:, 0] * a[0, j] + e[:, 1] * a[1, j] + e[:, 2] * a[2, j]
        ok &= ~(np.abs(d) > reach + h[j])
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            d = t[:, i2] * r[i1, j] - t[:, i1] * r[i2, j]
            rb = e[:, i1] * a[i2, j] + e[:, i2] * a[i1, j]
            rq = h[j1] * a[i, j2] + h[j2] * a[i, j1]
            ok &= ~(np.abs(d) > rb + rq)
    return np.nonzero(ok)[0].astype(np.uint32)


def rotations(rng, k):
    """k random rotations (float32, orthonormal to float32's rounding), some axis-aligned."""
    q = rng.normal(size=(k, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    m = np.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        axis=1,
    ).reshape(k, 3, 3)
    m[rng.uniform(0, 1, k) < 0.15] = np.eye(3)
    return m.astype(np.float32)


@pytest.fixture(scope="module")
def scene_world():
    boxes = uniform_density(3000, seed=21, overlaps_per_box=3.0)
    world = bpx.World(threads=2)
    world.set_boxes(boxes)
    rng = np.random.default_rng(5)
    world.set_user_data(None, rng.integers(0, 2**64, len(boxes), dtype=np.uint64))
    yield world, Scene(boxes), boxes
    world.close()


def oriented_queries(boxes, k, seed):
    rng = np.random.default_rng(seed)
    q = make_queries(boxes, k, seed)
    half = np.where(rng.uniform(0, 1, (k, 3)) < 0.1, 0.0, rng.uniform(0, 3, (k, 3)))
    return q["centres"], half.astype(np.float32), rotations(rng, k)


# -- point and oriented queries -----------------------------------------------------------------


def test_point_queries_match_the_oracle(scene_world):
    world, scene, boxes = scene_world
    q = make_queries(boxes, 300, seed=3)
    points = np.concatenate([q["origins"], boxes[:50, :3], boxes[50:100, 3:]])  # corners too
    batch = world.query_point_batch(points)
    for k, p in enumerate(points):
        want = oracle_point(scene, p)
        got = world.query_point(p)
        assert got.dtype == np.uint32 and got.tolist() == want.tolist(), k
        assert batch.query(k).tolist() == want.tolist()
        assert world.query_box(np.concatenate([p, p])).tolist() == want.tolist()
        some = world.query_point(p, any=True)
        assert len(some) == min(1, len(want)) and set(some) <= set(want)


def test_point_queries_on_a_touching_lattice():
    boxes = touching(400, seed=2)
    scene = Scene(boxes)
    with bpx.World() as world:
        world.set_boxes(boxes)
        for p in np.concatenate([boxes[:, :3], boxes[:, 3:]]):
            assert world.query_point(p).tolist() == oracle_point(scene, p).tolist()


def test_oriented_queries_match_the_oracle(scene_world):
    world, scene, boxes = scene_world
    centres, half, rots = oriented_queries(boxes, 300, seed=8)
    batch = world.query_oriented_batch(centres, half, rots)
    hits = 0
    for k in range(len(centres)):
        want = oracle_oriented(scene, centres[k], half[k], rots[k])
        got = world.query_oriented(centres[k], half[k], rots[k])
        assert got.dtype == np.uint32 and got.tolist() == want.tolist(), k
        assert batch.query(k).tolist() == want.tolist()
        flat = rots[k].reshape(9)
        assert world.query_oriented(centres[k], half[k], flat).tolist() == want.tolist()
        some = world.query_oriented(centres[k], half[k], rots[k], any=True)
        assert len(some) == min(1, len(want)) and set(some) <= set(want)
        hits += len(want)
    assert hits > 300  # the queries meet boxes, not just empty space


def test_an_axis_aligned_oriented_box_is_a_box_query(scene_world):
    world, scene, boxes = scene_world
    rng = np.random.default_rng(4)
    for _ in range(100):
        c = rng.uniform(-10, 10, 3)
        h = rng.choice([0.25, 0.5, 1.0, 2.0], 3)  # exact: c +- h is the same box in float32
        c = c.astype(np.float32).astype(np.float64)
        want = world.query_box(np.concatenate([c - h, c + h]))
        assert world.query_oriented(c, h, np.eye(3)).tolist() == want.tolist()


def test_oriented_batches_broadcast_one_shape_and_one_rotation(scene_world):
    world, scene, boxes = scene_world
    centres, _, rots = oriented_queries(boxes, 40, seed=9)
    half = np.array([1.0, 0.5, 2.0], np.float32)
    got = world.query_oriented_batch(centres, half, rots[0])
    for k, c in enumerate(centres):
        assert got.query(k).tolist() == oracle_oriented(scene, c, half, rots[0]).tolist()


def test_oriented_filters(scene_world):
    _, _, boxes = scene_world
    n = len(boxes)
    categories = (np.arange(n) % 3 + 1).astype(np.uint32)
    masks = np.full(n, ALL, np.uint32)
    scene = Scene(boxes, categories=categories, masks=masks)
    centres, half, rots = oriented_queries(boxes, 50, seed=10)
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.set_filters(None, categories, masks)
        for k in range(50):
            want = oracle_oriented(scene, centres[k], half[k], rots[k], category=ALL, mask=2)
            got = world.query_oriented(centres[k], half[k], rots[k], mask=2)
            assert got.tolist() == want.tolist()


@pytest.mark.parametrize(
    "args,cls,text",
    [
        (([0, 0, 0], [1, -1, 1], np.eye(3)), bpx.InvalidArgumentError, "half"),
        (([0, 0, 0], [1, 1, 1], 2 * np.eye(3)), bpx.InvalidArgumentError, "rotation"),
        (([0, 0, 0], [1, 1, 1], np.ones((3, 3))), bpx.InvalidArgumentError, "rotation"),
        (([0, np.nan, 0], [1, 1, 1], np.eye(3)), bpx.NotFiniteError, None),
        (([0, 0, 0], [1, np.inf, 1], np.eye(3)), bpx.NotFiniteError, None),
        (([0, 0, 0], [1, 1, 1], np.eye(2)), bpx.InvalidArgumentError, "rotation"),
        (([0, 0], [1, 1, 1], np.eye(3)), bpx.InvalidArgumentError, "centre"),
    ],
)
def test_bad_oriented_queries(scene_world, args, cls, text):
    world = scene_world[0]
    with pytest.raises(cls, match=text) as info:
        world.query_oriented(*args)
    assert str(info.value).startswith("World.query_oriented")
    with pytest.raises(cls):
        world.query_oriented(*args, shared=True)


def test_bad_points_and_a_bad_oriented_batch_name_their_index(scene_world):
    world = scene_world[0]
    with pytest.raises(bpx.NotFiniteError) as info:
        world.query_point([0, 0, np.nan])
    assert info.value.axis == 2 and str(info.value).startswith("World.query_point")
    with pytest.raises(bpx.InvalidArgumentError):
        world.query_point([[0, 0, 0]])
    rots = np.stack([np.eye(3)] * 3)
    rots[1] *= 2
    with pytest.raises(bpx.InvalidArgumentError) as info:
        world.query_oriented_batch(np.zeros((3, 3)), [1, 1, 1], rots)
    assert info.value.index == 1
    with pytest.raises(bpx.InvalidArgumentError, match="one per query"):
        world.query_oriented_batch(np.zeros((3, 3)), [1, 1, 1], rots[:2])


# -- shared queries -------------------------------------------------------------------------------


def test_shared_queries_are_the_same_as_the_others(scene_world):
    world, scene, boxes = scene_world
    q = make_queries(boxes, 150, seed=12)
    centres, half, rots = oriented_queries(boxes, 150, seed=13)
    world.prepare_queries()
    for k in range(150):
        box = q["boxes"][k]
        o, d, m = q["origins"][k], q["directions"][k], q["max_fractions"][k]
        for query in [
            lambda **kw: world.query_box(box, **kw),
            lambda **kw: world.query_sphere(q["centres"][k], q["radii"][k], **kw),
            lambda **kw: world.query_point(o, **kw),
            lambda **kw: world.query_oriented(centres[k], half[k], rots[k], **kw),
        ]:
            want = query()
            assert query(shared=True).tolist() == want.tolist()
            assert query(shared=True, any=True).tolist() == query(any=True).tolist()
        assert world.query_box(box, shared=True).tolist() == oracle_box(scene, box).tolist()
        assert (world.query_sphere(q["centres"][k], q["radii"][k], shared=True).tolist()
                == oracle_sphere(scene, q["centres"][k], q["radii"][k]).tolist())
        for every in (False, True):
            ids, fractions = oracle_cast(scene, o, o, d, m, not every)
            for got in (world.ray_cast(o, d, m, all=every, shared=True),
                        world.ray_cast(o, d, m, all=every)):
                if every:
                    assert got.ids.tolist() == ids.tolist()
                    assert got.fractions.tolist() == fractions.tolist()
                else:
                    assert (got is None) == (len(ids) == 0)
                    if got is not None:
                        assert (got.id, got.fraction) == (ids[0], fractions[0])
            lo, hi = box[:3], box[3:]
            ids, fractions = oracle_cast(scene, lo, hi, d, m, not every)
            got = world.sweep(box, d, m, all=every, shared=True)
            if every:
                assert got.ids.tolist() == ids.tolist()
            else:
                assert (got is None) == (len(ids) == 0)
        anyhit = world.ray_cast(o, d, m, any=True, shared=True)
        assert anyhit == world.ray_cast(o, d, m, any=True)
    # Past the 64 hits the shared path holds on the stack: bpx says how many, it runs again.
    everything = [-100, -100, -100, 100, 100, 100]
    assert world.query_box(everything, shared=True).tolist() == list(range(len(boxes)))
    lo, hi, d = [-60, -4, -4], [-59, 4, 4], [120, 0, 0]
    ids, fractions = oracle_cast(scene, lo, hi, d, 1.0, False)
    got = world.sweep(lo + hi, d, all=True, shared=True)
    assert len(ids) > 64 and got.ids.tolist() == ids.tolist()
    assert got.fractions.tolist() == fractions.tolist()


def test_shared_queries_need_a_prepared_unchanged_world():
    boxes = uniform_density(200, seed=2)
    with bpx.World() as world:
        world.set_boxes(boxes)
        with pytest.raises(bpx.StateError, match="World.query_box: .*prepare"):
            world.query_box([0, 0, 0, 1, 1, 1], shared=True)
        world.prepare_queries()
        before = world.query_box([-50, -50, -50, 50, 50, 50], shared=True)
        assert len(before) == 200
        world.remove([0, 1])
        for call in (
            lambda: world.query_box([0, 0, 0, 1, 1, 1], shared=True),
            lambda: world.ray_cast([0, 0, 0], [1, 0, 0], shared=True),
            lambda: world.query_point([0, 0, 0], each=print, shared=True),
        ):
            with pytest.raises(bpx.StateError):
                call()
        world.query_box([0, 0, 0, 1, 1, 1])  # the plain queries prepare for themselves
        world.prepare_queries()
        after = world.query_box([-50, -50, -50, 50, 50, 50], shared=True)
        assert after.tolist() == before.tolist()[2:]
    with pytest.raises(bpx.StateError, match="closed"):
        world.query_box([0, 0, 0, 1, 1, 1], shared=True)
    with pytest.raises(bpx.StateError, match="closed"):
        world.prepare_queries()


def test_python_threads_share_one_prepared_world():
    boxes = uniform_density(5000, seed=3, overlaps_per_box=2.0)
    q = make_queries(boxes, 200, seed=14)
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.prepare_queries()
        want = [world.ray_cast(q["origins"][k], q["directions"][k], q["max_fractions"][k],
                               all=True).ids.tolist() for k in range(200)]
        failures = []

        def work(seed):
            order = np.random.default_rng(seed).permutation(200)
            for k in order:
                got = world.ray_cast(q["origins"][k], q["directions"][k], q["max_fractions"][k],
                                     all=True, shared=True)
                if got.ids.tolist() != want[k]:
                    failures.append(k)

        threads = [threading.Thread(target=work, args=(s,)) for s in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert failures == []


def test_shared_readers_run_together_and_a_change_waits_for_them():
    """A shared query held open inside its callback (the GIL free meanwhile, waiting on an
    event) does not keep another thread's shared query out, but keeps a change out until it
    ends; after the change, shared queries say the world is no longer prepared."""
    boxes = uniform_density(500, seed=4)
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.prepare_queries()
        inside, release = threading.Event(), threading.Event()
        order = []

        def hold(i, fraction, data):
            inside.set()
            release.wait(10)
            order.append("callback returns")  # the reader ends after this, before the writer
            return 0  # stop: one hit is enough

        def reader():
            world.query_box([-50, -50, -50, 50, 50, 50], each=hold, shared=True)

        def writer():
            world.set_boxes(boxes[:100])
            order.append("writer done")

        held = threading.Thread(target=reader)
        held.start()
        assert inside.wait(10)
        # Another reader runs to the end while the first is held.
        assert len(world.query_box([-50, -50, -50, 50, 50, 50], shared=True)) == 500
        changer = threading.Thread(target=writer)
        changer.start()
        changer.join(0.3)
        assert changer.is_alive() and order == []  # waits for the held reader
        release.set()
        held.join(10)
        changer.join(10)
        assert order == ["callback returns", "writer done"]
        assert len(world) == 100
        with pytest.raises(bpx.StateError):
            world.query_box([0, 0, 0, 1, 1, 1], shared=True)


def test_gil_is_released_during_a_shared_query():
    import time

    boxes = uniform_density(300_000, seed=1)
    everything = [-1e3, -1e3, -1e3, 1e3, 1e3, 1e3]
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.prepare_queries()
        start = time.perf_counter()
        assert len(world.query_box(everything, shared=True)) == len(boxes)
        call = time.perf_counter() - start
        done, started = threading.Event(), threading.Event()

        def work():
            started.set()
            for _ in range(3):
                world.query_box(everything, shared=True)
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
    assert len(gaps) > 100
    assert max(gaps) < 0.5 * call, (max(gaps), call)


def test_readers_and_writers_under_load():
    a = uniform_density(1500, seed=5)
    b = a + np.float32(0.25)
    scenes = {len(x): x for x in (a, b[:1000])}
    probe = np.array([-20, -20, -20, 20, 20, 20], np.float32)
    want = {n: Scene(x) for n, x in scenes.items()}
    with bpx.World() as world:
        world.set_boxes(a)
        world.prepare_queries()
        stop = threading.Event()
        bad, answered = [], [0]

        def reader():
            while not stop.is_set():
                try:
                    got = world.query_box(probe, shared=True)
                except bpx.StateError:
                    continue  # between a change and the next prepare
                if not any(got.tolist() == oracle_box(s, probe).tolist() for s in want.values()):
                    bad.append(len(got))
                answered[0] += 1

        readers = [threading.Thread(target=reader) for _ in range(3)]
        for t in readers:
            t.start()
        for step in range(30):
            world.set_boxes(a if step % 2 else b[:1000])
            world.prepare_queries()
        stop.set()
        for t in readers:
            t.join()
        assert bad == [] and answered[0] > 0


# -- each= callbacks ------------------------------------------------------------------------------


@pytest.mark.parametrize("shared", [False, True])
def test_each_reports_every_hit_with_its_user_data(scene_world, shared):
    world, scene, boxes = scene_world
    q = make_queries(boxes, 60, seed=15)
    centres, half, rots = oriented_queries(boxes, 60, seed=16)
    data = world.user_data(np.arange(len(boxes)))
    if shared:
        world.prepare_queries()
    for k in range(60):
        box, o = q["boxes"][k], q["origins"][k]
        for call, want in [
            (lambda fn: world.query_box(box, each=fn, shared=shared), oracle_box(scene, box)),
            (lambda fn: world.query_point(o, each=fn, shared=shared), oracle_point(scene, o)),
            (lambda fn: world.query_sphere(q["centres"][k], q["radii"][k], each=fn,
                                           shared=shared),
             oracle_sphere(scene, q["centres"][k], q["radii"][k])),
            (lambda fn: world.query_oriented(centres[k], half[k], rots[k], each=fn,
                                             shared=shared),
             oracle_oriented(scene, centres[k], half[k], rots[k])),
        ]:
            seen = []
            assert call(lambda i, f, d: seen.append((i, f, d))) is None
            assert sorted(i for i, _, _ in seen) == want.tolist()
            assert all(f == 0.0 and d == int(data[i]) for i, f, d in seen)
        d, m = q["directions"][k], q["max_fractions"][k]
        ids, fractions = oracle_cast(scene, o, o, d, m, False)
        seen = {}
        assert world.ray_cast(o, d, m, each=lambda i, f, _: seen.__setitem__(i, f),
                              shared=shared) is None
        assert sorted(seen) == sorted(ids.tolist())
        assert all(seen[i] == f for i, f in zip(ids.tolist(), fractions.tolist()))
        lo, hi = q["boxes"][k][:3], q["boxes"][k][3:]
        ids, _ = oracle_cast(scene, lo, hi, d, m, False)
        seen = []
        world.sweep(q["boxes"][k], d, m, each=lambda i, f, _: seen.append(i), shared=shared)
        assert sorted(seen) == sorted(ids.tolist())


@pytest.mark.parametrize("shared", [False, True])
def test_each_steers_the_walk(scene_world, shared):
    world, scene, boxes = scene_world
    q = make_queries(boxes, 200, seed=17)
    if shared:
        world.prepare_queries()
    clipped = 0
    for k in range(200):
        o, d, m = q["origins"][k], q["directions"][k], q["max_fractions"][k]
        ids, fractions = oracle_cast(scene, o, o, d, m, False)
        # Clip to each hit: the last one reported is the closest (Box2D's closest ray cast).
        best = []

        def closest(i, f, _):
            if not best or (f, i) < best[0]:
                best[:] = [(f, i)]
            return f

        world.ray_cast(o, d, m, each=closest, shared=shared)
        if len(ids):
            assert best[0][0] == fractions[0]
            assert best[0][1] in ids[fractions == fractions[0]].tolist()
        else:
            assert best == []
        # 0 stops at the first hit; < 0 and NaN ignore and go on; None goes on.
        for steer, calls in [(0.0, min(1, len(ids))), (-1.0, len(ids)),
                             (float("nan"), len(ids)), (None, len(ids)),
                             (np.float32(np.inf), len(ids))]:
            seen = []
            world.ray_cast(o, d, m, each=lambda i, f, _: seen.append(i) or steer, shared=shared)
            assert len(seen) == calls, (steer, k)
        seen = []
        world.query_box(q["boxes"][k], each=lambda i, f, _: seen.append(i) or 0, shared=shared)
        assert len(seen) == min(1, len(oracle_box(scene, q["boxes"][k])))
        # A fixed end: hits entering after it are skipped, those before are all reported.
        if len(ids) > 1 and fractions[0] > 0:  # (returning 0 would stop)
            cut = float(fractions[0])
            seen = []
            world.ray_cast(o, d, m, each=lambda i, f, _: seen.append((i, f)) or cut,
                           shared=shared)
            assert {i for i, f in seen if f <= cut} == set(ids[fractions <= cut].tolist())
            assert all(f <= cut for _, f in seen[1:])
            clipped += 1
    assert clipped > 10


@pytest.mark.parametrize("shared", [False, True])
def test_each_raises_what_the_callback_raises_and_stops(scene_world, shared):
    world = scene_world[0]
    if shared:
        world.prepare_queries()
    calls = []

    def boom(i, f, d):
        calls.append(i)
        raise KeyError("from the callback")

    everything = [-100, -100, -100, 100, 100, 100]
    with pytest.raises(KeyError, match="from the callback"):
        world.query_box(everything, each=boom, shared=shared)
    assert len(calls) == 1
    with pytest.raises(TypeError):
        world.query_box(everything, each=lambda i, f, d: "not a number", shared=shared)
    with pytest.raises(TypeError):
        world.query_box(everything, each=lambda i: None, shared=shared)  # wrong arity
    # The world is fine afterwards.
    assert len(world.query_box(everything, shared=shared)) == len(world)


@pytest.mark.parametrize("shared", [False, True])
def test_each_callback_cannot_use_its_own_world(scene_world, shared):
    world, _, boxes = scene_world
    if shared:
        world.prepare_queries()
    everything = [-100, -100, -100, 100, 100, 100]
    for inner in (
        lambda: world.collide(),
        lambda: world.set_boxes(boxes),
        lambda: world.query_box(everything),
        lambda: world.query_box(everything, shared=True),
        lambda: world.query_point([0, 0, 0], each=print),
        lambda: world.prepare_queries(),
        lambda: world.close(),
        lambda: len(world),
    ):
        with pytest.raises(bpx.StateError, match="own query callback"):
            world.query_box(everything, each=lambda i, f, d: inner(), shared=shared)
    assert not world.closed
    # Another world is fine from inside.
    with bpx.World() as other:
        other.set_boxes(boxes[:10])
        counts = []
        world.query_box(everything, shared=shared,
                        each=lambda i, f, d: counts.append(len(other.query_box(everything))) or 0)
        assert counts == [10]


def test_each_with_a_pair_filter_and_nested_worlds():
    boxes = uniform_density(50, seed=8, overlaps_per_box=3.0)
    with bpx.World() as a, bpx.World() as b:
        a.set_boxes(boxes)
        b.set_boxes(boxes)
        everything = [-100, -100, -100, 100, 100, 100]
        errors = []

        def inner(i, f, d):  # b's callback, inside a's: a and b both refuse
            for w in (a, b):
                try:
                    len(w)
                except bpx.StateError:
                    errors.append(w is a)
            return 0

        a.query_box(everything, each=lambda i, f, d: b.query_box(everything, each=inner) or 0)
        assert errors == [True, False]

        def pair_filter(i, j, di, dj):  # from the pair filter, a's queries are refused too
            for call in (lambda: a.query_box(everything, shared=True),
                         lambda: a.query_box(everything, each=print)):
                try:
                    call()
                except bpx.StateError:
                    errors.append("filter")
            return True

        a.set_pair_filter(pair_filter)
        a.collide()
        assert errors.count("filter") >= 2


def test_each_arguments():
    with bpx.World() as world:
        world.set_boxes([[0, 0, 0, 1, 1, 1]])
        with pytest.raises(bpx.InvalidArgumentError, match="not callable"):
            world.query_box([0, 0, 0, 1, 1, 1], each=3)
        with pytest.raises(bpx.InvalidArgumentError, match="each and any"):
            world.query_box([0, 0, 0, 1, 1, 1], each=print, any=True)
        with pytest.raises(bpx.InvalidArgumentError, match="each and all"):
            world.ray_cast([0, 0, 0], [1, 0, 0], each=print, all=True)
        with pytest.raises(bpx.InvalidArgumentError, match="each and any"):
            world.sweep([0, 0, 0, 1, 1, 1], [1, 0, 0], each=print, any=True)
        with pytest.raises(bpx.NotFiniteError):
            world.query_point([np.nan, 0, 0], each=print)
        with pytest.raises(bpx.InvalidArgumentError):  # the C layer checks too
            world._c.query_each(_bpx.QUERY_BOX, np.zeros((2, 6), np.float32),
                                np.ones(1, np.uint32), np.ones(1, np.uint32), print, False)


def test_each_and_shared_leak_nothing():
    import gc

    boxes = uniform_density(300, seed=9)
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.prepare_queries()
        everything = [-100, -100, -100, 100, 100, 100]

        def rounds():
            for _ in range(50):
                world.query_box(everything, shared=True)
                world.query_box(everything, each=lambda i, f, d: None, shared=True)
                world.query_box(everything, each=lambda i, f, d: None)
                try:
                    world.query_box(everything, each=lambda i, f, d: 1 / 0)
                except ZeroDivisionError:
                    pass

        rounds()
        gc.collect()
        before = _bpx._allocated_bytes()
        import tracemalloc

        tracemalloc.start()
        rounds()
        gc.collect()
        first, _ = tracemalloc.get_traced_memory()
        rounds()
        gc.collect()
        second, _ = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert second - first < 20_000
        assert _bpx._allocated_bytes() == before
