"""The one-shot call and what the machine offers: find_pairs, backends, simd_widths."""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Iterator, List, Optional

import numpy as np

from . import _bpx
from ._arrays import boxes_array, pairs_from_bytes
from ._errors import InvalidArgumentError, NotFiniteError

MAX_BOXES: int = _bpx.MAX_BOXES
MAX_THREADS = 256

# Below this many boxes a cycle takes well under a millisecond on one core, less than starting
# and joining the threads of a one-shot world costs.
_THREADED_FROM = 16384


@dataclass(frozen=True)
class Backend:
    """A backend and whether it runs here (``bpx.backends()``)."""

    name: str
    available: bool
    reason: str  #: why not, when unavailable
    detail: str  #: e.g. "avx512, 16 lanes"


def backends() -> List[Backend]:
    """Every backend compiled into bpx's C library, in the C enum's order, with whether it can
    run on this machine (``bpx backends`` on the command line)."""
    return [Backend(*row) for row in _bpx.backends()]


def available_backends() -> List[str]:
    """Names of the backends that run here ("auto" first)."""
    return [b.name for b in backends() if b.available]


def simd_widths() -> List[tuple]:
    """(name, supported, lanes) for each SIMD width of the brute-force comparator."""
    return list(_bpx.simd_widths())


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def check_threads(threads: Any, what: str) -> int:
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)):
        raise InvalidArgumentError(f"{what}: threads must be an int, got {threads!r}")
    if not 0 <= int(threads) <= MAX_THREADS:
        raise InvalidArgumentError(f"{what}: threads is {threads}, expected 0 .. {MAX_THREADS}")
    return int(threads)


def check_backend(backend: Any, what: str) -> str:
    if not isinstance(backend, str):
        raise InvalidArgumentError(f"{what}: backend must be a name (str), got {backend!r}")
    return backend


def find_pairs(
    boxes: Any = None,
    backend: str = "auto",
    threads: Optional[int] = None,
    *,
    mins: Any = None,
    maxs: Any = None,
    cell: Any = None,
    pbc: Any = True,
    return_shifts: bool = False,
) -> Any:
    """Every overlapping pair among boxes, as a (k, 2) uint32 array sorted by (i, j), i < j.

    Boxes i and j overlap iff ``min_i <= max_j and min_j <= max_i`` on x, y and z: closed
    intervals, so touching boxes collide. The result is exact and the same bytes for every
    backend and thread count.

    Args:
        boxes: (n, 6) [min x, min y, min z, max x, max y, max z] or (n, 2, 3) [[min], [max]].
            A C-contiguous float32 array is read where it lies, without a copy. float64 (and
            integers wider than 16 bits, up to 2^53) are answered exactly on their own values:
            the float32 comparator on boxes rounded outward, then each candidate decided in
            float64, so boxes one float64 ulp apart do not pair. float16 and small integers
            are converted to float32, exactly.
        backend: "auto" (default), "reference", "brute", "prune", "sap", "grid", "model",
            "opencl", "cuda", "hybrid", "rtl" (the chip's RTL simulated, at most 512 boxes; not
            in the wheel): see ``bpx.backends()``.
        threads: threads working on the call, 1 .. 256 (0 is 1). None: every CPU this process
            may use from 16,384 boxes, one thread below (where starting threads costs more
            than they save).
        mins, maxs: instead of boxes, (n, 3) minimum and maximum corners (one copy).
        cell, pbc: a periodic cell, as for ``neighbor_pairs``: one length, three, or a diagonal
            3x3 matrix, and which axes are periodic (default all). Then box i pairs with every
            periodic image of box j that it overlaps (the same closed intervals), once per
            image: a pair appears twice when two images of j overlap i (a box longer than half
            the cell), and a box longer than the cell pairs with its own images (i == j). The
            boxes need not lie inside the cell. Exact for float32 and float64 alike.
        return_shifts: also return each pair's image shift, (k, 3) int32: box j moved by
            ``shift * cell`` overlaps box i (0 on open axes); sorted by (i, j, shift).

    Returns:
        (k, 2) uint32 array of pairs (i, j), i < j (i <= j with a cell), sorted; it owns its
        memory. With return_shifts, the tuple (pairs, shifts).

    Raises:
        NotFiniteError, MinGreaterThanMaxError: a bad box; the message names the box and axis
            (also ``.index`` and ``.axis``). Both are ValueErrors.
        InvalidArgumentError: a wrong shape; DTypeError (also a TypeError): a dtype that is not
            real numbers; UnknownBackendError, BackendUnavailableError; OutOfMemoryError.

    The GIL is released while bpx works, so other Python threads run meanwhile.
    """
    from ._neighbors import exact_array, exact_pairs

    array, f64 = boxes_array(boxes, "find_pairs: boxes", mins, maxs, convert=exact_array)
    backend = check_backend(backend, "find_pairs")
    if threads is None:
        threads = usable_cpus() if array.shape[0] >= _THREADED_FROM else 1
    threads = check_threads(threads, "find_pairs")
    if cell is not None or return_shifts:
        from ._neighbors import periodic_pairs

        pairs, shifts = periodic_pairs(array, f64, cell, pbc, backend, threads)
        return (pairs, shifts) if return_shifts else pairs
    if f64:
        return exact_pairs(array, backend, threads)
    return pairs_from_bytes(_bpx.find_pairs(array, backend, threads))


@contextmanager
def converted_note(converted: bool) -> Iterator[None]:
    """Says, in a NotFiniteError's message, that the input was converted to float32: a finite
    float64 beyond float32's range (3.4e38) becomes an infinity there."""
    try:
        yield
    except NotFiniteError as exc:
        if not converted:
            raise
        raise type(exc)(
            f"{exc} (after conversion to float32)", exc.status, exc.index, exc.axis
        ) from None
