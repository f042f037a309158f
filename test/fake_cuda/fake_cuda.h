// The fake device's own calls (runtime.c), for its kernels (kernels.cu) and its tests.
// SPDX-License-Identifier: MIT
#pragma once

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/// Aborts, naming `what`, unless [p, p + bytes) lies inside one live device allocation (bytes
/// 0: no check). Every fake kernel checks each array it reads or writes this way.
void bpx_fake_cuda_require_device(const void *p, size_t bytes, const char *what);
/// After k more successful allocations (device and pinned counted together) every allocation
/// fails with cudaErrorMemoryAllocation, until called again; k < 0: none fails (the default).
void bpx_fake_cuda_fail_allocations_after(long k);
/// Device and pinned allocations alive now.
long bpx_fake_cuda_live_blocks(void);

#ifdef __cplusplus
}
#endif
