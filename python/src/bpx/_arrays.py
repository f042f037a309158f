"""NumPy arrays in and out of the extension module.

Everything the C layer receives is a C-contiguous float32 or uint32 array. An array that
already is one is passed on as it is: bpx reads the caller's memory, nothing is copied. Any
other real dtype (float64, float16, integers) or layout (Fortran order, strides, a byte-swapped
dtype, a list) is converted once, with ``np.ascontiguousarray``. Rounding to float32 is
monotone, so a float64 overlap (``min_i <= max_j``) is never lost; boxes closer than float32's
resolution may pair as touching.
"""

from __future__ import annotations

from typing import Any, Callable, Optional, Tuple

import numpy as np

from ._errors import DTypeError, InvalidArgumentError

UINT32_MAX = 0xFFFFFFFF


def _asarray(value: Any, what: str) -> np.ndarray:
    try:
        array = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged lists and the like
        raise InvalidArgumentError(f"{what}: not an array: {exc}") from None
    return array


def _no_rows(array: np.ndarray, width: int) -> np.ndarray:
    """An empty 1-D array ([], np.empty(0)) as (0, width): no rows, as an empty list of pairs
    is no pairs. Anything else as it is."""
    if array.ndim == 1 and array.size == 0:
        return array.reshape(0, width)
    return array


def _check_real(array: np.ndarray, what: str, expected: str) -> None:
    if array.dtype.kind not in "fiu":
        raise DTypeError(
            f"{what}: dtype {array.dtype} cannot hold {expected}; "
            "expected float32 (other real dtypes are converted)"
        )


def as_float32(array: np.ndarray) -> Tuple[np.ndarray, bool]:
    """The array as C-contiguous native float32, and whether that took a conversion."""
    # A float64 beyond float32's range becomes an infinity, which bpx then reports naming the
    # box and axis: NumPy's overflow warning would only say it twice, without where.
    with np.errstate(over="ignore"):
        out = np.ascontiguousarray(array, dtype=np.float32)
    return out, out is not array


def boxes_array(
    boxes: Any,
    what: str = "boxes",
    mins: Any = None,
    maxs: Any = None,
    convert: Callable[[np.ndarray], Tuple[np.ndarray, bool]] = as_float32,
) -> Tuple[np.ndarray, bool]:
    """Boxes as an (n, 6) C-contiguous array [min x, y, z, max x, y, z] (bpx_box's layout) of
    what ``convert`` makes of them (float32 by default), and the bool it returns (for
    as_float32: whether the array is a converted copy).

    Takes (n, 6), (n, 2, 3) (row 0 the minimum corner), or separate (n, 3) ``mins`` and
    ``maxs`` (always one copy: the two are interleaved).
    """
    if mins is not None or maxs is not None:
        if boxes is not None:
            raise InvalidArgumentError(f"{what}: give boxes, or mins and maxs, not both")
        if mins is None or maxs is None:
            raise InvalidArgumentError(f"{what}: mins and maxs go together")
        lo = _rows_of_3(mins, "mins")
        hi = _rows_of_3(maxs, "maxs")
        if lo.shape != hi.shape:
            raise InvalidArgumentError(
                f"{what}: mins has shape {lo.shape} but maxs has shape {hi.shape}"
            )
        out, flag = convert(np.concatenate([lo, hi], axis=1))
        return out, flag or convert is as_float32
    if boxes is None:
        raise InvalidArgumentError(f"{what}: no boxes given")
    array = _no_rows(_asarray(boxes, what), 6)
    _check_real(array, what, "coordinates")
    if array.ndim == 3 and array.shape[1:] == (2, 3):
        # Made contiguous first, so that the reshape is a view and the conversion one copy.
        out, flag = convert(array)
        return out.reshape(out.shape[0], 6), flag
    if array.ndim != 2 or array.shape[1] != 6:
        raise InvalidArgumentError(
            f"{what}: expected shape (n, 6) or (n, 2, 3), got {array.shape}"
        )
    return convert(array)


def _rows_of_3(values: Any, what: str) -> np.ndarray:
    array = _no_rows(_asarray(values, what), 3)
    _check_real(array, what, "coordinates")
    if array.ndim != 2 or array.shape[1] != 3:
        raise InvalidArgumentError(f"{what}: expected shape (n, 3), got {array.shape}")
    return array


def vec3_array(values: Any, what: str) -> Tuple[np.ndarray, bool]:
    """Three floats per object (extents, centres) as (n, 3) C-contiguous float32."""
    return as_float32(_rows_of_3(values, what))


def uint32_array(values: Any, what: str, count: Optional[int] = None) -> np.ndarray:
    """Ids, categories or masks as a 1-D C-contiguous uint32 array, every value checked to fit
    (a negative id is an error naming its position, never a wrapped-around huge id). A scalar
    stands for one value, or for ``count`` copies of it when count is given."""
    return int_array(values, what, np.uint32, count)


def int_array(values: Any, what: str, dtype: Any, count: Optional[int] = None) -> np.ndarray:
    """Integers as a 1-D C-contiguous array of dtype (uint32, int32 or uint64), as
    ``uint32_array`` does for uint32: every value checked to fit, an error naming the position
    of the first that does not; a scalar stands for one value, or count copies of it."""
    info = np.iinfo(dtype)
    array = _asarray(values, what)
    if array.dtype.kind in "fO" and not isinstance(values, np.ndarray):
        array = _python_ints(values, what, info, array)
    if array.dtype.kind not in "iu":
        raise DTypeError(f"{what}: dtype {array.dtype} is not an integer dtype")
    if array.ndim == 0:
        array = np.broadcast_to(array, (1 if count is None else count,))
    if array.ndim != 1:
        raise InvalidArgumentError(f"{what}: expected a 1-D array, got shape {array.shape}")
    if array.size and array.dtype != dtype:
        if int(array.min()) < info.min or int(array.max()) > info.max:
            k = int(np.argmax((array < info.min) | (array > info.max)))
            value = int(array[k])
            raise InvalidArgumentError(
                f"{what}[{k}] is {value}: {_out_of_range(value, info)}", index=k
            )
    return np.ascontiguousarray(array, dtype=dtype)


def _out_of_range(value: int, info: Any) -> str:
    if value < 0 and info.min == 0:
        return "negative"
    if value < info.min:
        return f"below -2**{info.bits - 1}"
    return f"above 2**{info.bits - (info.min < 0)} - 1"


def _python_ints(values: Any, what: str, info: Any, array: np.ndarray) -> np.ndarray:
    """Python ints that NumPy made float64 or object (ints beyond int64, such as 2**64 - 1
    beside small ones), checked against info's range and converted exactly; array (NumPy's own
    conversion) when values are not all ints."""
    items = np.array(values, dtype=object)
    flat = items.ravel().tolist()
    if not flat:  # [] is no values, not float64 ones
        return np.zeros(items.shape, np.int64)
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in flat):
        return array
    for k, value in enumerate(flat):
        if value < info.min or value > info.max:
            place, index = "", None  # a scalar
            if items.ndim in (1, 2):
                index = k // (items.shape[1] if items.ndim == 2 else 1)  # a pair's position
                place = f"[{index}]"
            raise InvalidArgumentError(
                f"{what}{place} is {value}: {_out_of_range(value, info)}", index=index
            )
    return items.astype(np.uint64 if info.min == 0 else np.int64)


def pairs_array(pairs: Any, what: str) -> np.ndarray:
    """Pairs of ids, (k, 2), as a C-contiguous uint32 array (bpx_pair's layout), every id
    checked as ``uint32_array`` checks ids; an error names the pair's position. An empty list
    is no pairs."""
    array = _asarray(pairs, what)
    if array.size == 0 and array.ndim == 1:
        return np.empty((0, 2), np.uint32)
    if array.dtype.kind in "fO" and not isinstance(pairs, np.ndarray):
        array = _python_ints(pairs, what, np.iinfo(np.uint32), array)
    if array.dtype.kind not in "iu":
        raise DTypeError(f"{what}: dtype {array.dtype} is not an integer dtype")
    if array.ndim != 2 or array.shape[1] != 2:
        raise InvalidArgumentError(f"{what}: expected shape (k, 2), got {array.shape}")
    if array.size and array.dtype != np.uint32:
        bad = (array < 0) | (array > UINT32_MAX)
        if bad.any():
            k = int(np.argmax(bad.any(axis=1)))
            value = int(array[k][bad[k]][0])
            raise InvalidArgumentError(
                f"{what}[{k}] is {array[k].tolist()}: {value} is "
                f"{_out_of_range(value, np.iinfo(np.uint32))}",
                index=k,
            )
    return np.ascontiguousarray(array, dtype=np.uint32)


def pairs_from_bytes(data: bytearray) -> np.ndarray:
    """(k, 2) uint32 pairs over the bytearray the C layer filled: a view, no copy."""
    return np.frombuffer(data, dtype=np.uint32).reshape(-1, 2)
