// bpx: broad-phase collision detection. SPDX-License-Identifier: MIT
//
// Base definitions: export macro, version, status codes, allocator and logger hooks.
#pragma once

#include <stddef.h>
#include <stdint.h>

#if defined(BPX_STATIC_DEFINE)
#define BPX_API
#elif defined(_WIN32)
#if defined(BPX_BUILDING)
#define BPX_API __declspec(dllexport)
#else
#define BPX_API __declspec(dllimport)
#endif
#elif defined(__GNUC__)
#define BPX_API __attribute__((visibility("default")))
#else
#define BPX_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define BPX_VERSION_MAJOR 0
#define BPX_VERSION_MINOR 1
#define BPX_VERSION_PATCH 0

/// Library version as "major.minor.patch" (static string).
BPX_API const char *bpx_version(void);

/// Every status code, defined once: the enum and bpx_status_string() both come from this list.
///
/// Error policy: no bpx function crashes, aborts, exits or leaks on bad input. Each validates its
/// arguments and data before changing any state and returns the first problem it finds as a
/// status. A world keeps a message naming what and where (box index, axis, value) for its last
/// error, readable with bpx_world_error(); one-shot calls fill an optional bpx_error.
#define BPX_STATUS_LIST(X)                                                                         \
    X(BPX_OK, "ok")                                                                                \
    X(BPX_ERR_NULL_ARGUMENT, "a required pointer argument is null")                                \
    X(BPX_ERR_INVALID_ARGUMENT, "an argument is out of its documented range")                      \
    X(BPX_ERR_NOT_FINITE, "a coordinate is NaN or infinite")                                       \
    X(BPX_ERR_MIN_GREATER_THAN_MAX, "a box has min > max on some axis")                            \
    X(BPX_ERR_TOO_MANY_BOXES, "box count exceeds BPX_MAX_BOXES")                                   \
    X(BPX_ERR_OUT_OF_MEMORY, "memory allocation failed")                                           \
    X(BPX_ERR_CAPACITY, "the output buffer is too small; the needed count was reported")           \
    X(BPX_ERR_UNKNOWN_BACKEND, "no backend has that name")                                         \
    X(BPX_ERR_BACKEND_UNAVAILABLE, "the backend is not compiled in or not supported here")         \
    X(BPX_ERR_BAD_STATE, "the call is not valid in the world's current state")                     \
    X(BPX_ERR_DEVICE, "the compute device failed (driver error, kernel build, lost device)")       \
    X(BPX_ERR_DEVICE_MEMORY, "the device is out of memory, or opencl_memory_limit is too low")  \
    X(BPX_ERR_TOO_MANY_PAIRS, "the pair set exceeds the 2^32 - 1 pairs this backend indexes")

typedef enum bpx_status {
#define BPX_STATUS_ENUM_(name, text) name,
    BPX_STATUS_LIST(BPX_STATUS_ENUM_)
#undef BPX_STATUS_ENUM_
    BPX_STATUS_COUNT
} bpx_status;

/// Short static English text for a status ("ok", "a coordinate is NaN or infinite", ...).
/// Unknown values give "unknown status".
BPX_API const char *bpx_status_string(bpx_status status);

/// Symbolic name of a status ("BPX_ERR_NOT_FINITE"), for logs and tests.
BPX_API const char *bpx_status_name(bpx_status status);

/// Allocator hooks. alloc returns memory aligned to at least `alignment` (a power of two, at most
/// 4096) or NULL; free releases it. Both must be thread-safe. Set them before creating any world;
/// NULL restores the default (aligned_alloc/free).
typedef void *bpx_alloc_fn(size_t size, size_t alignment, void *user);
typedef void bpx_free_fn(void *memory, void *user);
BPX_API void bpx_set_allocator(bpx_alloc_fn *alloc, bpx_free_fn *free_fn, void *user);

/// Bytes currently allocated by the library, over all worlds (for leak checks and budgets).
BPX_API int64_t bpx_allocated_bytes(void);

/// The most bytes allocated by the library at once since the last bpx_reset_allocated_peak (or
/// since the start), over all worlds: a world's peak memory is this minus what was allocated
/// before it was made.
BPX_API int64_t bpx_allocated_peak(void);
/// Starts a new peak from what is allocated now.
BPX_API void bpx_reset_allocated_peak(void);

/// Log hook: the library reports rare events (backend fallbacks, device build logs) here.
/// Default: silent. level 0 = error, 1 = warning, 2 = info.
typedef void bpx_log_fn(int level, const char *message, void *user);
BPX_API void bpx_set_logger(bpx_log_fn *log, void *user);

#ifdef __cplusplus
}
#endif
