"""What World's queries return, and their arguments as the C layer takes them.

The answers are defined exactly in bpx's header (include/bpx/query.h) and in ``World``'s query
methods; this module holds the result types and the conversions: every coordinate, radius and
max_fraction goes to bpx as float32 (rounded once, like boxes), every category and mask as
uint32.
"""

from __future__ import annotations

from typing import Any, List, NamedTuple, Optional, Tuple

import numpy as np

from ._arrays import _asarray, _check_real, _no_rows, uint32_array
from ._errors import InvalidArgumentError

#: A query's category and mask when none are given: it sees every box whose mask is not 0
#: (``bpx_default_query_filter``).
ALL = 0xFFFFFFFF


class Hit(NamedTuple):
    """The closest hit of a ray or sweep: the box's id and the fraction t of first contact
    (the hit point is ``origin + t * direction``; 0 when the query starts touching the box)."""

    id: int
    fraction: float


class Hits(NamedTuple):
    """Every hit of a ray or sweep, sorted by fraction, then id: (k,) uint32 ids and (k,)
    float32 fractions."""

    ids: np.ndarray
    fractions: np.ndarray


class BatchIds(NamedTuple):
    """The hits of a batch of region or sphere queries in CSR form: query k's ids, sorted, are
    ``ids[offsets[k]:offsets[k + 1]]``. offsets is (queries + 1,) intp, ids uint32."""

    offsets: np.ndarray
    ids: np.ndarray

    @property
    def counts(self) -> np.ndarray:
        """Hits per query, (queries,) intp."""
        return np.diff(self.offsets)

    def query(self, k: int) -> np.ndarray:
        """Query k's ids (a view)."""
        return self.ids[self.offsets[k] : self.offsets[k + 1]]

    def split(self) -> List[np.ndarray]:
        """Every query's ids, as a list of views (one per query: none for no queries)."""
        if self.offsets.shape[0] <= 1:
            return []
        return np.split(self.ids, self.offsets[1:-1])


class BatchHits(NamedTuple):
    """The hits of a batch of rays or sweeps in CSR form: query k's hits are
    ``ids[offsets[k]:offsets[k + 1]]`` and the same slice of fractions, sorted by fraction,
    then id (with ``all=False``, 0 or 1 per query). offsets is (queries + 1,) intp, ids uint32,
    fractions float32."""

    offsets: np.ndarray
    ids: np.ndarray
    fractions: np.ndarray

    @property
    def counts(self) -> np.ndarray:
        """Hits per query, (queries,) intp."""
        return np.diff(self.offsets)

    def query(self, k: int) -> Hits:
        """Query k's hits (views)."""
        a, b = self.offsets[k], self.offsets[k + 1]
        return Hits(self.ids[a:b], self.fractions[a:b])

    def split(self) -> List[Hits]:
        """Every query's hits, as a list of views."""
        return [self.query(k) for k in range(self.offsets.shape[0] - 1)]


class QueryStats(NamedTuple):
    """The query tree's state (``bpx_world_query_stats``): how often it was built from scratch
    and refitted, its nodes and boxes, and the nanoseconds of the last build or refit. All 0
    before the first query."""

    builds: int
    refits: int
    nodes: int
    boxes: int
    last_update_ns: int


# -- arguments --------------------------------------------------------------------------------


class Params:
    """Builds the (k, width) float32 rows of a query kind (see csrc/_bpx.c), noting whether a
    finite value became infinite on its way to float32 (for the error message)."""

    def __init__(self, count: int, width: int) -> None:
        self.rows = np.empty((count, width), np.float32)
        self.overflowed = False
        self.column = 0

    def put(self, values: np.ndarray) -> None:
        """Writes values ((k, m) or (k,)) into the next columns."""
        width = 1 if values.ndim == 1 else values.shape[1]
        target = self.rows[:, self.column : self.column + width]
        with np.errstate(over="ignore", invalid="ignore"):
            target[...] = values.reshape(target.shape)
        if values.dtype.kind == "f" and values.dtype.itemsize > 4 and values.size:
            source = values.reshape(target.shape)
            if np.any(np.isfinite(source) & ~np.isfinite(target)):
                self.overflowed = True
        self.column += width


def _real(value: Any, what: str) -> np.ndarray:
    array = _asarray(value, what)
    _check_real(array, what, "coordinates")
    return array


def one_box(value: Any, what: str) -> np.ndarray:
    """A box as (1, 6): (6,) [min x, y, z, max x, y, z] or (2, 3) [[min], [max]]."""
    array = _real(value, what)
    if array.shape not in ((6,), (2, 3)):
        raise InvalidArgumentError(f"{what}: expected shape (6,) or (2, 3), got {array.shape}")
    return array.reshape(1, 6)


def one_vec3(value: Any, what: str) -> np.ndarray:
    array = _real(value, what)
    if array.shape != (3,):
        raise InvalidArgumentError(f"{what}: expected shape (3,), got {array.shape}")
    return array.reshape(1, 3)


def one_scalar(value: Any, what: str) -> np.ndarray:
    array = _real(value, what)
    if array.ndim != 0:
        raise InvalidArgumentError(f"{what}: expected a number, got shape {array.shape}")
    return array.reshape(1)


def many_boxes(value: Any, what: str) -> np.ndarray:
    """Boxes as (k, 6), from (k, 6) or (k, 2, 3), in their own dtype ([]: no boxes)."""
    array = _no_rows(_real(value, what), 6)
    if array.ndim == 3 and array.shape[1:] == (2, 3):
        return array.reshape(array.shape[0], 6)
    if array.ndim != 2 or array.shape[1] != 6:
        raise InvalidArgumentError(
            f"{what}: expected shape (k, 6) or (k, 2, 3), got {array.shape}"
        )
    return array


def many_vec3(
    value: Any, what: str, count: Optional[int] = None, broadcast: bool = False
) -> np.ndarray:
    """(k, 3) vectors in their own dtype ([]: none); count: the k they must have; broadcast:
    a (3,) vector stands for count copies of it."""
    array = _no_rows(_real(value, what), 3)
    if broadcast and count is not None and array.shape == (3,):
        return np.broadcast_to(array, (count, 3))
    if array.ndim != 2 or array.shape[1] != 3:
        raise InvalidArgumentError(f"{what}: expected shape (k, 3), got {array.shape}")
    if count is not None and array.shape[0] != count:
        raise InvalidArgumentError(
            f"{what}: expected shape ({count}, 3) (one per query), got {array.shape}"
        )
    return array


def one_rotation(value: Any, what: str) -> np.ndarray:
    """A rotation as (1, 9) row-major: (3, 3) or (9,)."""
    array = _real(value, what)
    if array.shape not in ((3, 3), (9,)):
        raise InvalidArgumentError(f"{what}: expected shape (3, 3) or (9,), got {array.shape}")
    return array.reshape(1, 9)


def many_rotations(value: Any, what: str, count: int) -> np.ndarray:
    """count rotations as (count, 9) row-major: (count, 3, 3) or (count, 9), or one (3, 3)
    for all."""
    array = _real(value, what)
    if array.shape == (3, 3):
        return np.broadcast_to(array.reshape(1, 9), (count, 9))
    if array.ndim == 3 and array.shape[1:] == (3, 3):
        array = array.reshape(array.shape[0], 9)
    if array.ndim != 2 or array.shape != (count, 9):
        raise InvalidArgumentError(
            f"{what}: expected shape ({count}, 3, 3) or ({count}, 9) (one per query), or "
            f"(3, 3) for all, got {array.shape}"
        )
    return array


def many_scalars(value: Any, what: str, count: int) -> np.ndarray:
    """A number for every query, or one number per query ((count,))."""
    array = _real(value, what)
    if array.ndim == 0:
        return np.broadcast_to(array, (count,))
    if array.shape != (count,):
        raise InvalidArgumentError(
            f"{what}: expected a number or shape ({count},), got {array.shape}"
        )
    return array


def filter_arrays(
    category: Any, mask: Any, what: str, count: Optional[int]
) -> Tuple[np.ndarray, np.ndarray]:
    """category and mask as uint32 arrays of 1 (for every query) or count values."""
    out = []
    for name, value in (("category", category), ("mask", mask)):
        array = uint32_array(value, f"{what}: {name}")
        if np.ndim(value) != 0 and (count is None or array.shape[0] != count):
            expected = "a number" if count is None else f"a number or shape ({count},)"
            raise InvalidArgumentError(
                f"{what}: {name}: expected {expected}, got shape {np.shape(value)}"
            )
        out.append(array)
    return out[0], out[1]
