"""bpx's exceptions: one class per kind of C status, under bpx.Error.

Each class that has a builtin counterpart derives from it too, so ``except ValueError`` catches
a bad box and ``except MemoryError`` an allocation failure, as a NumPy user expects.
"""

from __future__ import annotations

from typing import Optional

__all__ = [
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


class Error(Exception):
    """Any error bpx reports.

    Attributes:
        status: the C status name, e.g. ``"BPX_ERR_NOT_FINITE"``.
        index: the first offending box (or the position in an ids list, or the query's
            position in a batch), or None.
        axis: 0, 1 or 2 for x, y, z where an axis is involved, else None.
    """

    def __init__(
        self,
        message: str,
        status: str = "BPX_ERR_INVALID_ARGUMENT",
        index: Optional[int] = None,
        axis: Optional[int] = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.index = index
        self.axis = axis


class InvalidArgumentError(Error, ValueError):
    """An argument out of its documented range: a shape, a length, an id not in use."""


class InvalidBoxError(InvalidArgumentError):
    """A box, extent or centre, or a query's box, centre, origin or direction, that bpx
    refuses; ``index`` and ``axis`` say which."""


class NotFiniteError(InvalidBoxError):
    """A coordinate is NaN or infinite (BPX_ERR_NOT_FINITE)."""


class MinGreaterThanMaxError(InvalidBoxError):
    """A box has min > max on some axis, or an extent's minimum is > 0."""


class TooManyBoxesError(InvalidArgumentError):
    """More boxes than bpx.MAX_BOXES."""


class UnknownBackendError(InvalidArgumentError):
    """No backend has that name (see bpx.backends())."""


class DTypeError(InvalidArgumentError, TypeError):
    """An array whose dtype cannot stand for coordinates or ids (complex, bool, object, ...)."""


class BackendUnavailableError(Error, RuntimeError):
    """The backend or SIMD width is not compiled in or not supported on this machine."""


class StateError(Error, RuntimeError):
    """The call is not valid in the world's current state (e.g. update_centres before
    load_extents, events without track_events, a closed world)."""


class OutOfMemoryError(Error, MemoryError):
    """bpx could not allocate memory; the world is as it was before the call."""


class TooManyPairsError(Error, OverflowError):
    """More pairs than can be returned (BPX_ERR_TOO_MANY_PAIRS): past what the backend can
    count (2^32 - 1 pairs for prune, sap, grid and opencl's sweep; brute and reference count
    further), or past what one array can hold (PY_SSIZE_T_MAX bytes, 8 a pair: reachable on
    32-bit hosts only). Raised once the count is known, before the pairs' memory is
    allocated, rather than a MemoryError after."""


class DeviceError(Error, RuntimeError):
    """The compute device failed (driver error, kernel build, lost device)."""


class DeviceMemoryError(DeviceError, MemoryError):
    """The device is out of memory."""


_BY_STATUS = {
    "BPX_ERR_NULL_ARGUMENT": InvalidArgumentError,
    "BPX_ERR_INVALID_ARGUMENT": InvalidArgumentError,
    "BPX_ERR_NOT_FINITE": NotFiniteError,
    "BPX_ERR_MIN_GREATER_THAN_MAX": MinGreaterThanMaxError,
    "BPX_ERR_TOO_MANY_BOXES": TooManyBoxesError,
    "BPX_ERR_OUT_OF_MEMORY": OutOfMemoryError,
    "BPX_ERR_UNKNOWN_BACKEND": UnknownBackendError,
    "BPX_ERR_BACKEND_UNAVAILABLE": BackendUnavailableError,
    "BPX_ERR_BAD_STATE": StateError,
    "BPX_ERR_DEVICE": DeviceError,
    "BPX_ERR_DEVICE_MEMORY": DeviceMemoryError,
    "BPX_ERR_TOO_MANY_PAIRS": TooManyPairsError,
}


def _from_status(status: str, index: Optional[int], axis: Optional[int], message: str) -> Error:
    """The exception for a C status; the extension module calls this on every error."""
    cls = _BY_STATUS.get(status, Error)
    return cls(message, status, index, axis)
