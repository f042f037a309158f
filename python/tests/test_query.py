"""World's queries against a NumPy oracle that applies include/bpx/query.h's definitions to every
box (closed intervals; the sphere's distance and the slab test in double precision, step by step
as the header writes them; ties to the lowest id; sorted by id, or by fraction then id), on every
scene kind; filters; removed ids; batches equal to single queries; bad queries."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from scenes import SCENES, touching, uniform_density

import bpx
from bpx import _bpx

ALL = 0xFFFFFFFF
BOX, SPHERE, RAY, SWEEP = "box", "sphere", "ray", "sweep"


# -- the oracle -------------------------------------------------------------------------------


class Scene:
    """What a world holds, as the oracle sees it: boxes, which ids are live, their filters."""

    def __init__(self, boxes, live=None, categories=None, masks=None):
        self.boxes = np.asarray(boxes, np.float32).reshape(-1, 6)
        n = len(self.boxes)
        self.live = np.ones(n, bool) if live is None else np.asarray(live, bool)
        self.categories = np.ones(n, np.uint32) if categories is None else categories
        self.masks = np.full(n, ALL, np.uint32) if masks is None else masks
        b = self.boxes.astype(np.float64)  # exact
        self.lo, self.hi = b[:, :3], b[:, 3:]

    def seen(self, category, mask):
        return (
            self.live
            & ((np.uint32(category) & self.masks) != 0)
            & ((self.categories & np.uint32(mask)) != 0)
        )


def oracle_box(scene, box, category=ALL, mask=ALL):
    q = np.asarray(box, np.float32).astype(np.float64).reshape(6)
    hit = np.all((scene.lo <= q[3:]) & (scene.hi >= q[:3]), axis=1)
    return np.nonzero(hit & scene.seen(category, mask))[0].astype(np.uint32)


def oracle_sphere(scene, centre, radius, category=ALL, mask=ALL):
    c = np.asarray(centre, np.float32).astype(np.float64)
    r = float(np.float32(radius))
    g = np.maximum(np.maximum(scene.lo - c, c - scene.hi), 0.0)
    d2 = ((0.0 + g[:, 0] * g[:, 0]) + g[:, 1] * g[:, 1]) + g[:, 2] * g[:, 2]  # the C order
    hit = d2 <= r * r
    return np.nonzero(hit & scene.seen(category, mask))[0].astype(np.uint32)


def oracle_cast(scene, qlo, qhi, direction, max_fraction, closest, category=ALL, mask=ALL):
    """(ids, fractions) of the sweep of [qlo, qhi] along direction (a ray: qlo == qhi)."""
    qlo = np.asarray(qlo, np.float32).astype(np.float64)
    qhi = np.asarray(qhi, np.float32).astype(np.float64)
    d = np.asarray(direction, np.float32).astype(np.float64)
    n = len(scene.boxes)
    ok = scene.seen(category, mask).copy()
    enter = np.full(n, -np.inf)
    exit_ = np.full(n, np.inf)
    with np.errstate(over="ignore"):
        for a in range(3):
            if d[a] == 0.0:  # +0.0 and -0.0
                ok &= (scene.lo[:, a] <= qhi[a]) & (scene.hi[:, a] >= qlo[a])
                continue
            inv = 1.0 / d[a]
            t1 = (scene.lo[:, a] - qhi[a]) * inv
            t2 = (scene.hi[:, a] - qlo[a]) * inv
            enter = np.maximum(enter, np.minimum(t1, t2))
            exit_ = np.minimum(exit_, np.maximum(t1, t2))
    start = np.maximum(enter, 0.0)
    ok &= start <= np.minimum(exit_, float(np.float32(max_fraction)))
    ids = np.nonzero(ok)[0].astype(np.uint32)
    with np.errstate(over="ignore"):
        fractions = start[ok].astype(np.float32)  # rounded to float: may round to inf
    order = np.lexsort((ids, fractions))  # by fraction, then id
    ids, fractions = ids[order], fractions[order]
    if closest:
        ids, fractions = ids[:1], fractions[:1]
    return ids, fractions


# -- queries made from a scene: near its boxes, on their faces and corners ---------------------


def pick(rng, boxes, k):
    """(k, 3) coordinates: a box's min or max, a point inside it, or near it."""
    b = boxes[rng.integers(0, len(boxes), k)].astype(np.float64)
    lo, hi = b[:, :3], b[:, 3:]
    choice = rng.integers(0, 4, (k, 3))
    inside = lo + (hi - lo) * rng.uniform(0, 1, (k, 3))
    near = lo + rng.uniform(-4, 4, (k, 3))
    return np.select([choice == 0, choice == 1, choice == 2], [lo, hi, inside], near).astype(
        np.float32
    )


def directions(rng, k):
    """Components 0.0, -0.0, a denormal, +-1, or random; some whole rows zero."""
    choice = rng.integers(0, 7, (k, 3))
    sign = np.where(rng.integers(0, 2, (k, 3)) == 1, 1.0, -1.0)
    d = np.select(
        [choice == 0, choice == 1, choice == 2, choice == 3],
        [np.zeros((k, 3)), np.full((k, 3), -0.0), sign * 1e-40, sign],
        rng.uniform(-3, 3, (k, 3)),
    ).astype(np.float32)
    d[rng.uniform(0, 1, k) < 0.05] = 0.0
    return d


def max_fractions(rng, k, d):
    m = rng.choice(np.array([0.0, 0.5, 1.0, np.inf, 3.0], np.float32), k)
    drawn = rng.uniform(0, 1, k) < 0.2
    m[drawn] = rng.uniform(0, 10, int(drawn.sum()))
    m = np.where(np.all(d == 0, axis=1), np.float32(0.0), m)  # a zero direction: a point
    return m.astype(np.float32)


def make_queries(boxes, k, seed):
    rng = np.random.default_rng(seed)
    origins = pick(rng, boxes, k)
    d = directions(rng, k)
    aim = rng.uniform(0, 1, k) < 0.3  # segments from a point to another: max_fraction 1
    with np.errstate(over="ignore", invalid="ignore"):
        target = (pick(rng, boxes, k).astype(np.float64) - origins).astype(np.float32)
        d[aim] = np.where(np.isfinite(target[aim]), target[aim], np.float32(1.0))
    m = max_fractions(rng, k, d)
    m[aim & np.any(d != 0, axis=1)] = 1.0
    m = np.where(np.all(d == 0, axis=1), np.float32(0.0), m).astype(np.float32)
    size = np.where(rng.uniform(0, 1, (k, 3)) < 0.2, 0.0, rng.uniform(0, 2, (k, 3)))
    lo = pick(rng, boxes, k)
    with np.errstate(over="ignore"):
        hi = np.minimum(lo.astype(np.float64) + size, 3.4e38).astype(np.float32)
    hi = np.maximum(hi, lo)
    radii = rng.choice(np.array([0.0, 0.5, 1.0, 2.5], np.float32), k)
    drawn = rng.uniform(0, 1, k) < 0.3
    radii[drawn] = rng.uniform(0, 3, int(drawn.sum()))
    return {
        "origins": origins,
        "directions": d,
        "max_fractions": m,
        "boxes": np.concatenate([lo, hi], axis=1),
        "centres": pick(rng, boxes, k),
        "radii": radii,
    }


def check_all_kinds(world, scene, q, category=ALL, mask=ALL):
    """Every kind, single and batched, against the oracle; batches byte for byte against the
    singles. category and mask: numbers or (k,) arrays."""
    k = len(q["origins"])
    cats = np.broadcast_to(np.asarray(category, np.uint32), (k,))
    msks = np.broadcast_to(np.asarray(mask, np.uint32), (k,))
    checked = hits = 0
    singles = {BOX: [], SPHERE: []}
    for j in range(k):
        f = dict(category=int(cats[j]), mask=int(msks[j]))
        ids = world.query_box(q["boxes"][j], **f)
        assert ids.dtype == np.uint32
        np.testing.assert_array_equal(ids, oracle_box(scene, q["boxes"][j], **f))
        singles[BOX].append(ids)
        ids = world.query_sphere(q["centres"][j], q["radii"][j], **f)
        np.testing.assert_array_equal(ids, oracle_sphere(scene, q["centres"][j], q["radii"][j], **f))
        singles[SPHERE].append(ids)
        checked += 2
    batch = world.query_box_batch(q["boxes"], category=category, mask=mask)
    assert batch.offsets.tolist() == np.cumsum([0] + [len(s) for s in singles[BOX]]).tolist()
    assert batch.ids.tobytes() == b"".join(s.tobytes() for s in singles[BOX])
    batch = world.query_sphere_batch(q["centres"], q["radii"], category=category, mask=mask)
    assert batch.offsets.tolist() == np.cumsum([0] + [len(s) for s in singles[SPHERE]]).tolist()
    assert batch.ids.tobytes() == b"".join(s.tobytes() for s in singles[SPHERE])
    for every in (False, True):
        rays, sweeps = [], []
        for j in range(k):
            f = dict(category=int(cats[j]), mask=int(msks[j]))
            o, d, m, b = q["origins"][j], q["directions"][j], q["max_fractions"][j], q["boxes"][j]
            got = world.ray_cast(o, d, m, all=every, **f)
            want = oracle_cast(scene, o, o, d, m, not every, **f)
            rays.append(check_cast(got, want, every))
            got = world.sweep(b, d, m, all=every, **f)
            want = oracle_cast(scene, b[:3], b[3:], d, m, not every, **f)
            sweeps.append(check_cast(got, want, every))
            checked += 2
        for singles_of_kind, batch in (
            (rays, world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"],
                                        all=every, category=category, mask=mask)),
            (sweeps, world.sweep_batch(q["boxes"], q["directions"], q["max_fractions"],
                                       all=every, category=category, mask=mask)),
        ):
            assert batch.offsets.dtype == np.intp and batch.offsets.shape == (k + 1,)
            assert batch.counts.tolist() == [len(ids) for ids, _ in singles_of_kind]
            assert batch.ids.tobytes() == b"".join(ids.tobytes() for ids, _ in singles_of_kind)
            assert batch.fractions.tobytes() == b"".join(f.tobytes() for _, f in singles_of_kind)
            hits += len(batch.ids)
    return checked, hits


def check_cast(got, want, every):
    """got (a Hit, None or Hits) equals the oracle's (ids, fractions); returns it as arrays."""
    want_ids, want_fractions = want
    if every:
        assert isinstance(got, bpx.Hits)
        ids, fractions = got
        assert ids.dtype == np.uint32 and fractions.dtype == np.float32
    elif got is None:
        ids, fractions = np.empty(0, np.uint32), np.empty(0, np.float32)
    else:
        assert isinstance(got, bpx.Hit) and isinstance(got.id, int)
        ids = np.array([got.id], np.uint32)
        fractions = np.array([got.fraction], np.float32)
    np.testing.assert_array_equal(ids, want_ids)
    np.testing.assert_array_equal(fractions, want_fractions)
    return ids, fractions


# -- the answers --------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", sorted(SCENES))
def test_every_kind_matches_the_oracle_on_every_scene(kind):
    boxes = SCENES[kind](300, seed=5)
    with bpx.World() as world:
        world.set_boxes(boxes)
        checked, hits = check_all_kinds(world, Scene(boxes), make_queries(boxes, 40, seed=11))
        assert checked == 40 * 2 + 40 * 2 * 2
        assert hits > 40  # the queries meet boxes: the comparison is not of empty results


@pytest.mark.parametrize("n", [0, 1, 2, 17])
def test_small_worlds(n):
    boxes = uniform_density(n, seed=3, overlaps_per_box=2.0)
    with bpx.World() as world:
        world.set_boxes(boxes)
        queries = make_queries(boxes if n else np.zeros((1, 6), np.float32), 10, seed=n)
        check_all_kinds(world, Scene(boxes), queries)


def test_touching_lattice_faces_edges_and_corners():
    # Unit boxes on an integer lattice: rays along faces and edges, sweeps that end exactly on
    # a face, spheres that just reach a corner. Every such contact counts.
    boxes = touching(216, seed=2)
    scene = Scene(boxes)
    rng = np.random.default_rng(4)
    k = 120
    axis = rng.integers(0, 3, k)
    d = np.zeros((k, 3), np.float32)
    d[np.arange(k), axis] = rng.choice([-1.0, 1.0, 0.5, -2.0], k)
    origins = rng.integers(-1, 8, (k, 3)).astype(np.float32)  # on lattice planes: faces, edges
    lo = rng.integers(-1, 8, (k, 3)).astype(np.float32)
    queries = {
        "origins": origins,
        "directions": d,
        "max_fractions": rng.choice(np.array([0, 1, 2, 3.5, np.inf], np.float32), k),
        "boxes": np.concatenate([lo, lo + rng.integers(0, 2, (k, 3))], axis=1).astype(np.float32),
        "centres": rng.integers(-1, 8, (k, 3)).astype(np.float32) + 0.5,
        "radii": rng.choice(np.array([0, 0.5, math.sqrt(0.5), 1, 1.5], np.float32), k),
    }
    with bpx.World() as world:
        world.set_boxes(boxes)
        check_all_kinds(world, scene, queries)
        # along the lattice's edge x = 1, y = 1: every box sharing that edge is hit
        ids, fractions = world.ray_cast([1, 1, -0.5], [0, 0, 1], 1.0, all=True)
        want = oracle_cast(scene, [1, 1, -0.5], [1, 1, -0.5], [0, 0, 1], 1.0, False)
        np.testing.assert_array_equal(ids, want[0])
        np.testing.assert_array_equal(fractions, want[1])
        assert len(ids) > 0
    # a box swept along x by exactly the gap to the next one touches it at fraction 1
    with bpx.World() as world:
        world.set_boxes([[0, 0, 0, 1, 1, 1], [3, 0, 0, 4, 1, 1], [2, 0, 0, 2.5, 1, 1]])
        assert world.sweep([0, 0, 0, 1, 1, 1], [2, 0, 0]) == bpx.Hit(0, 0.0)
        assert world.sweep([-2, 0, 0, -1, 1, 1], [1, 0, 0]) == bpx.Hit(0, 1.0)
        assert world.sweep([-2, 0, 0, -1, 1, 1], [0.5, 0, 0]) is None
        hits = world.ray_cast([-1, 0.5, 1], [1, 0, 0], all=True)  # along the top face z = 1
        assert hits.ids.tolist() == [0, 2, 1] and hits.fractions.tolist() == [1, 3, 4]
        assert world.ray_cast([-1, 0.5, 1.0001], [1, 0, 0]) is None
        assert world.query_sphere([2, 0.5, 0.5], 1.0).tolist() == [0, 1, 2]
        assert world.query_sphere([2, 0.5, 0.5], 0.99).tolist() == [2]
        assert world.query_box([1, 0, 0, 3, 0, 0]).tolist() == [0, 1, 2]  # touching edges


def test_ties_go_to_the_lowest_id():
    # Identical boxes: every ray hits all of them at the same fraction.
    boxes = np.tile(np.array([[0, 0, 0, 1, 1, 1]], np.float32), (50, 1))
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.remove(np.arange(0, 7))
        assert world.ray_cast([-5, 0.5, 0.5], [1, 0, 0]) == bpx.Hit(7, 5.0)
        hits = world.ray_cast([-5, 0.5, 0.5], [1, 0, 0], all=True)
        assert hits.ids.tolist() == list(range(7, 50)) and set(hits.fractions.tolist()) == {5.0}
        assert world.sweep([-5, 0, 0, -4, 1, 1], [10, 0, 0]) == bpx.Hit(7, float(np.float32(0.4)))  # rounded to float


def test_signed_zero_and_denormal_directions():
    with bpx.World() as world:
        world.set_boxes([[0, 0, 0, 1, 1, 1], [-1, -1, -1, -0.0, -0.0, -0.0]])
        for zero in (0.0, -0.0):
            d = [1, zero, zero]
            assert world.ray_cast([-2, 0, 0], d, all=True).ids.tolist() == [1, 0]
        # a denormal component is not zero: the ray starts outside on y and only moves 1e-40
        # per unit t there, so it never reaches the box with a finite max_fraction
        assert world.ray_cast([0.5, -1, 0.5], [0, 1e-40, 0], 1e30) is None
        # with no bound it does, at t = 1 / 1e-40 in double: infinite once rounded to float
        assert world.ray_cast([0.5, -1, 0.5], [0, 1e-40, 0], math.inf) == bpx.Hit(0, math.inf)
        # zero direction and max_fraction 0: a point query
        assert world.ray_cast([0.5, 0.5, 0.5], [0, 0, 0], 0.0) == bpx.Hit(0, 0.0)
        assert world.ray_cast([0, 0, 0], [-0.0, 0, 0], 0, all=True).ids.tolist() == [0, 1]


# -- filters, removed ids, moves ----------------------------------------------------------------


def test_filters_on_boxes_and_queries():
    boxes = uniform_density(400, seed=8, overlaps_per_box=4.0)
    rng = np.random.default_rng(8)
    categories = (np.uint32(1) << rng.integers(0, 4, 400).astype(np.uint32)).astype(np.uint32)
    masks = rng.integers(0, 16, 400).astype(np.uint32)
    masks[:5] = 0  # seen by no query
    scene = Scene(boxes, categories=categories, masks=masks)
    queries = make_queries(boxes, 40, seed=9)
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.set_filters(None, categories, masks)
        # one filter for every query, then one per query (batches with (k,) arrays)
        check_all_kinds(world, scene, queries, category=3, mask=0b0101)
        check_all_kinds(world, scene, queries)
        qc = rng.integers(0, 16, 40).astype(np.uint32)
        qm = rng.integers(0, 16, 40).astype(np.uint32)
        check_all_kinds(world, scene, queries, category=qc, mask=qm)
        everything = world.query_box([-1e30, -1e30, -1e30, 1e30, 1e30, 1e30])
        assert not set(range(5)) & set(everything.tolist())
        assert len(world.query_box([-1e30] * 3 + [1e30] * 3, category=0)) == 0
        assert len(world.query_box([-1e30] * 3 + [1e30] * 3, mask=0)) == 0


def test_removed_ids_are_never_returned_and_moves_refit():
    boxes = uniform_density(500, seed=12, overlaps_per_box=4.0)
    rng = np.random.default_rng(12)
    with bpx.World(threads=2) as world:
        world.add(boxes)
        assert world.query_stats == bpx.QueryStats(0, 0, 0, 0, 0)  # no query yet, no tree
        removed = rng.choice(500, 150, replace=False)
        world.remove(removed)
        live = np.ones(500, bool)
        live[removed] = False
        queries = make_queries(boxes, 40, seed=13)
        check_all_kinds(world, Scene(boxes, live=live), queries)
        builds = world.query_stats.builds
        assert builds == 1 and world.query_stats.boxes == 350
        everything = world.query_sphere([0, 0, 0], 1e30)
        assert everything.tolist() == np.nonzero(live)[0].tolist()
        # moving the same ids: the next query refits
        keep = np.nonzero(live)[0]
        moved = boxes.copy()
        moved[keep] += rng.uniform(-2, 2, (len(keep), 1)).astype(np.float32)
        world.move(keep, moved[keep])
        check_all_kinds(world, Scene(moved, live=live), queries)
        stats = world.query_stats
        assert stats.builds + stats.refits == 2 and stats.refits >= 1 or stats.builds == 2
        # ids coming back: a rebuild, and the returned ids are live ones only
        world.collide()  # reports the removed ids' pairs as ended: they may be handed out again
        new = world.add(boxes[:20])
        live[new] = True
        moved[new] = boxes[:20]
        check_all_kinds(world, Scene(moved, live=live), queries)
        assert world.query_stats.builds >= 2


def test_two_phase_mode_is_queried_too():
    rng = np.random.default_rng(3)
    half = rng.uniform(0.2, 1.0, (200, 3)).astype(np.float32)
    with bpx.World() as world:
        world.load_extents(-half)
        for step in range(3):
            centres = rng.uniform(-6, 6, (200, 3)).astype(np.float32)
            world.update_centres(centres)
            boxes = np.concatenate([centres - half, centres + half], axis=1)
            check_all_kinds(world, Scene(boxes), make_queries(boxes, 15, seed=step))
        assert world.query_stats.refits >= 1


def test_batches_are_the_same_for_any_thread_count_and_across_chunks():
    boxes = uniform_density(3000, seed=21, overlaps_per_box=3.0)
    q = make_queries(boxes, 500, seed=22)  # 8 chunks of 64
    results = []
    for threads in (1, 2, 3):
        with bpx.World(threads=threads) as world:
            world.set_boxes(boxes)
            got = [
                world.query_box_batch(q["boxes"]),
                world.query_sphere_batch(q["centres"], q["radii"]),
                world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"]),
                world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"], all=True),
                world.sweep_batch(q["boxes"], q["directions"], q["max_fractions"], all=True),
            ]
            results.append([[a.tobytes() for a in r] for r in got])
    assert results[0] == results[1] == results[2]
    scene = Scene(boxes)
    with bpx.World(threads=2) as world:
        world.set_boxes(boxes)
        b = world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"], all=True)
        for j in range(0, 500, 37):
            ids, fractions = b.query(j)
            want = oracle_cast(scene, q["origins"][j], q["origins"][j], q["directions"][j],
                               q["max_fractions"][j], False)
            np.testing.assert_array_equal(ids, want[0])
            np.testing.assert_array_equal(fractions, want[1])
        assert len(b.split()) == 500
        assert [len(x) for x in world.query_box_batch(q["boxes"]).split()] == list(
            world.query_box_batch(q["boxes"]).counts
        )


def test_batch_arguments_broadcast_and_convert():
    boxes = uniform_density(200, seed=2, overlaps_per_box=4.0)
    q = make_queries(boxes, 30, seed=3)
    with bpx.World() as world:
        world.set_boxes(boxes)
        a = world.query_sphere_batch(q["centres"], 1.5)
        b = world.query_sphere_batch(q["centres"].astype(np.float64), np.full(30, 1.5))
        c = world.query_sphere_batch(q["centres"].tolist(), [1.5] * 30)
        assert a.ids.tobytes() == b.ids.tobytes() == c.ids.tobytes()
        d = world.query_box_batch(q["boxes"].reshape(30, 2, 3))
        e = world.query_box_batch(np.asfortranarray(q["boxes"]))
        assert d.ids.tobytes() == e.ids.tobytes() == world.query_box_batch(q["boxes"]).ids.tobytes()
        assert world.query_box(q["boxes"][0].reshape(2, 3)).tolist() == world.query_box(
            q["boxes"][0].tolist()).tolist()
        empty = world.ray_cast_batch(np.zeros((0, 3)), np.zeros((0, 3)))
        assert empty.offsets.tolist() == [0] and len(empty.ids) == 0 and len(empty.fractions) == 0
        offsets, ids, fractions = world.sweep_batch(q["boxes"][:3], q["directions"][:3], 0.0)
        assert offsets.shape == (4,)


# -- bad queries ----------------------------------------------------------------------------------

NAN, INF = math.nan, math.inf
GOOD_BOX = [0, 0, 0, 1, 1, 1]


def bad_single_queries():
    """(call, exception, status, axis, text in the message)."""
    return [
        (lambda w: w.ray_cast([0, NAN, 0], [1, 0, 0]), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", 1, "World.ray_cast: origin y is nan"),
        (lambda w: w.ray_cast([0, 0, 0], [1, 0, INF]), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", 2, "World.ray_cast: direction z is inf"),
        (lambda w: w.ray_cast([0, 0, 0], [1, 0, 0], NAN), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", None, "max_fraction is NaN"),
        (lambda w: w.ray_cast([0, 0, 0], [1, 0, 0], -1.0), bpx.InvalidArgumentError,
         "BPX_ERR_INVALID_ARGUMENT", None, "max_fraction -1 is negative"),
        (lambda w: w.ray_cast([0, 0, 0], [0, -0.0, 0]), bpx.InvalidArgumentError,
         "BPX_ERR_INVALID_ARGUMENT", None, "World.ray_cast: zero direction"),
        (lambda w: w.ray_cast([0, 0, 0], [0, 0, 0], 1e-30, all=True), bpx.InvalidArgumentError,
         "BPX_ERR_INVALID_ARGUMENT", None, "zero direction"),
        (lambda w: w.query_sphere([0, 0, 0], -0.5), bpx.InvalidArgumentError,
         "BPX_ERR_INVALID_ARGUMENT", None, "World.query_sphere: radius -0.5 is negative"),
        (lambda w: w.query_sphere([-INF, 0, 0], 1), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", 0, "World.query_sphere: centre x is -inf"),
        (lambda w: w.query_sphere([0, 0, 0], NAN), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", None, "radius is nan"),
        (lambda w: w.query_box([0, 0, 2, 1, 1, 1]), bpx.MinGreaterThanMaxError,
         "BPX_ERR_MIN_GREATER_THAN_MAX", 2, "World.query_box: box min z 2 > max 1"),
        (lambda w: w.query_box([0, 0, 0, 1, NAN, 1]), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", 1, "box max y is nan"),
        (lambda w: w.sweep([1, 0, 0, 0, 1, 1], [1, 0, 0]), bpx.MinGreaterThanMaxError,
         "BPX_ERR_MIN_GREATER_THAN_MAX", 0, "World.sweep: box min x 1 > max 0"),
        (lambda w: w.sweep(GOOD_BOX, [0, 0, 0]), bpx.InvalidArgumentError,
         "BPX_ERR_INVALID_ARGUMENT", None, "World.sweep: zero direction with max_fraction 1"),
        (lambda w: w.sweep(GOOD_BOX, [0, NAN, 0], all=True), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", 1, "direction y is nan"),
        (lambda w: w.sweep(GOOD_BOX, [1, 0, 0], -0.5), bpx.InvalidArgumentError,
         "BPX_ERR_INVALID_ARGUMENT", None, "negative"),
        # finite in float64, infinite in float32
        (lambda w: w.ray_cast(np.array([0, 0, 1e39]), [1, 0, 0]), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", 2, "(after conversion to float32)"),
        (lambda w: w.query_sphere([0, 0, 0], 1e39), bpx.NotFiniteError,
         "BPX_ERR_NOT_FINITE", None, "(after conversion to float32)"),
    ]


def snapshot(world):
    """What a query error must not change: the boxes, the pairs, the tree, a reference batch."""
    ref = make_queries(uniform_density(50, seed=1), 20, seed=2)
    return (
        len(world),
        world.pairs.tobytes(),
        world.query_stats[:4],
        world.ray_cast_batch(ref["origins"], ref["directions"], ref["max_fractions"],
                             all=True).ids.tobytes(),
    )


@pytest.fixture
def world_with_boxes():
    with bpx.World(threads=2) as world:
        world.set_boxes(uniform_density(300, seed=4, overlaps_per_box=3.0))
        world.collide()
        world.query_box(GOOD_BOX)  # the tree is built: a query error must not touch it
        yield world


@pytest.mark.parametrize("case", range(len(bad_single_queries())))
def test_bad_single_queries_name_the_query_and_axis(world_with_boxes, case):
    call, cls, status, axis, text = bad_single_queries()[case]
    world = world_with_boxes
    before = snapshot(world)
    with pytest.raises(cls) as info:
        call(world)
    e = info.value
    assert type(e) is cls and isinstance(e, ValueError) and isinstance(e, bpx.Error)
    assert e.status == status and e.axis == axis and e.index is None
    assert text in str(e), str(e)
    assert "query 0" not in str(e)
    assert snapshot(world) == before


def test_bad_queries_in_a_batch_name_their_index_and_nothing_runs(world_with_boxes):
    world = world_with_boxes
    before = snapshot(world)
    k = 200
    rng = np.random.default_rng(0)
    origins = rng.uniform(-5, 5, (k, 3)).astype(np.float32)
    dirs = rng.uniform(-1, 1, (k, 3)).astype(np.float32)
    boxes = np.concatenate([origins, origins + 1], axis=1)
    cases = []
    o = origins.copy()
    o[137, 2] = NAN
    cases.append((lambda: world.ray_cast_batch(o, dirs), bpx.NotFiniteError, 137, 2,
                  "World.ray_cast_batch: query 137: origin z is nan"))
    d = dirs.copy()
    d[70] = 0.0
    cases.append((lambda: world.ray_cast_batch(origins, d, all=True), bpx.InvalidArgumentError,
                  70, None, "World.ray_cast_batch: query 70: zero direction"))
    # the same zero direction with max_fraction 0 is a point query and fine; 71 is not
    m = np.ones(k, np.float32)
    m[70] = 0.0
    m[71] = -2.0
    cases.append((lambda: world.ray_cast_batch(origins, d, m), bpx.InvalidArgumentError, 71,
                  None, "query 71: max_fraction -2 is negative"))
    b = boxes.copy()
    b[5, 1], b[5, 4] = 3.0, 2.0
    cases.append((lambda: world.query_box_batch(b), bpx.MinGreaterThanMaxError, 5, 1,
                  "World.query_box_batch: query 5: box min y 3 > max 2"))
    cases.append((lambda: world.sweep_batch(b, dirs), bpx.MinGreaterThanMaxError, 5, 1,
                  "World.sweep_batch: query 5"))
    r = np.ones(k, np.float32)
    r[199] = -1
    cases.append((lambda: world.query_sphere_batch(origins, r), bpx.InvalidArgumentError, 199,
                  None, "World.query_sphere_batch: query 199: radius -1 is negative"))
    o2 = origins.astype(np.float64)
    o2[3, 0] = -1e39
    cases.append((lambda: world.query_sphere_batch(o2, 1.0), bpx.NotFiniteError, 3, 0,
                  "query 3: centre x is -inf (after conversion to float32)"))
    for call, cls, index, axis, text in cases:
        with pytest.raises(cls) as info:
            call()
        e = info.value
        assert (e.index, e.axis) == (index, axis) and text in str(e), str(e)
        assert snapshot(world) == before
    # after a move the tree is stale: a bad query neither refits nor rebuilds it
    stats = world.query_stats
    world.move([0, 1], np.array([GOOD_BOX, GOOD_BOX], np.float32))
    with pytest.raises(bpx.NotFiniteError):
        world.ray_cast_batch(o, dirs)
    assert world.query_stats == stats
    world.query_box(GOOD_BOX)
    assert world.query_stats.refits + world.query_stats.builds == stats.refits + stats.builds + 1
    # the world still answers, as before
    assert world.ray_cast_batch(origins, dirs).ids.tobytes() == world.ray_cast_batch(
        origins, dirs).ids.tobytes()


@pytest.mark.parametrize(
    "call,cls,text",
    [
        (lambda w: w.query_box([0, 0, 0, 1, 1]), bpx.InvalidArgumentError,
         r"World.query_box: box: expected shape \(6,\) or \(2, 3\), got \(5,\)"),
        (lambda w: w.query_box(np.zeros((1, 6))), bpx.InvalidArgumentError, "got \\(1, 6\\)"),
        (lambda w: w.query_sphere([0, 0], 1), bpx.InvalidArgumentError,
         r"centre: expected shape \(3,\)"),
        (lambda w: w.query_sphere([0, 0, 0], [1, 2]), bpx.InvalidArgumentError,
         "radius: expected a number"),
        (lambda w: w.ray_cast([0, 0, 0], [[1, 0, 0]]), bpx.InvalidArgumentError,
         r"direction: expected shape \(3,\)"),
        (lambda w: w.ray_cast([0, 0, 0], [1, 0, 0], [1.0]), bpx.InvalidArgumentError,
         "max_fraction: expected a number"),
        (lambda w: w.ray_cast([0, 0, 0j], [1, 0, 0]), bpx.DTypeError, "complex"),
        (lambda w: w.ray_cast(["a", "b", "c"], [1, 0, 0]), bpx.DTypeError, "<U1"),
        (lambda w: w.sweep(GOOD_BOX, [1, 0]), bpx.InvalidArgumentError, "translation"),
        (lambda w: w.ray_cast([0, 0, 0], [1, 0, 0], category=-1), bpx.InvalidArgumentError,
         "negative"),
        (lambda w: w.ray_cast([0, 0, 0], [1, 0, 0], mask=2**32), bpx.InvalidArgumentError,
         "above 2"),
        (lambda w: w.query_box(GOOD_BOX, category=[1, 2]), bpx.InvalidArgumentError,
         "category: expected a number"),
        (lambda w: w.query_box(GOOD_BOX, mask=1.5), bpx.DTypeError, "not an integer"),
        (lambda w: w.ray_cast_batch(np.zeros((4, 3)), np.ones((5, 3))), bpx.InvalidArgumentError,
         r"directions: expected shape \(4, 3\)"),
        (lambda w: w.ray_cast_batch(np.zeros((4, 2)), np.ones((4, 3))), bpx.InvalidArgumentError,
         r"origins: expected shape \(k, 3\)"),
        (lambda w: w.ray_cast_batch(np.zeros(3), np.ones(3)), bpx.InvalidArgumentError,
         r"origins: expected shape \(k, 3\)"),
        (lambda w: w.ray_cast_batch(np.zeros((4, 3)), np.ones((4, 3)), [1, 2]),
         bpx.InvalidArgumentError, r"max_fractions: expected a number or shape \(4,\)"),
        (lambda w: w.sweep_batch(np.zeros((4, 5)), np.ones((4, 3))), bpx.InvalidArgumentError,
         r"boxes: expected shape \(k, 6\) or \(k, 2, 3\)"),
        (lambda w: w.sweep_batch(np.zeros((4, 6)), np.ones((3, 3))), bpx.InvalidArgumentError,
         "translations"),
        (lambda w: w.query_sphere_batch(np.zeros((4, 3)), np.ones(3)), bpx.InvalidArgumentError,
         "radii"),
        (lambda w: w.query_box_batch(np.zeros((4, 6)), category=np.ones(3, np.uint32)),
         bpx.InvalidArgumentError, r"category: expected a number or shape \(4,\)"),
        (lambda w: w.query_box_batch(np.zeros((4, 6)), mask=[[1]] * 4),
         bpx.InvalidArgumentError, "mask"),
    ],
)
def test_wrong_shapes_and_dtypes_change_nothing(world_with_boxes, call, cls, text):
    before = snapshot(world_with_boxes)
    with pytest.raises(cls, match=text):
        call(world_with_boxes)
    assert snapshot(world_with_boxes) == before


def test_the_c_layer_checks_its_buffers():
    # bpx.World shapes everything before the C call; a direct call with anything else is
    # refused there, not read out of bounds.
    with bpx.World() as world:
        c = world._c
        one = np.ones(1, np.uint32)
        with pytest.raises(bpx.InvalidArgumentError, match="7 items per row"):
            c.query(_bpx.QUERY_RAY, True, False, np.zeros((1, 6), np.float32), one, one, False)
        with pytest.raises(bpx.InvalidArgumentError, match="expected one query"):
            c.query(_bpx.QUERY_RAY, True, False, np.zeros((2, 7), np.float32), one, one, False)
        with pytest.raises(bpx.InvalidArgumentError, match="3 categories for 2 queries"):
            c.query(_bpx.QUERY_BOX, False, False, np.zeros((2, 6), np.float32),
                    np.ones(3, np.uint32), one, True)
        with pytest.raises(bpx.InvalidArgumentError, match="float32"):
            c.query(_bpx.QUERY_BOX, False, False, np.zeros((1, 6)), one, one, False)
        with pytest.raises(bpx.InvalidArgumentError, match="unknown query kind"):
            c.query(9, False, False, np.zeros((1, 6), np.float32), one, one, False)


def test_closed_world_and_device_free_defaults():
    world = bpx.World()
    world.set_boxes(np.array([GOOD_BOX], np.float32))
    assert world.query_box(GOOD_BOX).tolist() == [0]
    world.close()
    for call in (
        lambda: world.query_box(GOOD_BOX),
        lambda: world.ray_cast([0, 0, 0], [1, 0, 0]),
        lambda: world.sweep_batch(np.zeros((1, 6)), np.ones((1, 3))),
        lambda: world.query_stats,
    ):
        with pytest.raises(bpx.StateError, match="closed"):
            call()


# -- threads, the GIL, memory ---------------------------------------------------------------------


def test_gil_is_released_during_a_batch():
    boxes = uniform_density(100_000, seed=1)
    rng = np.random.default_rng(1)
    k = 100_000
    origins = rng.uniform(-40, 40, (k, 3)).astype(np.float32)
    dirs = rng.uniform(-1, 1, (k, 3)).astype(np.float32)
    with bpx.World() as world:
        world.set_boxes(boxes)
        world.ray_cast_batch(origins[:10], dirs[:10])  # builds the tree
        start = time.perf_counter()
        world.ray_cast_batch(origins, dirs, 20.0, all=True)
        call = time.perf_counter() - start
        done, started = threading.Event(), threading.Event()

        def work():
            started.set()
            world.ray_cast_batch(origins, dirs, 20.0, all=True)
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


def test_python_threads_query_one_world():
    boxes = uniform_density(2000, seed=6, overlaps_per_box=3.0)
    q = make_queries(boxes, 200, seed=7)
    with bpx.World(threads=2) as world:
        world.set_boxes(boxes)
        expected = world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"],
                                        all=True).ids.tobytes()
        results = []

        def work():
            for _ in range(5):
                got = world.ray_cast_batch(q["origins"], q["directions"], q["max_fractions"],
                                           all=True)
                results.append(got.ids.tobytes())

        threads = [threading.Thread(target=work) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert results == [expected] * 20


def test_queries_leak_nothing():
    import gc
    import tracemalloc

    boxes = uniform_density(2000, seed=1, overlaps_per_box=2.0)
    q = make_queries(boxes, 100, seed=2)

    def churn():
        with bpx.World(threads=2) as world:
            world.set_boxes(boxes)
            world.query_box_batch(q["boxes"])
            world.sweep_batch(q["boxes"], q["directions"], q["max_fractions"], all=True)
            world.ray_cast(q["origins"][0], q["directions"][0], all=True)
            world.query_sphere(q["centres"][0], 2.0)
            with pytest.raises(bpx.NotFiniteError):
                world.ray_cast([NAN, 0, 0], [1, 0, 0])
            with pytest.raises(bpx.InvalidArgumentError):
                world.query_sphere_batch(q["centres"], -1.0)
            world.query_stats

    gc.collect()
    base = _bpx._allocated_bytes()
    churn()
    gc.collect()
    assert _bpx._allocated_bytes() == base
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for _ in range(20):
            churn()
        gc.collect()
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert _bpx._allocated_bytes() == base
    assert grown < 64 * 1024, grown
