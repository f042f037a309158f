"""Neighbour lists and exact float64 pairs: periodic cells, cutoffs, images with their shifts.

``neighbor_pairs`` is the call particle, granular and molecular codes make (every pair within a
cutoff, over a periodic cell, with the image shift and the distance); ``find_pairs`` sends
float64 and wide-integer boxes here so that they are answered exactly, not rounded to float32.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Optional, Tuple

import numpy as np

from . import _bpx
from ._errors import DTypeError, InvalidArgumentError

# bpx_input_format and bpx_metric (include/bpx/neighbors.h)
_BOXES_F32, _BOXES_F64, _POINTS_F32, _POINTS_F64 = 0, 1, 2, 3
_METRICS = {"box": 0, "euclidean": 1}
_EXACT_INTEGERS = 2**53  # integers of at most this magnitude are float64 exactly


class Neighbors(NamedTuple):
    """The pairs of ``neighbor_pairs``, sorted by (i, j, shift), each once (i < j; i == j for a
    box and its own image, the shift's first non-zero component then positive).

    Object i and the image of object j shifted by ``shifts @ cell`` (``shifts * lengths`` for
    an orthorhombic cell given as lengths) are within the cutoff: for points the vector is
    ``x[j] - x[i] + shifts @ cell``, ASE's convention. ``vectors`` (points only) is that
    vector; ``distances`` its length for points (Euclidean metric), else the metric's distance
    between the boxes.
    """

    i: np.ndarray  #: (k,) uint32
    j: np.ndarray  #: (k,) uint32
    shifts: np.ndarray  #: (k, 3) int32, 0 on open axes
    distances: Optional[np.ndarray]  #: (k,) float64, or None when not asked for
    vectors: Optional[np.ndarray]  #: (k, 3) float64, or None

    @property
    def pairs(self) -> np.ndarray:
        """(k, 2) uint32 [i, j]."""
        return np.stack([self.i, self.j], axis=1)


def exact_array(array: np.ndarray, what: str = "boxes") -> Tuple[np.ndarray, bool]:
    """The coordinates as float32 when that holds them exactly (float32, float16, integers of
    up to 16 bits), else as float64 (float64, and wider integers of at most 2^53 in
    magnitude); the bool says float64. Anything else is refused rather than rounded."""
    if array.dtype.kind not in "fiu":
        raise DTypeError(f"{what}: dtype {array.dtype} cannot hold coordinates")
    if array.dtype == np.float32 or array.dtype == np.float16 or (
        array.dtype.kind in "iu" and array.dtype.itemsize <= 2
    ):
        return np.ascontiguousarray(array, dtype=np.float32), False
    if array.dtype.kind == "f" and array.dtype.itemsize > 8:
        raise DTypeError(
            f"{what}: dtype {array.dtype} is wider than float64; convert it (rounding) yourself"
        )
    if array.dtype.kind in "iu" and array.size:
        big = (array > _EXACT_INTEGERS) | (array < -_EXACT_INTEGERS)  # integer comparisons
        if big.any():
            where = tuple(int(x) for x in np.argwhere(big)[0])
            raise InvalidArgumentError(
                f"{what}: the integer {array[where]} at index {where} is beyond 2^53, where "
                "float64 cannot hold every integer exactly"
            )
    return np.ascontiguousarray(array, dtype=np.float64), True


def period_of(cell: Any, pbc: Any, what: str) -> Tuple[float, float, float]:
    if cell is None:
        if pbc is not True and pbc is not False and np.any(pbc):
            raise InvalidArgumentError(f"{what}: pbc is set but no cell was given")
        return (0.0, 0.0, 0.0)
    lengths = np.asarray(cell, dtype=np.float64)
    if lengths.shape == (3, 3):
        if np.any(lengths[~np.eye(3, dtype=bool)] != 0):
            raise InvalidArgumentError(
                f"{what}: the cell {lengths.tolist()} is triclinic; only orthorhombic cells "
                "(a diagonal matrix, three lengths or one) are supported here (neighbor_pairs "
                "takes triclinic cells for points)"
            )
        lengths = np.diag(lengths).copy()
    elif lengths.shape == ():
        lengths = np.full(3, float(lengths))
    elif lengths.shape != (3,):
        raise InvalidArgumentError(
            f"{what}: cell must be one length, three, or a diagonal 3x3 matrix; got shape "
            f"{lengths.shape}"
        )
    periodic = np.broadcast_to(np.asarray(pbc, dtype=bool), (3,))
    period = np.where(periodic, lengths, 0.0)
    for axis in range(3):
        if periodic[axis] and not (np.isfinite(lengths[axis]) and lengths[axis] > 0):
            raise InvalidArgumentError(
                f"{what}: the cell's length on axis {'xyz'[axis]} is {lengths[axis]}; a "
                "periodic axis needs a finite length > 0"
            )
    return (float(period[0]), float(period[1]), float(period[2]))


def _complete_cell(cell: np.ndarray) -> np.ndarray:
    """Zero lattice vectors made up as ASE's ``complete_cell`` does (for open axes)."""
    cell = np.array(cell, dtype=np.float64)
    missing = np.nonzero(~cell.any(axis=1))[0]
    if len(missing) == 3:
        cell.flat[::4] = 1.0
    elif len(missing) == 2:
        V, s, WT = np.linalg.svd(cell.T)
        cell = (V @ np.diag([s[0], 1.0, 1.0]) @ WT).T
        if np.sign(np.linalg.det(cell)) < 0:
            cell[missing[0]] = -cell[missing[0]]
    elif len(missing) == 1:
        i = missing[0]
        cell[i] = np.cross(cell[i - 2], cell[i - 1])
        cell[i] /= np.linalg.norm(cell[i])
    return cell


def triclinic_of(cell: Any, pbc: Any, what: str) -> Any:
    """For a 3x3 cell that is not diagonal: ``(vectors, open)`` for the C call (zero vectors
    of open axes completed as ASE does), or ``"open"`` when no axis is periodic; None for any
    other cell (``period_of``'s)."""
    if cell is None:
        return None
    try:
        matrix = np.asarray(cell, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if matrix.shape != (3, 3) or not np.any(matrix[~np.eye(3, dtype=bool)] != 0):
        return None
    periodic = np.broadcast_to(np.asarray(pbc, dtype=bool), (3,))
    if not periodic.any():
        return "open"
    zero = ~matrix.any(axis=1)
    for axis in range(3):
        if zero[axis] and periodic[axis]:
            raise InvalidArgumentError(
                f"{what}: the cell's lattice vector {'abc'[axis]} is zero on a periodic axis"
            )
    if zero.any():
        matrix = _complete_cell(matrix)
    rows = tuple(tuple(float(v) for v in row) for row in matrix)
    return (rows[0], rows[1], rows[2], tuple(not bool(p) for p in periodic)), matrix


def _threads(threads: Optional[int], n: int) -> int:
    from ._core import _THREADED_FROM, check_threads, usable_cpus

    if threads is None:
        threads = usable_cpus() if n >= _THREADED_FROM else 1
    return check_threads(threads, "neighbor_pairs")


def neighbor_pairs(
    objects: Any,
    cutoff: float,
    cell: Any = None,
    *,
    pbc: Any = True,
    metric: Optional[str] = None,
    distances: bool = True,
    vectors: bool = False,
    backend: str = "auto",
    threads: Optional[int] = None,
) -> Neighbors:
    """Every pair of points (or boxes) within ``cutoff``, over the images of a periodic cell.

    Args:
        objects: (n, 3) points, or boxes as (n, 6) [min x, y, z, max x, y, z] or (n, 2, 3).
            float32 and float64 are read as they are (float64 answered exactly, never
            rounded to float32); integers up to 2^53.
        cutoff: the largest distance reported, finite and >= 0 (any size: past half the cell,
            a pair is reported once for each image within it).
        cell: None (no periodic axis), one length (cubic), three lengths, or a 3x3 matrix
            whose rows are the lattice vectors a, b, c (ASE's ``atoms.cell``). A diagonal
            matrix is the orthorhombic cell of its lengths; any other (triclinic) takes points
            and the Euclidean metric, either handedness, and must not be singular (condition
            number up to 2^24). The objects need not lie inside it.
        pbc: which axes are periodic, one bool or three (ASE's convention); default all, when
            a cell is given. With a triclinic cell, axis k is the lattice vector k; a zero
            vector on an open axis is completed as ASE does.
        metric: "euclidean" (default for points) or "box" (default for boxes: the largest
            gap over the axes, decided exactly on the input coordinates).
        distances, vectors: also return the distances (default) and, for points, the
            vectors from point i to the image of point j: ``x[j] - x[i] + shifts @ cell``
            (ASE's D), in the order of operations the distances were computed in.
        backend, threads: as for find_pairs.

    Returns:
        Neighbors(i, j, shifts, distances, vectors), sorted by (i, j, shift).

    Raises:
        InvalidArgumentError: a bad cell (zero, negative, NaN; triclinic with boxes, the box
            metric, or singular), cutoff or shape;
        NotFiniteError / MinGreaterThanMaxError naming the object; TooManyBoxesError when a
        cell is so small against the objects and the cutoff that their images pass
        MAX_BOXES.
    """
    what = "neighbor_pairs"
    try:
        array = np.asarray(objects)
    except (ValueError, TypeError) as exc:
        raise InvalidArgumentError(f"{what}: objects is not an array: {exc}") from None
    if array.ndim == 3 and array.shape[1:] == (2, 3):
        array = array.reshape(array.shape[0], 6)
    if array.ndim != 2 or array.shape[1] not in (3, 6):
        raise InvalidArgumentError(
            f"{what}: expected points (n, 3) or boxes (n, 6) or (n, 2, 3), got {array.shape}"
        )
    points = array.shape[1] == 3
    data, f64 = exact_array(array, what)
    if metric is None:
        metric = "euclidean" if points else "box"
    if metric not in _METRICS:
        raise InvalidArgumentError(f"{what}: metric must be 'euclidean' or 'box', got {metric!r}")
    try:
        cutoff = float(cutoff)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"{what}: cutoff must be a number, got {cutoff!r}") from None
    if vectors and not points:
        raise InvalidArgumentError(f"{what}: vectors are for points, not boxes")
    triclinic = triclinic_of(cell, pbc, what)
    cell_arg = None
    if triclinic == "open":
        period = (0.0, 0.0, 0.0)
    elif triclinic is not None:
        if not points or metric != "euclidean":
            raise InvalidArgumentError(
                f"{what}: a triclinic cell takes points (n, 3) and the Euclidean metric; boxes "
                "and the box metric need an orthorhombic cell (three lengths)"
            )
        cell_arg, matrix = triclinic
        period = (0.0, 0.0, 0.0)
    else:
        period = period_of(cell, pbc, what)
    fmt = (_POINTS_F64 if f64 else _POINTS_F32) if points else (_BOXES_F64 if f64 else _BOXES_F32)
    raw, raw_distances = _bpx.find_neighbors(
        what, data, fmt, period, cutoff, _METRICS[metric], bool(distances), False, backend,
        _threads(threads, len(data)), cell_arg,
    )
    i = np.frombuffer(raw[0], dtype=np.uint32)
    j = np.frombuffer(raw[1], dtype=np.uint32)
    shifts = np.frombuffer(raw[2], dtype=np.int32).reshape(-1, 3)
    d = np.frombuffer(raw_distances, dtype=np.float64) if distances else None
    v = None
    if vectors:
        xyz = data.astype(np.float64, copy=False)
        if cell_arg is not None:  # S_0 a + S_1 b + S_2 c, as bpx sums it
            s64 = shifts.astype(np.float64)
            image = s64[:, :1] * matrix[0] + s64[:, 1:2] * matrix[1] + s64[:, 2:] * matrix[2]
            v = (xyz[j] + image) - xyz[i]
        else:
            v = (xyz[j] + shifts * np.asarray(period)) - xyz[i]  # as bpx computes the distances
    return Neighbors(i, j, shifts, d, v)


def exact_pairs(boxes64: np.ndarray, backend: str, threads: int) -> np.ndarray:
    """find_pairs for (n, 6) float64 boxes, decided on the float64 coordinates."""
    raw, _ = _bpx.find_neighbors(
        "find_pairs", boxes64, _BOXES_F64, (0.0, 0.0, 0.0), 0.0, 0, False, True, backend,
        threads,
    )
    return np.frombuffer(raw, dtype=np.uint32).reshape(-1, 2)


def periodic_pairs(
    boxes: np.ndarray, f64: bool, cell: Any, pbc: Any, backend: str, threads: int
) -> Tuple[np.ndarray, np.ndarray]:
    """find_pairs over a periodic cell: the box metric at cutoff 0 (Algorithm 1's closed
    intervals) over every image, as pairs (k, 2) and their shifts (k, 3)."""
    period = period_of(cell, pbc, "find_pairs")
    raw, _ = _bpx.find_neighbors(
        "find_pairs", boxes, _BOXES_F64 if f64 else _BOXES_F32, period, 0.0, _METRICS["box"],
        False, False, backend, threads,
    )
    i = np.frombuffer(raw[0], dtype=np.uint32)
    j = np.frombuffer(raw[1], dtype=np.uint32)
    shifts = np.frombuffer(raw[2], dtype=np.int32).reshape(-1, 3)
    return np.stack([i, j], axis=1), shifts
