"""bpx.World: a broad phase kept between the cycles of a simulation."""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, NamedTuple, Optional, Tuple, Union

import numpy as np

from . import _bpx
from ._arrays import (
    boxes_array,
    int_array,
    pairs_array,
    pairs_from_bytes,
    uint32_array,
    vec3_array,
)
from ._core import check_backend, check_threads, converted_note
from ._errors import DTypeError, InvalidArgumentError
from ._neighbors import exact_array, period_of
from ._query import (
    ALL,
    BatchHits,
    BatchIds,
    Hit,
    Hits,
    Params,
    QueryStats,
    filter_arrays,
    many_boxes,
    many_rotations,
    many_scalars,
    many_vec3,
    one_box,
    one_rotation,
    one_scalar,
    one_vec3,
)

#: A query_each callback: ``fn(id, fraction, user_data)`` -> None (go on) or a number that
#: steers the walk (< 0 or NaN: ignore this hit; 0: stop; > 0: go on, a ray or sweep ending at
#: that fraction).
HitCallback = Callable[[int, float, int], Optional[float]]


class Stage(NamedTuple):
    """One stage of a profiled cycle (``World(profile=True)``; ``bpx_stage_stats``): its
    wall-clock time, and the bytes it reads and writes as computed from the sizes of the arrays
    it touches (not counted by hardware), to read against the machine's memory floor."""

    name: str  #: e.g. "update", "keys", "scatter", "tests", "order", "merge"
    backend: str  #: the backend that ran it ("grid", "sap"; "world" for the world's own)
    ns: int  #: wall-clock nanoseconds
    bytes_read: int  #: bytes the stage reads
    bytes_written: int  #: bytes the stage writes
    random: int  #: records reached at spread addresses ("gather", "scatter"), else 0
    access: str  #: "sequential", "gather" or "scatter"


@dataclass(frozen=True)
class Stats:
    """Counts and timings of a world's last cycle (``bpx_world_stats``): the paper's registers
    n and collision count, and wall-clock nanoseconds per stage."""

    box_count: int  #: n, the boxes in the world
    pair_count: int  #: pairs found by the last collide
    pair_tests: int  #: box-pair tests the comparator made
    update_ns: int  #: updater: the last set_boxes / update_centres, validation included
    compare_ns: int  #: comparator: the pair tests, all threads
    emit_ns: int  #: collision emitter: merging hits into one ordered list
    cycle_count: int  #: collides since the world was made
    rebuilt: bool  #: sap: the last cycle rebuilt its sorted lists from scratch
    backend: str  #: the backend the last cycle ran (auto's choice, for auto)
    simd: str  #: the SIMD width in use
    transfer_in_ns: int = 0  #: opencl, cuda: host-to-device time
    transfer_out_ns: int = 0  #: opencl, cuda: device-to-host time
    device_ns: int = 0  #: opencl, cuda: kernel time
    bytes_in: int = 0  #: opencl, cuda: bytes sent to the device
    bytes_out: int = 0  #: opencl, cuda: bytes read back
    device_share: float = 0.0  #: hybrid: the share of the boxes the device got
    #: with ``World(profile=True)``: the cycle's stages in the order they ran (the updater's
    #: first; grid, sap, prune and auto report theirs); empty without it
    stages: Tuple[Stage, ...] = ()


class PairEvents(NamedTuple):
    """The change in the pair set made by the last collide, each (k, 2) uint32, sorted."""

    began: np.ndarray  #: pairs in this cycle's set and not in the previous one's
    ended: np.ndarray  #: pairs in the previous cycle's set and not in this one's


class World:
    """A broad phase kept between the cycles of a simulation (a ``bpx_world``).

    Each cycle, hand over the boxes (one of the two modes below), then call ``collide()`` for
    every overlapping pair (i, j), i < j, sorted, as a (k, 2) uint32 array. A box's index is its
    id.

    Two-phase mode (the paper's): ``load_extents(minima)`` once, then each cycle
    ``update_centres(centres)``; box i is ``centres[i] + minima[i]`` .. ``centres[i] - minima[i]``.

    General mode: ``set_boxes(boxes)`` each cycle, or keep boxes and change them by id with
    ``add``, ``remove`` and ``move`` (a removed id is handed out again only after a collide has
    reported its pairs as ended).

    Filters: ``set_filters(ids, categories, masks)``; a and b pair only if
    ``(category_a & mask_b) and (category_b & mask_a)``. ``set_groups(ids, groups)``: the same
    non-zero group always pairs (positive) or never (negative), before the filter's rule.
    ``exclude_pairs(pairs)`` / ``include_pairs(pairs)``: pairs that never pair, before both
    (``pair_excluded(i, j)``). Each costs little per overlapping pair (two reads; a hash lookup
    only for a pair whose boxes both have exclusions) and the pairs are the same for any
    thread count. ``set_user_data(ids, values)`` / ``user_data(ids)``: a uint64 per box.

    Queries, over the current boxes (removed ids never come back), with a filter of their own:
    ``query_box``, ``query_sphere``, ``query_point`` and ``query_oriented`` (sorted uint32
    ids), ``ray_cast`` and ``sweep`` (the closest ``Hit(id, fraction)`` or None, or with
    ``all=True`` every hit as ``Hits(ids, fractions)``), and each ``*_batch`` form for many
    queries at once on the world's threads, in CSR form. ``any=True`` (every kind) stops at the
    first hit the tree's walk meets: at most one, none exactly when there is none. The answers
    are exact, as include/bpx/query.h defines them. ``shared=True`` (single queries, after
    ``prepare_queries()``): many Python threads query the world at once. ``each=fn``: a
    callback per hit that steers the walk (accept, ignore, stop, end a ray early).

    Events: with ``track_events=True``, ``events`` holds the pairs that began and ended with
    the last collide.

    Errors raise ``bpx.Error`` subclasses naming the box and the axis; after an error the world
    is as it was before the call. The GIL is released while bpx works; one world serves one
    call at a time (a second thread's call waits for the first). Use it as a context manager,
    or call ``close()``, to free its threads and memory at once.

    Args:
        backend: "auto" (default) or a name from ``bpx.backends()``.
        threads: threads working on each cycle, the caller's included (0 or 1: the caller
            only; bpx starts threads - 1 of its own, which spin ``spin_us`` after a cycle).
        track_events: keep the pair set between cycles for ``events``.
        simd: force a SIMD width for brute ("scalar", "sse2", "avx2", "avx512", "neon").
        spin_us: microseconds a worker spins for the next cycle before it sleeps (0: 200;
            negative: never spin).
        capacity_hint: boxes to reserve memory for up front.
        begin_margin, end_margin: contact margins (not with a cell).
        profile: time each stage of every cycle and count its bytes, into ``stats.stages``
            (two clock reads a stage; the same pairs either way).
        cell, pbc: a periodic cell, as for ``neighbor_pairs`` (one length, three, or a diagonal
            3x3 matrix; ``pbc`` says which axes are periodic, default all). Then box j pairs
            with box i when any periodic image of j (j moved by whole cell lengths) overlaps
            i: ``pairs``, ``events``, filters and exclusions stay on the distinct (i, j), and
            ``image_pairs()`` gives every overlapping image with its shift. Boxes need not lie
            inside the cell.
    """

    def __init__(
        self,
        backend: str = "auto",
        threads: int = 1,
        *,
        track_events: bool = False,
        simd: str = "auto",
        spin_us: int = 0,
        capacity_hint: int = 0,
        begin_margin: float = 0.0,
        end_margin: float = 0.0,
        cell: Any = None,
        pbc: Any = True,
        profile: bool = False,
    ) -> None:
        backend = check_backend(backend, "World")
        threads = check_threads(threads, "World")
        if not isinstance(simd, str):
            raise InvalidArgumentError(f"World: simd must be a name (str), got {simd!r}")
        begin, end = float(begin_margin), float(end_margin)
        if not (0.0 <= begin < float("inf")) or not (
            end == 0.0 or (begin <= end < float("inf"))
        ):
            raise InvalidArgumentError(
                f"World: begin_margin {begin_margin!r} and end_margin {end_margin!r} must be "
                "finite and >= 0, with end_margin >= begin_margin (or 0: the same)"
            )
        self._c = _bpx.World(
            backend,
            simd,
            threads,
            bool(track_events),
            int(spin_us),
            int(capacity_hint),
            begin,
            end,
            period_of(cell, pbc, "World"),
            bool(profile),
        )
        self._requested = backend
        self._threads = threads
        self._track_events = bool(track_events)

    def set_pair_filter(self, fn: Any) -> None:
        """A callable ``fn(i, j, user_data_i, user_data_j) -> bool`` asked once when a pair
        would begin (``bpx_world_set_pair_filter``): False keeps it out while it persists. It
        runs on the thread that calls ``collide``, pairs in (i, j) order. It must not use this
        world (a call from inside raises ``StateError``). If it raises, that pair and the
        cycle's other new pairs are refused and ``collide`` raises the exception after the
        cycle. ``None`` removes it; setting one asks again about every pair. Cost: one walk
        over the pairs a cycle, and a Python call per pair that begins."""
        if fn is not None and not callable(fn):
            raise InvalidArgumentError(f"World.set_pair_filter: {fn!r} is not callable")
        self._c.set_pair_filter(fn)

    # -- snapshot and restore -----------------------------------------------------------------

    def snapshot(self) -> bytes:
        """The world's whole state as bytes (``bpx_world_snapshot``): boxes, extents, ids,
        filters, groups, user data, excluded pairs and the last collide's pairs, versioned and
        checksummed. A world restored from them reports the same pairs and events on its next
        collide as this one would."""
        return self._c.snapshot()

    def restore(self, data: Any) -> None:
        """Replaces the world's state with a snapshot's (``bpx_world_restore``; any bytes-like
        object). Pairs read as none until the next collide. Bytes that are not a snapshot this
        library reads (cut short, changed, another version) raise ``InvalidArgumentError``
        naming what and where, and leave the world as it was."""
        self._c.restore(data)

    # -- the updater: the paper's two phases --------------------------------------------------

    def load_extents(self, minima: Any) -> None:
        """Initialisation phase: each object's box centred at the origin, as its minimum corner,
        (n, 3) with every value <= 0 (for half-sizes h, pass -h). The world then holds n boxes,
        all at the origin until the first ``update_centres``. Leaves the general mode."""
        array, converted = vec3_array(minima, "World.load_extents: minima")
        with converted_note(converted):
            self._c.load_extents(array)

    def update_centres(self, centres: Any) -> None:
        """Updating phase: the n objects' current centres, (n, 3). C-contiguous float32 is read
        in place (12 bytes per object, the paper's per-cycle transfer)."""
        array, converted = vec3_array(centres, "World.update_centres: centres")
        with converted_note(converted):
            self._c.update_centres(array)

    # -- the general mode ---------------------------------------------------------------------

    def set_boxes(
        self,
        boxes: Any = None,
        *,
        mins: Any = None,
        maxs: Any = None,
        exact: Optional[bool] = None,
    ) -> None:
        """Replaces every box: (n, 6) or (n, 2, 3), or ``mins=`` and ``maxs=`` (n, 3). Ids
        become 0 .. n-1; an id in use below both the old and the new n keeps its filter.

        float64 boxes (and integers wider than 16 bits, up to 2^53) that float32 cannot hold
        exactly are answered exactly (``bpx_world_set_boxes64``): the comparator on the boxes
        rounded outward, each candidate decided on the doubles, so boxes one float64 ulp apart
        do not pair. The world then holds float64 boxes: ``add``, ``move`` and ``remove``,
        margins and snapshots raise StateError until boxes float32 holds are set again.
        ``exact=False`` rounds them to float32 instead (the old way: every call then works);
        ``exact=True`` takes the float64 way for float64 input even where float32 holds the
        values."""
        what = "World.set_boxes: boxes"
        if exact is False:
            array, converted = boxes_array(boxes, what, mins, maxs)
            with converted_note(converted):
                self._c.set_boxes(array)
            return
        array, f64 = boxes_array(boxes, what, mins, maxs, convert=exact_array)
        if f64 and not exact:
            with np.errstate(over="ignore", invalid="ignore"):
                narrow = array.astype(np.float32)
            if np.array_equal(narrow, array):  # float32 holds every value: nothing to lose
                array, f64 = narrow, False
        if f64:
            self._c.set_boxes64(array)
        else:
            self._c.set_boxes(np.ascontiguousarray(array, dtype=np.float32))

    def add(self, boxes: Any) -> np.ndarray:
        """Adds boxes ((k, 6) or (k, 2, 3)); returns their ids, (k,) uint32: freed ids first,
        then new ones at the end."""
        array, converted = boxes_array(boxes, "World.add: boxes")
        with converted_note(converted):
            return np.frombuffer(self._c.add_boxes(array), dtype=np.uint32)

    def remove(self, ids: Any) -> None:
        """Removes boxes by id (an int or a 1-D array). Nothing is removed when one id is not
        in use or appears twice."""
        self._c.remove_boxes(uint32_array(ids, "World.remove: ids"))

    def move(self, ids: Any, boxes: Any) -> None:
        """Gives each id in ids its new box from boxes ((k, 6) or (k, 2, 3))."""
        id_array = uint32_array(ids, "World.move: ids")
        array, converted = boxes_array(boxes, "World.move: boxes")
        with converted_note(converted):
            self._c.move_boxes(id_array, array)

    def set_filters(self, ids: Any, categories: Any, masks: Any) -> None:
        """Collision filtering inside the broad phase: a and b pair only if
        ``(category_a & mask_b) and (category_b & mask_a)``. ids (None for 0 .. k-1),
        categories and masks are uint32 values, 1-D of one length; a scalar category or mask
        applies to every id. Every box starts with category 1 and mask 0xFFFFFFFF.

        Cost: the pair test reads the two boxes' categories and masks."""
        what = "World.set_filters"
        id_array, count = _ids_and_count(ids, what, ("categories", categories), ("masks", masks))
        cats = uint32_array(categories, f"{what}: categories", count)
        mask_array = uint32_array(masks, f"{what}: masks", count)
        self._c.set_filters(id_array, cats, mask_array)

    def set_groups(self, ids: Any, groups: Any) -> None:
        """Groups (Box2D's rule): two boxes in the same non-zero group always pair when the
        group is positive and never when it is negative, whatever their categories and masks;
        boxes in different groups, or in group 0 (where every box starts), follow
        ``set_filters``' rule. Excluded pairs (``exclude_pairs``) never pair, groups or not.

        ids (None for 0 .. k-1) are uint32, groups int32 (-2**31 .. 2**31 - 1), 1-D of one
        length; a scalar group applies to every id. A group stays with its id, as a filter
        does, until the box is removed (or dropped by ``set_boxes`` / ``load_extents``).

        Cost: two reads per overlapping pair (the boxes' groups); pairs come out the same for
        any thread count.

        Raises:
            InvalidArgumentError: an id not in use (``.index``: its position in ids), a
                negative id or one above 2**32 - 1, a group out of int32's range, lengths
                that differ; DTypeError: non-integer ids or groups. Nothing changes on error.
        """
        what = "World.set_groups"
        id_array, count = _ids_and_count(ids, what, ("groups", groups))
        self._c.set_groups(id_array, int_array(groups, f"{what}: groups", np.int32, count))

    def exclude_pairs(self, pairs: Any) -> None:
        """Excluded pairs: boxes i and j never pair, whatever their groups and filters, until
        ``include_pairs``. pairs: (k, 2) integer ids, each pair of two different boxes in use;
        (i, j) and (j, i) are the same pair, and excluding one twice is the same as once.
        An exclusion goes when either box is removed (with the id's pairs, at the next
        collide) or dropped by ``set_boxes`` / ``load_extents``.

        Cost: one hash lookup per overlapping pair whose two boxes both have an exclusion;
        every other pair costs two reads. Pairs come out the same for any thread count.

        Raises:
            InvalidArgumentError: a pair with an id not in use or with i == j (``.index``:
                the pair's position), a negative id or one above 2**32 - 1, a shape other than
                (k, 2); DTypeError: non-integer ids. Nothing changes on error.
        """
        self._c.exclude_pairs(pairs_array(pairs, "World.exclude_pairs: pairs"))

    def include_pairs(self, pairs: Any) -> None:
        """Ends exclusions made by ``exclude_pairs``; a pair that is not excluded is left as it
        is. pairs and errors as ``exclude_pairs``; one hash removal per pair."""
        self._c.include_pairs(pairs_array(pairs, "World.include_pairs: pairs"))

    def pair_excluded(self, i: Any, j: Any) -> bool:
        """Whether boxes i and j are an excluded pair now (one hash lookup). False for i == j
        and for ids not in use."""
        what = "World.pair_excluded"
        return self._c.pair_excluded(_one_id(i, f"{what}: i"), _one_id(j, f"{what}: j"))

    def set_user_data(self, ids: Any, values: Any) -> None:
        """User data: a 64-bit value per box (an engine's body handle, an index into a Python
        list), 0 until set. ids (None for 0 .. k-1) are uint32, values uint64 (Python ints up
        to 2**64 - 1), 1-D of one length; a scalar value applies to every id. A value stays with
        its id, as a filter does. Cost: 8 bytes per box, allocated on first use; never read by
        the broad phase.

        Raises:
            InvalidArgumentError: an id not in use (``.index``: its position in ids), a
                negative id or value, one too big, lengths that differ; DTypeError:
                non-integer ids or values. Nothing changes on error.
        """
        what = "World.set_user_data"
        id_array, count = _ids_and_count(ids, what, ("values", values))
        self._c.set_user_data(id_array, int_array(values, f"{what}: values", np.uint64, count))

    def user_data(self, ids: Any) -> Union[int, np.ndarray]:
        """The user data of one id (an int), or of each id in a 1-D array ((k,) uint64); 0 for
        an id not in use or never set."""
        values = np.frombuffer(
            self._c.user_data(uint32_array(ids, "World.user_data: ids")), np.uint64
        )
        return int(values[0]) if np.ndim(ids) == 0 else values

    # -- comparator and emitter -----------------------------------------------------------------

    def collide(self) -> np.ndarray:
        """Finds every overlapping pair among the current boxes: a (k, 2) uint32 array of
        (i, j), i < j, sorted by (i, j), owned by the caller."""
        return pairs_from_bytes(self._c.collide())

    @property
    def pairs(self) -> np.ndarray:
        """The last collide's pairs again (a new array each time; empty after an error)."""
        return pairs_from_bytes(self._c.pairs())

    def image_pairs(self) -> Tuple[np.ndarray, np.ndarray]:
        """The last collide's pairs over every periodic image (``bpx_world_image_pairs``):
        (pairs (k, 2) uint32, shifts (k, 3) int32), sorted by (i, j, shift). Box i and box j
        moved by ``shift * cell`` overlap; a pair of boxes that meet in several images (one
        wider than half the cell) is listed once per image, and a box at least a cell wide
        meets its own images (i == j, the shift's first non-zero component positive). Without
        a cell: the pairs, with shift 0."""
        i, j, shifts = self._c.image_pairs()
        pairs = np.stack([np.frombuffer(i, np.uint32), np.frombuffer(j, np.uint32)], axis=1)
        return pairs, np.frombuffer(shifts, np.int32).reshape(-1, 3)

    @property
    def period(self) -> Tuple[float, float, float]:
        """The cell's length on each axis, 0 on open ones (a restored snapshot's cell)."""
        return self._c.period()

    @property
    def events(self) -> PairEvents:
        """(began, ended) of the last collide; needs ``track_events=True`` (else StateError).
        The first collide reports every pair as began."""
        began, ended = self._c.events()
        return PairEvents(pairs_from_bytes(began), pairs_from_bytes(ended))

    @property
    def began(self) -> np.ndarray:
        """Pairs that began with the last collide (``events.began``)."""
        return self.events.began

    @property
    def ended(self) -> np.ndarray:
        """Pairs that ended with the last collide (``events.ended``)."""
        return self.events.ended

    @property
    def stats(self) -> Stats:
        """Counts and timings of the last cycle, as a ``bpx.Stats``."""
        raw = self._c.stats()
        raw["stages"] = tuple(Stage(*stage) for stage in raw["stages"])
        return Stats(**raw)

    @property
    def backend(self) -> str:
        """The backend the last cycle ran (for "auto", its choice of that cycle)."""
        return self._c.stats()["backend"]

    @property
    def threads(self) -> int:
        """Threads working on each cycle, as asked for."""
        return self._threads

    @property
    def track_events(self) -> bool:
        return self._track_events

    # -- queries ------------------------------------------------------------------------------
    # bpx_world_query and bpx_world_query_batch (include/bpx/query.h, docs/queries.md). Each
    # method shapes its arguments into float32 rows (bpx/_query.py) and one C call runs the
    # queries with the GIL released and returns ids, fractions and CSR offsets as buffers that
    # NumPy wraps without a copy.

    def _query(
        self,
        kind: int,
        every: bool,
        any_hit: bool,
        what: str,
        columns: Tuple[np.ndarray, ...],
        category: Any,
        mask: Any,
        batch: bool,
        shared: bool = False,
        each: Optional[HitCallback] = None,
    ) -> Any:
        """Runs one query, or a batch of k, of one kind. every: every hit (always, for regions
        and spheres), else the closest; any_hit: at most one hit, the first the tree's walk
        meets. columns are its floats, side by side: (k, m) or (k,) arrays in the kind's order,
        k = 1 for one query. category and mask: a number, or with a batch (k,). shared: as one
        of the readers of a prepared world (bpx_world_query_shared); each: a callback for
        every hit (bpx_world_query_each; returns None). Returns the C layer's (ids,
        fractions), or with a batch (offsets, ids, fractions)."""
        rays = kind in (_bpx.QUERY_RAY, _bpx.QUERY_SWEEP)
        if every and any_hit and rays:
            raise InvalidArgumentError(f"{what}: all and any exclude each other")
        if each is not None:
            if not callable(each):
                raise InvalidArgumentError(f"{what}: each={each!r} is not callable")
            if any_hit or (every and rays):
                what_else = "any" if any_hit else "all"
                raise InvalidArgumentError(
                    f"{what}: each and {what_else} exclude each other (the callback decides "
                    "which hits count)"
                )
        closest = not every and not any_hit
        count = columns[0].shape[0]
        params = Params(count, sum(1 if c.ndim == 1 else c.shape[1] for c in columns))
        for column in columns:
            params.put(column)
        cat, msk = filter_arrays(category, mask, what, count if batch else None)
        with converted_note(params.overflowed):
            if each is not None:
                return self._c.query_each(kind, params.rows, cat, msk, each, bool(shared))
            if shared:
                return self._c.query_shared(kind, closest, bool(any_hit), params.rows, cat, msk)
            return self._c.query(kind, closest, bool(any_hit), params.rows, cat, msk, batch)

    def prepare_queries(self) -> None:
        """Brings the query tree up to date with the boxes (``bpx_world_prepare_queries``: a
        refit or a rebuild, as the first query after a change does), so that queries with
        ``shared=True`` may run: they read the world only, any number of Python threads at
        once, each with the GIL released (the other queries and calls take the world one
        at a time). Call it again after the boxes change (set, add, move, remove, filters,
        update_centres...): until then a shared query raises ``StateError``. A call that
        changes the world waits for the shared queries running to finish; shared queries
        that come meanwhile wait for it."""
        self._c.prepare_queries()

    def query_box(
        self,
        box: Any,
        *,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
        shared: bool = False,
        each: Optional[HitCallback] = None,
    ) -> np.ndarray:
        """Ids of the boxes that overlap a box region, sorted: (k,) uint32.

        Box b is a hit iff the closed intervals overlap on x, y and z (the pairs' predicate:
        touching counts).

        Args:
            box: (6,) [min x, y, z, max x, y, z] or (2, 3) [[min], [max]].
            any: True: at most one id, the first hit the walk of the query tree meets (is
                anything there?), not the lowest; empty exactly when the full answer is. The
                walk stops at that hit, so it costs at most what the full query costs. Which
                hit depends on the tree only: the same boxes and calls give the same one, for
                any thread count.
            category, mask: the query's filter; it sees box b iff
                ``(category & mask_b) and (category_b & mask)``, the rule between two boxes.
                The default (all ones) sees every box whose mask is not 0.
            shared: True: run on the world as ``prepare_queries`` left it, reading it only:
                any number of threads may query at once (the GIL released); StateError if
                the world was not prepared or changed since.
            each: a callable ``each(id, fraction, user_data)`` called for every hit instead
                of returning them (``bpx_world_query_each``), in the order the tree's walk
                meets them (not sorted); fraction 0.0 for regions, user_data the box's
                ``set_user_data`` value. Its return steers the walk: None or a number > 0
                goes on (for a ray or sweep a number also ends the cast there: hits entering
                later are skipped; return ``fraction`` for closer hits only), < 0 or NaN
                ignores this hit and goes on, 0 stops. It runs on the calling thread, with
                the GIL; an exception it raises stops the query and propagates; a call into
                this world from inside it raises StateError. Returns None. Not with ``any``
                (or, for rays and sweeps, ``all``).

        Raises:
            NotFiniteError, MinGreaterThanMaxError: a bad box (``.axis`` names the axis);
            InvalidArgumentError: a wrong shape, a category or mask out of 0 .. 2**32 - 1;
            StateError: a closed world, or boxes in a device buffer; with shared=True, a world
            not prepared since its last change.
        """
        what = "World.query_box"
        columns = (one_box(box, f"{what}: box"),)
        return _ids(
            self._query(
                _bpx.QUERY_BOX, True, any, what, columns, category, mask, False, shared, each
            )
        )

    def query_point(
        self,
        point: Any,
        *,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
        shared: bool = False,
        each: Optional[HitCallback] = None,
    ) -> np.ndarray:
        """Ids of the boxes that contain a point, sorted: (k,) uint32 (``bpx_query_point``:
        the box query of [point, point], closed intervals, so a point on a face is inside).

        Args:
            point: (3,).
            any, category, mask, shared, each: as in ``query_box``.
        """
        what = "World.query_point"
        columns = (one_vec3(point, f"{what}: point"),)
        return _ids(
            self._query(
                _bpx.QUERY_POINT, True, any, what, columns, category, mask, False, shared, each
            )
        )

    def query_oriented(
        self,
        centre: Any,
        half_extents: Any,
        rotation: Any,
        *,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
        shared: bool = False,
        each: Optional[HitCallback] = None,
    ) -> np.ndarray:
        """Ids of the boxes that overlap an oriented box, sorted: (k,) uint32
        (``bpx_query_oriented``).

        The query box is ``{centre + rotation @ u : |u_k| <= half_extents_k}``: the columns of
        rotation are its axes. Exactly (include/bpx/query.h): box b is a hit iff none of the
        15 axes of the separating-axis test (x, y, z, rotation's columns and their 9 cross
        products) separates the two, in double precision, touching counting as overlap.

        Args:
            centre: (3,). half_extents: (3,), each >= 0.
            rotation: (3, 3) or (9,) row-major, orthonormal to 1e-3 (e.g. scipy's
                ``Rotation.as_matrix()``).
            any, category, mask, shared, each: as in ``query_box``.

        Raises:
            NotFiniteError: a NaN or infinite value; InvalidArgumentError: negative half
            extents, a rotation that is not orthonormal, a wrong shape.
        """
        what = "World.query_oriented"
        columns = (
            one_vec3(centre, f"{what}: centre"),
            one_vec3(half_extents, f"{what}: half_extents"),
            one_rotation(rotation, f"{what}: rotation"),
        )
        return _ids(
            self._query(
                _bpx.QUERY_ORIENTED, True, any, what, columns, category, mask, False, shared, each
            )
        )

    def query_sphere(
        self,
        centre: Any,
        radius: Any,
        *,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
        shared: bool = False,
        each: Optional[HitCallback] = None,
    ) -> np.ndarray:
        """Ids of the boxes that overlap a sphere, sorted: (k,) uint32.

        Box b is a hit iff ``d2 <= radius * radius`` in double precision, where d2 sums over
        the axes ``g * g``, ``g = max(b.min - c, c - b.max, 0)`` (centre and radius as
        float32): a box the sphere touches is a hit; radius 0 is a point query.

        Args:
            centre: (3,). radius: a number >= 0.
            any, category, mask, shared, each: as in ``query_box``.

        Raises:
            NotFiniteError: a NaN or infinite centre (``.axis``) or radius;
            InvalidArgumentError: a negative radius, a wrong shape, a bad category or mask.
        """
        what = "World.query_sphere"
        columns = (one_vec3(centre, f"{what}: centre"), one_scalar(radius, f"{what}: radius"))
        return _ids(
            self._query(
                _bpx.QUERY_SPHERE, True, any, what, columns, category, mask, False, shared, each
            )
        )

    def ray_cast(
        self,
        origin: Any,
        direction: Any,
        max_fraction: Any = math.inf,
        *,
        all: bool = False,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
        shared: bool = False,
        each: Optional[HitCallback] = None,
    ) -> Union[Optional[Hit], Hits]:
        """What the ray ``origin + t * direction``, t in [0, max_fraction], hits.

        The ray is the sweep of the point box [origin, origin]; see ``sweep`` for the exact
        test. A ray that starts inside or on a box hits it at fraction 0; a ray along a face or
        an edge hits the boxes that share it. direction need not be unit length (a unit one
        makes fractions distances); a zero direction needs max_fraction 0 (a point query).

        Args:
            origin, direction: (3,) each.
            max_fraction: the largest t, >= 0; +inf (the default) for an unbounded ray, 1 for
                the segment from origin to origin + direction.
            all: False (the default): the closest hit only; True: every hit.
            any: True: some hit, the first the walk of the query tree meets, not the closest
                (a line of sight is blocked, or not): None exactly when the ray hits nothing.
                The walk stops at that hit, with no search for a closer one: the cheapest
                way to ask whether the ray hits anything. Which hit depends on the tree only:
                the same boxes and calls give the same one, for any thread count. Not with
                all=True.
            category, mask: the query's filter, as in ``query_box``.
            shared, each: as in ``query_box``; each's fraction is the hit's, and a number it
                returns ends the ray there (Box2D's ray-cast callback): ``lambda id, f, data:
                f`` keeps only closer hits coming. Not with all or any.

        Returns:
            all=False: ``Hit(id, fraction)`` with the least fraction (ties to the lowest id), or
            None when the ray hits nothing. all=True: ``Hits(ids, fractions)``, (k,) uint32 and
            (k,) float32, sorted by fraction, then id. any=True: a ``Hit`` (its own fraction)
            or None.

        Raises:
            NotFiniteError: a NaN or infinite origin or direction (``.axis``), a NaN
            max_fraction; InvalidArgumentError: a negative max_fraction, a zero direction with
            max_fraction > 0, a wrong shape, a bad category or mask, all and any together.
        """
        what = "World.ray_cast"
        columns = (
            one_vec3(origin, f"{what}: origin"),
            one_vec3(direction, f"{what}: direction"),
            one_scalar(max_fraction, f"{what}: max_fraction"),
        )
        result = self._query(
            _bpx.QUERY_RAY, all, any, what, columns, category, mask, False, shared, each
        )
        return None if each is not None else _hits(*result, bool(all))

    def sweep(
        self,
        box: Any,
        translation: Any,
        max_fraction: Any = 1.0,
        *,
        all: bool = False,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
        shared: bool = False,
        each: Optional[HitCallback] = None,
    ) -> Union[Optional[Hit], Hits]:
        """What a box q moving by ``t * translation``, t in [0, max_fraction], hits.

        Exactly (include/bpx/query.h): per axis, with d the translation's component, d == 0
        admits every t if ``b.min <= q.max and b.max >= q.min`` and no t otherwise; d != 0
        admits t between ``(b.min - q.max) * inv`` and ``(b.max - q.min) * inv``,
        ``inv = 1.0 / d``, each step in double precision. With enter the largest lower end over
        the axes and exit the smallest upper end, b is hit iff
        ``max(enter, 0) <= min(exit, max_fraction)``, at fraction ``max(enter, 0)`` rounded to
        float32. A box that starts touching b hits it at fraction 0.

        Args:
            box: the box at t = 0, (6,) or (2, 3) as in ``query_box``.
            translation: (3,); zero needs max_fraction 0.
            max_fraction: the largest t, >= 0 (default 1: the whole translation; +inf allowed).
            all, any, category, mask, shared, each: as in ``ray_cast``.

        Returns:
            As ``ray_cast``: ``Hit(id, fraction)`` or None, or with all=True ``Hits``.

        Raises:
            As ``ray_cast``, and MinGreaterThanMaxError for a box with min > max.
        """
        what = "World.sweep"
        columns = (
            one_box(box, f"{what}: box"),
            one_vec3(translation, f"{what}: translation"),
            one_scalar(max_fraction, f"{what}: max_fraction"),
        )
        result = self._query(
            _bpx.QUERY_SWEEP, all, any, what, columns, category, mask, False, shared, each
        )
        return None if each is not None else _hits(*result, bool(all))

    # Batches: many queries of one kind in one call, on the world's threads
    # (bpx_world_query_batch). Results are CSR: query k's hits are [offsets[k], offsets[k + 1])
    # of ids (and fractions), the same as k single queries would give. A bad query raises
    # naming its position in the batch (``.index``) and nothing runs.

    def query_box_batch(
        self, boxes: Any, *, any: bool = False, category: Any = ALL, mask: Any = ALL
    ) -> BatchIds:
        """``query_box`` for each of k boxes ((k, 6) or (k, 2, 3)) at once.

        any: as in ``query_box`` (0 or 1 id per query). category and mask: a number for every
        query or (k,) arrays.

        Returns:
            ``BatchIds(offsets, ids)``: query j's ids, sorted, are
            ``ids[offsets[j]:offsets[j + 1]]`` (also ``.query(j)``, ``.split()``, ``.counts``).
        """
        what = "World.query_box_batch"
        columns = (many_boxes(boxes, f"{what}: boxes"),)
        offsets, ids, _ = self._query(
            _bpx.QUERY_BOX, True, any, what, columns, category, mask, True
        )
        return BatchIds(np.frombuffer(offsets, np.intp), np.frombuffer(ids, np.uint32))

    def query_sphere_batch(
        self,
        centres: Any,
        radii: Any,
        *,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
    ) -> BatchIds:
        """``query_sphere`` for k spheres at once: centres (k, 3), radii a number or (k,);
        any as in ``query_box``; category and mask a number or (k,). Returns
        ``BatchIds(offsets, ids)`` as ``query_box_batch``."""
        what = "World.query_sphere_batch"
        centre_array = many_vec3(centres, f"{what}: centres")
        count = centre_array.shape[0]
        columns = (centre_array, many_scalars(radii, f"{what}: radii", count))
        offsets, ids, _ = self._query(
            _bpx.QUERY_SPHERE, True, any, what, columns, category, mask, True
        )
        return BatchIds(np.frombuffer(offsets, np.intp), np.frombuffer(ids, np.uint32))

    def query_point_batch(
        self, points: Any, *, any: bool = False, category: Any = ALL, mask: Any = ALL
    ) -> BatchIds:
        """``query_point`` for k points ((k, 3)) at once; any, category and mask as in
        ``query_box_batch``. Returns ``BatchIds(offsets, ids)``."""
        what = "World.query_point_batch"
        columns = (many_vec3(points, f"{what}: points"),)
        offsets, ids, _ = self._query(
            _bpx.QUERY_POINT, True, any, what, columns, category, mask, True
        )
        return BatchIds(np.frombuffer(offsets, np.intp), np.frombuffer(ids, np.uint32))

    def query_oriented_batch(
        self,
        centres: Any,
        half_extents: Any,
        rotations: Any,
        *,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
    ) -> BatchIds:
        """``query_oriented`` for k oriented boxes at once: centres (k, 3); half_extents (k, 3)
        or (3,) for all; rotations (k, 3, 3) or (k, 9), or one (3, 3) for all. any, category
        and mask as in ``query_box_batch``. Returns ``BatchIds(offsets, ids)``."""
        what = "World.query_oriented_batch"
        centre_array = many_vec3(centres, f"{what}: centres")
        count = centre_array.shape[0]
        columns = (
            centre_array,
            many_vec3(half_extents, f"{what}: half_extents", count, broadcast=True),
            many_rotations(rotations, f"{what}: rotations", count),
        )
        offsets, ids, _ = self._query(
            _bpx.QUERY_ORIENTED, True, any, what, columns, category, mask, True
        )
        return BatchIds(np.frombuffer(offsets, np.intp), np.frombuffer(ids, np.uint32))

    def ray_cast_batch(
        self,
        origins: Any,
        directions: Any,
        max_fractions: Any = math.inf,
        *,
        all: bool = False,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
    ) -> BatchHits:
        """``ray_cast`` for k rays at once: origins and directions (k, 3), max_fractions a
        number or (k,), category and mask a number or (k,); all and any as in ``ray_cast``.

        Returns:
            ``BatchHits(offsets, ids, fractions)``: ray j's hits are
            ``ids[offsets[j]:offsets[j + 1]]`` and the same slice of fractions (also
            ``.query(j)``, ``.split()``, ``.counts``). With all=False each ray has 0 or 1 hit
            (its closest, or with any=True the first found); with all=True every hit, sorted
            by fraction, then id.
        """
        what = "World.ray_cast_batch"
        origin_array = many_vec3(origins, f"{what}: origins")
        count = origin_array.shape[0]
        columns = (
            origin_array,
            many_vec3(directions, f"{what}: directions", count),
            many_scalars(max_fractions, f"{what}: max_fractions", count),
        )
        return _batch_hits(
            *self._query(_bpx.QUERY_RAY, all, any, what, columns, category, mask, True)
        )

    def sweep_batch(
        self,
        boxes: Any,
        translations: Any,
        max_fractions: Any = 1.0,
        *,
        all: bool = False,
        any: bool = False,
        category: Any = ALL,
        mask: Any = ALL,
    ) -> BatchHits:
        """``sweep`` for k boxes at once: boxes (k, 6) or (k, 2, 3), translations (k, 3),
        max_fractions a number or (k,), category and mask a number or (k,); all and any as in
        ``ray_cast``. Returns ``BatchHits(offsets, ids, fractions)`` as ``ray_cast_batch``."""
        what = "World.sweep_batch"
        box_array = many_boxes(boxes, f"{what}: boxes")
        count = box_array.shape[0]
        columns = (
            box_array,
            many_vec3(translations, f"{what}: translations", count),
            many_scalars(max_fractions, f"{what}: max_fractions", count),
        )
        return _batch_hits(
            *self._query(_bpx.QUERY_SWEEP, all, any, what, columns, category, mask, True)
        )

    @property
    def query_stats(self) -> QueryStats:
        """The query tree's builds, refits, nodes, boxes and last update's ns
        (``bpx_world_query_stats``). The first query after the boxes changed refits the tree
        when the same ids only moved and rebuilds it when ids came or went."""
        return QueryStats(**self._c.query_stats())

    # -- life -----------------------------------------------------------------------------------

    def __len__(self) -> int:
        """Boxes in the world: the highest id in use + 1 (the paper's n register)."""
        return self._c.box_count()

    @property
    def closed(self) -> bool:
        """Whether ``close()`` has run; every other call then raises StateError."""
        return self._c.closed

    def close(self) -> None:
        """Joins the world's threads and frees its memory now. Safe to call twice."""
        self._c.close()

    def __enter__(self) -> "World":
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        if self.closed:
            return "<bpx.World closed>"
        return (
            f"<bpx.World backend={self._requested!r} threads={self._threads} "
            f"boxes={len(self)} track_events={self._track_events}>"
        )


def _ids(result: Optional[tuple]) -> Optional[np.ndarray]:
    """A region query's ids as (k,) uint32, or None (each=)."""
    return None if result is None else np.frombuffer(result[0], np.uint32)


def _hits(ids: bytearray, fractions: bytearray, every: bool) -> Union[Optional[Hit], Hits]:
    id_array = np.frombuffer(ids, np.uint32)
    fraction_array = np.frombuffer(fractions, np.float32)
    if every:
        return Hits(id_array, fraction_array)
    if id_array.shape[0] == 0:
        return None
    return Hit(int(id_array[0]), float(fraction_array[0]))


def _batch_hits(offsets: bytearray, ids: bytearray, fractions: bytearray) -> BatchHits:
    return BatchHits(
        np.frombuffer(offsets, np.intp),
        np.frombuffer(ids, np.uint32),
        np.frombuffer(fractions, np.float32),
    )


def _ids_and_count(ids: Any, what: str, *columns: Tuple[str, Any]) -> Tuple[Any, int]:
    """ids as a uint32 array (None stays None, for 0 .. k-1) and k, the length every column
    must have: ids' length, else the first column given as an array."""
    if ids is not None:
        id_array = uint32_array(ids, f"{what}: ids")
        return id_array, id_array.shape[0]
    for _, values in columns:
        if np.ndim(values) != 0:
            return None, int(np.shape(values)[0])
    names = " or ".join(name for name, _ in columns)
    raise InvalidArgumentError(f"{what}: with ids None, {names} must be an array")


def _one_id(value: Any, what: str) -> int:
    """One id, checked as ``uint32_array`` checks ids."""
    if np.ndim(value) != 0:
        raise InvalidArgumentError(f"{what}: expected one id, got shape {np.shape(value)}")
    try:
        return int(uint32_array(value, what)[0])
    except InvalidArgumentError as exc:
        if isinstance(exc, DTypeError):
            raise
        raise InvalidArgumentError(f"{what} is {value}: not in 0 .. 2**32 - 1") from None
