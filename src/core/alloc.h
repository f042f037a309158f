// Internal memory: every allocation goes through the user's hooks and is byte-counted. Exported
// from libbpx (the double underscore says: not the public API) so that the project's own
// libraries (libbpx_mpi) allocate through the same hooks and counters.
#pragma once

#include <stddef.h>

#include "bpx/base.h"

/// Cache-line alignment used for all SoA arrays and per-block buffers.
#define BPX_ALIGN 64

/// Returns aligned memory of at least size bytes, or NULL. size 0 gives NULL.
BPX_API void *bpx__alloc(size_t size);
/// Frees memory from bpx__alloc; size must be the size it was allocated with. NULL is allowed.
BPX_API void bpx__free(void *memory, size_t size);
/// Grows *memory from old_size to new_size bytes, keeping the first old_size bytes.
/// On failure returns 0 and leaves *memory untouched.
BPX_API int bpx__grow(void **memory, size_t old_size, size_t new_size);
