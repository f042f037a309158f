"""bpx: every overlapping pair of axis-aligned boxes, exact, from NumPy.

bpx finds, each cycle of a simulation, every pair of overlapping axis-aligned bounding boxes
among n objects: the broad phase of Woulfe, Dingliana & Manzke (VRIPHYS 2007), in C, with SIMD,
threads and faster algorithms (sort and sweep, a grid, temporal coherence) behind one contract:
boxes i < j overlap iff ``min_i <= max_j and min_j <= max_i`` on x, y and z (touching boxes
collide), and the pairs come back sorted by (i, j), the same from every backend.

One-shot::

    pairs = bpx.find_pairs(boxes)          # boxes (n, 6) float32 -> (k, 2) uint32

A simulation's loop::

    with bpx.World(threads=2, track_events=True) as world:
        world.load_extents(-half_sizes)    # once: boxes centred at the origin
        for step in range(steps):
            world.update_centres(centres)  # each cycle: 3 floats per object
            pairs = world.collide()
            began, ended = world.events

Queries on a world's boxes::

    world.query_box([0, 0, 0, 1, 1, 1])    # ids overlapping a region, sorted
    world.ray_cast(origin, direction)      # Hit(id, fraction) of the closest hit, or None
    world.ray_cast(origin, direction, any=True)   # some hit (the first found), or None
    world.ray_cast_batch(origins, directions, all=True)   # CSR: (offsets, ids, fractions)
    world.query_point(p); world.query_oriented(centre, half_extents, rotation)

Many Python threads on one world's queries at once (each with the GIL released)::

    world.prepare_queries()                # after the boxes change
    world.query_box(box, shared=True)      # from any number of threads

A callback per hit, that accepts, ignores or stops, and can end a ray early::

    world.ray_cast(origin, direction, each=lambda id, fraction, user_data: fraction)

Neighbour lists over a periodic cell (points or boxes, float64 exact)::

    nl = bpx.neighbor_pairs(positions, cutoff=1.2, cell=[10, 10, 10])
    nl.i, nl.j, nl.shifts, nl.distances    # pairs i < j, image shifts, distances

Filtering inside the broad phase: ``world.set_filters``, ``world.set_groups`` (Box2D's groups),
``world.exclude_pairs``; and a uint64 per box, ``world.set_user_data``.

Errors are ``bpx.Error`` subclasses (``ValueError`` for bad input, ``MemoryError`` for memory)
whose message names the box and the axis.
"""

from ._bpx import version as _c_version
from ._core import (
    MAX_BOXES,
    Backend,
    available_backends,
    backends,
    find_pairs,
    simd_widths,
)
from ._errors import (
    BackendUnavailableError,
    DeviceError,
    DeviceMemoryError,
    DTypeError,
    Error,
    InvalidArgumentError,
    InvalidBoxError,
    MinGreaterThanMaxError,
    NotFiniteError,
    OutOfMemoryError,
    StateError,
    TooManyBoxesError,
    TooManyPairsError,
    UnknownBackendError,
)
from ._neighbors import Neighbors, neighbor_pairs
from ._query import BatchHits, BatchIds, Hit, Hits, QueryStats
from ._world import PairEvents, Stage, Stats, World

__version__ = _c_version
__all__ = [
    "find_pairs",
    "neighbor_pairs",
    "Neighbors",
    "World",
    "Stats",
    "Stage",
    "PairEvents",
    "Hit",
    "Hits",
    "BatchIds",
    "BatchHits",
    "QueryStats",
    "Backend",
    "backends",
    "available_backends",
    "simd_widths",
    "MAX_BOXES",
    "Error",
    "InvalidArgumentError",
    "InvalidBoxError",
    "NotFiniteError",
    "MinGreaterThanMaxError",
    "TooManyBoxesError",
    "TooManyPairsError",
    "UnknownBackendError",
    "DTypeError",
    "BackendUnavailableError",
    "StateError",
    "OutOfMemoryError",
    "DeviceError",
    "DeviceMemoryError",
]

# Public names read as bpx.X in reprs, tracebacks and help(), not as the private module that
# defines them.
for _name in __all__:
    _obj = globals()[_name]
    if isinstance(_obj, type):
        _obj.__module__ = __name__
del _name, _obj
