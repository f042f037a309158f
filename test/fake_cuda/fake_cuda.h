// The fake device's own calls (memory.c, stream_order.c), for its kernels (kernels.cu) and its
// tests.
// SPDX-License-Identifier: MIT
#pragma once

#include <stddef.h>

#include <cuda_runtime_api.h>

#ifdef __cplusplus
extern "C" {
#endif

/// A fake kernel's access on `stream` to [p, p + bytes) (bytes 0: none): aborts, naming `what`,
/// unless it lies inside one live device allocation, or when it races an access in flight on a
/// stream it is not ordered with (stream_order.c); then it stays in flight until the host
/// synchronises with the stream. Every fake kernel declares each array it reads or writes so.
void bpx_fake_cuda_access(cudaStream_t stream, const void *p, size_t bytes, int write,
                          const char *what);
/// After k more successful allocations (device and pinned counted together) every allocation
/// fails with cudaErrorMemoryAllocation, until called again; k < 0: none fails (the default).
void bpx_fake_cuda_fail_allocations_after(long k);
/// Device and pinned allocations alive now.
long bpx_fake_cuda_live_blocks(void);

#ifdef __cplusplus
}
#endif
