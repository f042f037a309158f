// OpenCL platforms and devices: listing, selection, and the per-device context and program cache.
#include "device.h"

#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "core/log.h"

enum {
    PLATFORMS_MAX = 16,
    DEVICES_MAX = 64,
    CACHE_MAX = 16,
    TILE_MAX = 64, // comparator work-group: 64 rows, and 64 columns per tile
    OPTIONS_MAX = 512,
    LOG_CHUNK = 400, // the logger takes messages of up to 512 bytes
};

// CL_PLATFORM_NOT_FOUND_KHR (cl_khr_icd): the ICD loader found no platform at all.
#define PLATFORM_NOT_FOUND (-1001)

typedef struct cache_entry {
    bool used;
    const char *failure; // NULL: built
    cl_device_id id;
    char user_options[OPTIONS_MAX / 2 + 1]; // the world definition's opencl_build_options
    bpx_cl_device device;
} cache_entry;

static pthread_mutex_t cache_mutex = PTHREAD_MUTEX_INITIALIZER;
static cache_entry cache[CACHE_MAX];

const char *bpx__cl_error_name(cl_int code)
{
    switch (code) {
#define NAME_(c)                                                                                   \
    case c:                                                                                        \
        return #c;
        NAME_(CL_SUCCESS)
        NAME_(CL_DEVICE_NOT_FOUND)
        NAME_(CL_DEVICE_NOT_AVAILABLE)
        NAME_(CL_COMPILER_NOT_AVAILABLE)
        NAME_(CL_MEM_OBJECT_ALLOCATION_FAILURE)
        NAME_(CL_OUT_OF_RESOURCES)
        NAME_(CL_OUT_OF_HOST_MEMORY)
        NAME_(CL_PROFILING_INFO_NOT_AVAILABLE)
        NAME_(CL_BUILD_PROGRAM_FAILURE)
        NAME_(CL_MAP_FAILURE)
        NAME_(CL_INVALID_VALUE)
        NAME_(CL_INVALID_DEVICE_TYPE)
        NAME_(CL_INVALID_PLATFORM)
        NAME_(CL_INVALID_DEVICE)
        NAME_(CL_INVALID_CONTEXT)
        NAME_(CL_INVALID_COMMAND_QUEUE)
        NAME_(CL_INVALID_MEM_OBJECT)
        NAME_(CL_INVALID_BUILD_OPTIONS)
        NAME_(CL_INVALID_PROGRAM)
        NAME_(CL_INVALID_PROGRAM_EXECUTABLE)
        NAME_(CL_INVALID_KERNEL_NAME)
        NAME_(CL_INVALID_KERNEL)
        NAME_(CL_INVALID_ARG_INDEX)
        NAME_(CL_INVALID_ARG_VALUE)
        NAME_(CL_INVALID_ARG_SIZE)
        NAME_(CL_INVALID_KERNEL_ARGS)
        NAME_(CL_INVALID_WORK_DIMENSION)
        NAME_(CL_INVALID_WORK_GROUP_SIZE)
        NAME_(CL_INVALID_WORK_ITEM_SIZE)
        NAME_(CL_INVALID_GLOBAL_OFFSET)
        NAME_(CL_INVALID_EVENT_WAIT_LIST)
        NAME_(CL_INVALID_EVENT)
        NAME_(CL_INVALID_OPERATION)
        NAME_(CL_INVALID_BUFFER_SIZE)
        NAME_(CL_INVALID_GLOBAL_WORK_SIZE)
#undef NAME_
    case PLATFORM_NOT_FOUND:
        return "CL_PLATFORM_NOT_FOUND_KHR";
    default:
        return "CL_UNKNOWN_ERROR";
    }
}

bool bpx__cl_is_memory_error(cl_int code)
{
    return code == CL_MEM_OBJECT_ALLOCATION_FAILURE || code == CL_OUT_OF_RESOURCES ||
           code == CL_INVALID_BUFFER_SIZE;
}

// Platforms in clGetPlatformIDs order; 0 when there is none (or the loader fails).
static cl_uint list_platforms(cl_platform_id *out)
{
    cl_uint count = 0;
    if (clGetPlatformIDs(PLATFORMS_MAX, out, &count) != CL_SUCCESS)
        return 0;
    return count < PLATFORMS_MAX ? count : PLATFORMS_MAX;
}

static cl_uint list_devices(cl_platform_id platform, cl_device_id *out)
{
    cl_uint count = 0;
    if (clGetDeviceIDs(platform, CL_DEVICE_TYPE_ALL, DEVICES_MAX, out, &count) != CL_SUCCESS)
        return 0;
    return count < DEVICES_MAX ? count : DEVICES_MAX;
}

static int type_mask(cl_device_id device)
{
    cl_device_type type = 0;
    clGetDeviceInfo(device, CL_DEVICE_TYPE, sizeof type, &type, NULL);
    return (type & CL_DEVICE_TYPE_GPU)           ? BPX_OPENCL_GPU
           : (type & CL_DEVICE_TYPE_ACCELERATOR) ? BPX_OPENCL_ACCELERATOR
           : (type & CL_DEVICE_TYPE_CPU)         ? BPX_OPENCL_CPU
                                                 : 0;
}

// Preference among allowed devices: GPU, then accelerator, then CPU, then anything else.
static int rank(int type)
{
    return type == BPX_OPENCL_GPU ? 0 : type == BPX_OPENCL_ACCELERATOR ? 1 : type ? 2 : 3;
}

static void info_string(cl_device_id device, cl_device_info what, char *out, size_t size)
{
    char whole[512]; // the query fails when the buffer is too small: read all, then cut
    out[0] = '\0';
    if (clGetDeviceInfo(device, what, sizeof whole, whole, NULL) != CL_SUCCESS)
        return;
    whole[sizeof whole - 1] = '\0';
    size_t length = strlen(whole);
    length = length < size ? length : size - 1;
    memcpy(out, whole, length);
    out[length] = '\0';
}

// Options that would let the compiler change what a comparison or the updater's add decides.
static bool options_refused(const char *options)
{
    static const char *const refused[] = {"-cl-fast-relaxed-math", "-cl-mad-enable",
                                          "-cl-unsafe-math-optimizations", "-cl-denorms-are-zero",
                                          "-cl-finite-math-only"};
    for (size_t k = 0; k < sizeof refused / sizeof refused[0]; k++)
        if (options && strstr(options, refused[k]))
            return true;
    return false;
}

static void log_build_failure(const bpx_cl_device *d, cl_program program, cl_int code)
{
    bpx__log(0, "opencl: kernel build failed on %s (%s), %s; build log follows", d->name,
             d->platform_name, bpx__cl_error_name(code));
    size_t size = 0;
    if (clGetProgramBuildInfo(program, d->device, CL_PROGRAM_BUILD_LOG, 0, NULL, &size) !=
            CL_SUCCESS ||
        size == 0)
        return;
    // The log is read in pieces into a stack buffer: no allocation on this path.
    char chunk[LOG_CHUNK + 1];
    char whole[8192];
    if (size > sizeof whole)
        size = sizeof whole;
    if (clGetProgramBuildInfo(program, d->device, CL_PROGRAM_BUILD_LOG, size, whole, NULL) !=
        CL_SUCCESS)
        return;
    whole[size - 1] = '\0';
    size_t length = strlen(whole);
    for (size_t at = 0; at < length; at += LOG_CHUNK) {
        size_t piece = length - at < LOG_CHUNK ? length - at : LOG_CHUNK;
        memcpy(chunk, whole + at, piece);
        chunk[piece] = '\0';
        bpx__log(0, "opencl build log: %s", chunk);
    }
}

// Makes the context and builds the program for entry e (cache mutex held).
static const char *build(cache_entry *e, cl_platform_id platform, int platform_index,
                         int device_index, const char *user_options)
{
    bpx_cl_device *d = &e->device;
    cl_device_id device = e->id;
    *d = (bpx_cl_device){.platform = platform,
                         .device = device,
                         .platform_index = platform_index,
                         .device_index = device_index};
    info_string(device, CL_DEVICE_NAME, d->name, sizeof d->name);
    char platform_name[sizeof d->platform_name] = "";
    if (clGetPlatformInfo(platform, CL_PLATFORM_NAME, sizeof platform_name, platform_name, NULL) ==
        CL_SUCCESS)
        memcpy(d->platform_name, platform_name, sizeof platform_name);
    d->platform_name[sizeof d->platform_name - 1] = '\0';

    size_t max_group = 1;
    cl_device_fp_config fp = 0;
    clGetDeviceInfo(device, CL_DEVICE_MAX_WORK_GROUP_SIZE, sizeof max_group, &max_group, NULL);
    clGetDeviceInfo(device, CL_DEVICE_SINGLE_FP_CONFIG, sizeof fp, &fp, NULL);
    clGetDeviceInfo(device, CL_DEVICE_GLOBAL_MEM_SIZE, sizeof d->global_memory, &d->global_memory,
                    NULL);
    clGetDeviceInfo(device, CL_DEVICE_MAX_MEM_ALLOC_SIZE, sizeof d->max_alloc, &d->max_alloc, NULL);
    d->denormals = (fp & CL_FP_DENORM) != 0;
    d->tile = TILE_MAX;
    while (d->tile > 1 && d->tile > max_group)
        d->tile /= 2;
    d->scan_wg = BPX_CL_SCAN_WG_MAX;
    while (d->scan_wg > 16 && d->scan_wg > max_group)
        d->scan_wg /= 2;
    if (d->scan_wg > max_group || d->max_alloc == 0)
        return "device work-groups too small for the kernels";
    bool cpu = type_mask(device) == BPX_OPENCL_CPU;
    d->radix_bits = cpu ? BPX_CL_RADIX_BITS_CPU : BPX_CL_RADIX_BITS;
    d->radix_items = cpu ? BPX_CL_RADIX_ITEMS_CPU : BPX_CL_RADIX_ITEMS;
    // bpx_brute_small keeps six key planes, the row offsets and the scan's parts in local memory.
    cl_ulong local_memory = 0;
    clGetDeviceInfo(device, CL_DEVICE_LOCAL_MEM_SIZE, sizeof local_memory, &local_memory, NULL);
    d->small_wg = BPX_CL_SMALL_WG_MAX;
    while (d->small_wg > 32 && d->small_wg > max_group)
        d->small_wg /= 2;
    if (d->small_wg > max_group ||
        local_memory < 7 * BPX_CL_SMALL_N * sizeof(cl_uint) + d->small_wg * sizeof(cl_ulong) + 1024)
        d->small_wg = 0;
    d->small_n = d->small_wg == 0 ? 0 : cpu ? BPX_CL_SMALL_N_CPU : BPX_CL_SMALL_N_GPU;

    cl_int err;
    d->context = clCreateContext(NULL, 1, &device, NULL, NULL, &err);
    if (!d->context) {
        bpx__log(0, "opencl: clCreateContext on %s: %s", d->name, bpx__cl_error_name(err));
        return "OpenCL context creation failed";
    }
    d->program =
        clCreateProgramWithSource(d->context, (cl_uint)bpx__cl_source_count,
                                  (const char **)bpx__cl_sources, bpx__cl_source_sizes, &err);
    if (!d->program) {
        bpx__log(0, "opencl: clCreateProgramWithSource: %s", bpx__cl_error_name(err));
        clReleaseContext(d->context);
        return "OpenCL program creation failed";
    }
    char options[OPTIONS_MAX];
    snprintf(options, sizeof options,
             "-cl-std=CL1.2 -DBPX_TILE=%u -DBPX_SCAN_WG=%u -DBPX_STASH=%u -DBPX_SMALL_N=%u "
             "-DBPX_SMALL_WG=%u -DBPX_RADIX_BITS=%u -DBPX_RADIX_ITEMS=%u %s",
             d->tile, d->scan_wg, BPX_CL_STASH, BPX_CL_SMALL_N, d->small_wg ? d->small_wg : 32u,
             d->radix_bits, d->radix_items, user_options);
    err = clBuildProgram(d->program, 1, &device, options, NULL, NULL);
    if (err != CL_SUCCESS) {
        log_build_failure(d, d->program, err);
        clReleaseProgram(d->program);
        clReleaseContext(d->context);
        d->program = NULL;
        d->context = NULL;
        return "kernel build failed (build log sent to the logger)";
    }
    return NULL;
}

bool bpx__cl_device_get(const bpx_world_def *def, const bpx_cl_device **out, const char **reason,
                        char *detail, size_t detail_size)
{
    *out = NULL;
    if (def->opencl_platform < 0 || def->opencl_device < 0 ||
        (def->opencl_device_type & ~(BPX_OPENCL_GPU | BPX_OPENCL_CPU | BPX_OPENCL_ACCELERATOR)) ||
        def->opencl_method < BPX_OPENCL_AUTO || def->opencl_method > BPX_OPENCL_TREE) {
        *reason = "bad opencl_* field in the world definition";
        return false;
    }
    const char *user_options = def->opencl_build_options ? def->opencl_build_options : "";
    if (options_refused(user_options) || strlen(user_options) > OPTIONS_MAX / 2) {
        *reason = "opencl_build_options refused (fast-math options, or too long)";
        return false;
    }

    pthread_mutex_lock(&cache_mutex);
    cl_platform_id platforms[PLATFORMS_MAX];
    cl_uint platform_count = list_platforms(platforms);
    cl_platform_id best_platform = NULL;
    cl_device_id best = NULL;
    int best_rank = 99, best_p = -1, best_d = -1;
    for (cl_uint p = 0; p < platform_count; p++) {
        if (def->opencl_platform && (cl_uint)def->opencl_platform - 1 != p)
            continue;
        cl_device_id devices[DEVICES_MAX];
        cl_uint device_count = list_devices(platforms[p], devices);
        for (cl_uint k = 0; k < device_count; k++) {
            if (def->opencl_device && (cl_uint)def->opencl_device - 1 != k)
                continue;
            int type = type_mask(devices[k]);
            if (def->opencl_device_type && !(def->opencl_device_type & type))
                continue;
            cl_bool available = CL_FALSE, compiler = CL_FALSE;
            clGetDeviceInfo(devices[k], CL_DEVICE_AVAILABLE, sizeof available, &available, NULL);
            clGetDeviceInfo(devices[k], CL_DEVICE_COMPILER_AVAILABLE, sizeof compiler, &compiler,
                            NULL);
            if (!available || !compiler || rank(type) >= best_rank)
                continue;
            best_rank = rank(type);
            best = devices[k];
            best_platform = platforms[p];
            best_p = (int)p;
            best_d = (int)k;
        }
    }
    const char *failure = NULL;
    cache_entry *entry = NULL;
    if (platform_count == 0) {
        failure = "no OpenCL platform";
    } else if (def->opencl_platform && (cl_uint)def->opencl_platform > platform_count) {
        failure = "no OpenCL platform with that number";
    } else if (!best) {
        failure = "no usable OpenCL device matches the selection";
    } else {
        for (int k = 0; k < CACHE_MAX && !entry; k++)
            if (cache[k].used && cache[k].id == best &&
                strcmp(cache[k].user_options, user_options) == 0)
                entry = &cache[k]; // built before, or failed before (fails fast again)
        for (int k = 0; k < CACHE_MAX && !entry; k++)
            if (!cache[k].used) {
                entry = &cache[k];
                *entry = (cache_entry){.used = true, .id = best};
                snprintf(entry->user_options, sizeof entry->user_options, "%s", user_options);
                entry->failure = build(entry, best_platform, best_p, best_d, user_options);
            }
        if (!entry)
            failure = "too many OpenCL device configurations in one process";
        else
            failure = entry->failure;
    }
    pthread_mutex_unlock(&cache_mutex);
    if (failure) {
        *reason = failure;
        return false;
    }
    *reason = "";
    *out = &entry->device;
    if (detail && detail_size)
        snprintf(detail, detail_size, "%.60s, device %d:%d, m = %u", entry->device.name,
                 entry->device.platform_index, entry->device.device_index, entry->device.tile);
    return true;
}

bpx_status bpx_opencl_devices(bpx_opencl_device *out, int capacity, int *count)
{
    if (!count || (!out && capacity > 0))
        return BPX_ERR_NULL_ARGUMENT;
    *count = 0;
    cl_platform_id platforms[PLATFORMS_MAX];
    cl_uint platform_count = list_platforms(platforms);
    if (platform_count == 0)
        return BPX_ERR_BACKEND_UNAVAILABLE;
    int total = 0;
    for (cl_uint p = 0; p < platform_count; p++) {
        char platform_name[64] = "";
        clGetPlatformInfo(platforms[p], CL_PLATFORM_NAME, sizeof platform_name, platform_name,
                          NULL);
        platform_name[sizeof platform_name - 1] = '\0';
        cl_device_id devices[DEVICES_MAX];
        cl_uint device_count = list_devices(platforms[p], devices);
        for (cl_uint k = 0; k < device_count; k++, total++) {
            if (total >= capacity)
                continue;
            bpx_opencl_device *d = &out[total];
            *d = (bpx_opencl_device){
                .platform = (int)p, .device = (int)k, .type = type_mask(devices[k])};
            cl_uint units = 0;
            cl_ulong memory = 0;
            clGetDeviceInfo(devices[k], CL_DEVICE_MAX_COMPUTE_UNITS, sizeof units, &units, NULL);
            clGetDeviceInfo(devices[k], CL_DEVICE_GLOBAL_MEM_SIZE, sizeof memory, &memory, NULL);
            d->compute_units = (int)units;
            d->global_memory = memory;
            memcpy(d->platform_name, platform_name, sizeof platform_name);
            info_string(devices[k], CL_DEVICE_NAME, d->name, sizeof d->name);
            info_string(devices[k], CL_DEVICE_VERSION, d->version, sizeof d->version);
        }
    }
    *count = total;
    return BPX_OK;
}
