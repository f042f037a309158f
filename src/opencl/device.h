// OpenCL platforms and devices: listing, selection from a world definition, and one context and
// built program per device, shared by every world that uses it.
#pragma once

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include "bpx/opencl.h"

/// Work-group size of the scan and radix-sort kernels (BPX_SCAN_WG; power of two).
#define BPX_CL_SCAN_WG_MAX 128u
/// Values per work-item in the scan kernels (BPX_SCAN_ITEMS in scan.cl).
#define BPX_CL_SCAN_ITEMS 8u
/// The radix sort's digit (bits per pass) and elements per work-item (kernels/sort.cl): 4 bits
/// and 8 elements (16 counts per item, in registers on a GPU), and on a CPU device 6 bits and 64
/// elements: 6 passes over the 32-bit Morton codes rather than 8, 6-7 over the pair keys of 100k
/// to 1M boxes rather than 9-10. On PoCL (2 EPYC cores) the tree's two sorts at 1M boxes took
/// 42 and 18 ms against 55 and 32 with 4 bits (fastest of 15 cycles each), and 4 and 2 ms
/// against 5 and 3 at 100k; 8 bits (256 counts per item) was slower at 100k and no faster at 1M.
/// bench/results/epyc-2c-opencl-tree/clscale_linear.md.
#define BPX_CL_RADIX_BITS 4u
#define BPX_CL_RADIX_ITEMS 8u
#define BPX_CL_RADIX_BITS_CPU 6u
#define BPX_CL_RADIX_ITEMS_CPU 64u
/// Hits a row keeps on the device before its group must compare again to emit (BPX_STASH).
#define BPX_CL_STASH 4u
/// Small sets: one work-group of up to BPX_CL_SMALL_WG_MAX items finds all pairs in one launch
/// (bpx_brute_small), its boxes in local memory (room for BPX_CL_SMALL_N), for sets of up to
/// BPX_CL_SMALL_N_GPU boxes on a GPU or accelerator (H100, NVIDIA OpenCL, per cycle against the
/// tiled kernels: 68 against 119 us at 50 boxes, 120 against 145 at 512, 265 against 187 at
/// 1000: one multiprocessor's work outgrows the launches it saves) and BPX_CL_SMALL_N_CPU on a
/// CPU device, where a work-group is one core (PoCL: 1.6x faster at 50 boxes, 1.3x at 200, 1.6x
/// slower at 300). `bpx bench --table2 --backend opencl` and `bpx bench --backend opencl --sizes
/// 256,512,1000,2000 --scene uniform`, with and without the kernel.
#define BPX_CL_SMALL_N 1024u
#define BPX_CL_SMALL_N_GPU 512u
#define BPX_CL_SMALL_N_CPU 256u
#define BPX_CL_SMALL_WG_MAX 512u

/// A device with its context and program, built once and kept for the life of the process
/// (OpenCL contexts and programs are thread-safe; command queues and kernels are per world).
typedef struct bpx_cl_device {
    cl_platform_id platform;
    cl_device_id device;
    cl_context context;
    cl_program program;
    int platform_index;
    int device_index;
    unsigned tile;        ///< comparator tile width and work-group size (the backend's m)
    unsigned scan_wg;     ///< work-group size of scans and sorts
    unsigned radix_bits;  ///< bits per radix-sort pass (BPX_RADIX_BITS)
    unsigned radix_items; ///< elements per radix-sort work-item (BPX_RADIX_ITEMS)
    unsigned small_wg;    ///< work-group size of bpx_brute_small; 0: local memory too small for it
    unsigned small_n;     ///< bpx_brute_small for sets up to this many boxes (0: never)
    bool denormals; ///< single-precision subnormals supported (else the host does the updater)
    cl_ulong global_memory;
    cl_ulong max_alloc;
    char name[96];
    char platform_name[64];
} bpx_cl_device;

/// The device a world definition selects, its program built (cached). On failure returns false
/// with a static *reason ("no OpenCL platform", "kernel build failed (log sent to the logger)",
/// ...). detail (may be NULL) gets "NAME (PLATFORM), m = TILE".
bool bpx__cl_device_get(const bpx_world_def *def, const bpx_cl_device **out, const char **reason,
                        char *detail, size_t detail_size);

/// Name of an OpenCL error code ("CL_OUT_OF_RESOURCES").
const char *bpx__cl_error_name(cl_int code);

/// Whether an OpenCL error means the device ran out of memory (CL_OUT_OF_HOST_MEMORY is the
/// host's: BPX_ERR_OUT_OF_MEMORY).
bool bpx__cl_is_memory_error(cl_int code);

/// The embedded program text (generated at build time from src/opencl/kernels/).
extern const char *const bpx__cl_sources[];
extern const size_t bpx__cl_source_sizes[];
extern const int bpx__cl_source_count;
