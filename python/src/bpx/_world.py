"""bpx.World: a broad phase kept between the cycles of a simulation."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple, Optional

import numpy as np

from . import _bpx
from ._arrays import boxes_array, pairs_from_bytes, uint32_array, vec3_array
from ._core import check_backend, check_threads, converted_note
from ._errors import InvalidArgumentError


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
    ``(category_a & mask_b) and (category_b & mask_a)``.

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
    ) -> None:
        backend = check_backend(backend, "World")
        threads = check_threads(threads, "World")
        if not isinstance(simd, str):
            raise InvalidArgumentError(f"World: simd must be a name (str), got {simd!r}")
        self._c = _bpx.World(
            backend, simd, threads, bool(track_events), int(spin_us), int(capacity_hint)
        )
        self._requested = backend
        self._threads = threads
        self._track_events = bool(track_events)

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

    def set_boxes(self, boxes: Any = None, *, mins: Any = None, maxs: Any = None) -> None:
        """Replaces every box: (n, 6) or (n, 2, 3), or ``mins=`` and ``maxs=`` (n, 3). Ids
        become 0 .. n-1; an id in use below both the old and the new n keeps its filter."""
        array, converted = boxes_array(boxes, "World.set_boxes: boxes", mins, maxs)
        with converted_note(converted):
            self._c.set_boxes(array)

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
        applies to every id. Every box starts with category 1 and mask 0xFFFFFFFF."""
        count: Optional[int] = None
        id_array = None
        if ids is not None:
            id_array = uint32_array(ids, "World.set_filters: ids")
            count = id_array.shape[0]
        elif np.ndim(categories) == 0 and np.ndim(masks) == 0:
            raise InvalidArgumentError(
                "World.set_filters: with ids None, categories or masks must be an array"
            )
        elif np.ndim(categories) == 0:
            count = np.shape(masks)[0]
        else:
            count = np.shape(categories)[0]
        cats = uint32_array(categories, "World.set_filters: categories", count)
        mask_array = uint32_array(masks, "World.set_filters: masks", count)
        self._c.set_filters(id_array, cats, mask_array)

    # -- comparator and emitter -----------------------------------------------------------------

    def collide(self) -> np.ndarray:
        """Finds every overlapping pair among the current boxes: a (k, 2) uint32 array of
        (i, j), i < j, sorted by (i, j), owned by the caller."""
        return pairs_from_bytes(self._c.collide())

    @property
    def pairs(self) -> np.ndarray:
        """The last collide's pairs again (a new array each time; empty after an error)."""
        return pairs_from_bytes(self._c.pairs())

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
        return Stats(**self._c.stats())

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
    # Ray casts and region queries over the world's boxes come here when the C API has them
    # (bpx_world_query_* in include/bpx/bpx.h): each as a method taking NumPy arrays and
    # returning sorted uint32 ids, through the same conversions and error mapping as above.

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
