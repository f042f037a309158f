// bpx_clscale: the opencl backend's paths at scale, one path at a time, on the scenes `bpx bench`
// uses (uniform: about one overlap per box; heavy: the heavy-tailed size mix) and two of the
// tests' (dense: each box overlaps ~10% of the others; clustered), for the scaling
// figures of docs/opencl.md. Per scene, n, path and mode it runs a few cycles on one world and
// prints the fastest cycle (wall and device clock), the median, the pairs and the bounds tests
// per box, and the least CPU time a cycle took (the process's, all threads: PoCL's workers are
// the device). The fastest cycle is the figure to quote on a shared machine: other jobs only ever
// add time. Where they take the cores for whole cycles at a time, the CPU time is the steadier
// figure: waiting for a core costs wall time but no CPU time (sharing caches still costs both).
// Every cycle's pairs are compared byte for byte with prune's. Modes:
//   host      set_boxes + collide: boxes in from the host, pairs out to the host
//   resident  bpx_opencl_collide_device + bpx_opencl_finish, the boxes in a device buffer
//             (bpx_opencl_set_boxes_buffer): only the count crosses the link; the pairs are read
//             back after the timed cycle for the check
//
//   bpx_clscale [--sizes 10000,100000,1000000] [--scene uniform,heavy,dense,clustered]
//               [--method tree,sweep,brute,auto] [--mode host,resident] [--cycles 7]
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>

#include <bpx/bpx.h>
#include <bpx/opencl.h>

#include "scenes.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

// CPU time of the whole process (every thread), in seconds.
static double cpu_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static const char *const method_names[] = {"auto", "brute", "sweep", "tree"};
static const char *const mode_names[] = {"host", "resident"};
enum { MODE_HOST, MODE_RESIDENT };

// A world of the method for the mode; for resident, the boxes go to a device buffer first.
static bpx_world *make_world(int method, int mode, const bpx_box *boxes, uint32_t n)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = BPX_BACKEND_OPENCL;
    def.opencl_method = method;
    bpx_world *world = NULL;
    if (bpx_world_create(&def, &world) != BPX_OK)
        return NULL;
    void *context = NULL;
    if (mode == MODE_RESIDENT) {
        cl_mem buffer = NULL;
        if (bpx_opencl_world_handles(world, &context, NULL, NULL) == BPX_OK)
            buffer = clCreateBuffer(context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR,
                                    sizeof(bpx_box) * (n ? n : 1), (void *)boxes, NULL);
        bpx_status st = buffer ? bpx_opencl_set_boxes_buffer(world, buffer, n) : BPX_ERR_DEVICE;
        if (buffer)
            clReleaseMemObject(buffer); // the world keeps its own reference
        if (st != BPX_OK) {
            bpx_world_destroy(world);
            return NULL;
        }
    }
    return world;
}

// One cycle in the mode, timed into *ms (wall) and *cpu_ms, then its pairs into got (read back
// from the device for resident, untimed); *count gets their number.
static bpx_status run_cycle(bpx_world *world, const bpx_box *boxes, uint32_t n, int mode,
                            double *ms, double *cpu_ms, bpx_pair *got, size_t capacity,
                            size_t *count)
{
    double t0 = now_s(), c0 = cpu_s();
    bpx_status st;
    if (mode == MODE_HOST) {
        st = bpx_world_set_boxes(world, boxes, n);
        if (st == BPX_OK)
            st = bpx_world_collide(world);
        *ms = (now_s() - t0) * 1e3;
        *cpu_ms = (cpu_s() - c0) * 1e3;
        return st == BPX_OK ? bpx_world_copy_pairs(world, got, capacity, count) : st;
    }
    st = bpx_opencl_collide_device(world);
    if (st == BPX_OK)
        st = bpx_opencl_finish(world, count);
    *ms = (now_s() - t0) * 1e3;
    *cpu_ms = (cpu_s() - c0) * 1e3;
    void *pairs = NULL, *queue = NULL;
    if (st == BPX_OK)
        st = bpx_opencl_device_pairs(world, &pairs, NULL, NULL);
    if (st == BPX_OK)
        st = bpx_opencl_world_handles(world, NULL, &queue, NULL);
    if (st == BPX_OK && *count > capacity)
        return BPX_ERR_CAPACITY;
    if (st == BPX_OK && *count &&
        clEnqueueReadBuffer(queue, pairs, CL_TRUE, 0, sizeof(bpx_pair) * *count, got, 0, NULL,
                            NULL) != CL_SUCCESS)
        st = BPX_ERR_DEVICE;
    return st;
}

// Comma-separated names or numbers into out[] (at most 16); returns the count.
static int parse_list(const char *text, int *out, const char *const *names, int name_count)
{
    int count = 0;
    char buf[256];
    snprintf(buf, sizeof buf, "%s", text);
    for (char *tok = strtok(buf, ","); tok && count < 16; tok = strtok(NULL, ",")) {
        int value = -1;
        for (int k = 0; k < name_count; k++)
            if (strcmp(tok, names[k]) == 0)
                value = k;
        if (!names)
            value = atoi(tok);
        if (value < 0) {
            fprintf(stderr, "bpx_clscale: unknown name '%s'\n", tok);
            exit(2);
        }
        out[count++] = value;
    }
    return count;
}

int main(int argc, char **argv)
{
    int sizes[16] = {10000, 100000, 1000000}, size_count = 3;
    int scenes[16] = {0, 1}, scene_count = 2;
    int methods[16] = {3}, method_count = 1;
    int modes[16] = {MODE_HOST}, mode_count = 1;
    int cycles = 7;
    static const char *const scene_names[] = {"uniform", "heavy", "dense", "clustered"};
    for (int k = 1; k + 1 < argc; k += 2) {
        if (strcmp(argv[k], "--sizes") == 0)
            size_count = parse_list(argv[k + 1], sizes, NULL, 0);
        else if (strcmp(argv[k], "--scene") == 0)
            scene_count = parse_list(argv[k + 1], scenes, scene_names, 4);
        else if (strcmp(argv[k], "--method") == 0)
            method_count = parse_list(argv[k + 1], methods, method_names, 4);
        else if (strcmp(argv[k], "--mode") == 0)
            mode_count = parse_list(argv[k + 1], modes, mode_names, 2);
        else if (strcmp(argv[k], "--cycles") == 0)
            cycles = atoi(argv[k + 1]) > 1 ? atoi(argv[k + 1]) : 2;
        else {
            fprintf(stderr,
                    "usage: bpx_clscale [--sizes N,...] [--scene uniform,heavy,dense,clustered] "
                    "[--method tree,sweep,brute,auto] [--mode host,resident] [--cycles C]\n");
            return 2;
        }
    }
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_OPENCL);
    if (!info.available) {
        printf("bpx_clscale: opencl unavailable: %s\n", info.reason ? info.reason : "?");
        return 77;
    }
    printf("opencl on %s; %d cycles per row, the first (cold) not counted\n\n", info.detail,
           cycles);
    printf(
        "| scene | n | path | pairs/box | tests/box | fastest ms | device ms | median ms | least "
        "CPU ms |\n");
    printf("|---|---:|---|---:|---:|---:|---:|---:|---:|\n");
    int failures = 0;
    for (int s = 0; s < scene_count; s++)
        for (int z = 0; z < size_count; z++) {
            uint32_t n = (uint32_t)sizes[z];
            bpx_box *boxes = malloc(sizeof(bpx_box) * (n ? n : 1));
            if (!boxes)
                return 1;
            if (scenes[s] == 1)
                scene_heavy_tailed_density(n, 1, boxes);
            else if (scenes[s] >= 2)
                scene_generate(scenes[s] == 2 ? SCENE_DENSE : SCENE_CLUSTERED, n, 1, boxes);
            else
                scene_uniform_density(n, 1.0f, 1, boxes);
            size_t want = 0;
            bpx_pair probe;
            bpx_find_pairs(boxes, n, BPX_BACKEND_PRUNE, &probe, 0, &want, NULL);
            bpx_pair *expected = malloc(sizeof(bpx_pair) * (want ? want : 1));
            bpx_pair *got = malloc(sizeof(bpx_pair) * (want ? want : 1));
            if (!expected || !got ||
                bpx_find_pairs(boxes, n, BPX_BACKEND_PRUNE, expected, want, &want, NULL) != BPX_OK)
                return 1;
            for (int m = 0; m < method_count * mode_count; m++) {
                int method = methods[m / mode_count], mode = modes[m % mode_count];
                bpx_world *world = make_world(method, mode, boxes, n);
                if (!world)
                    return 1;
                double wall[64], fastest = 1e30, device = 0, least_cpu = 1e30;
                int timed = 0;
                bpx_cycle_stats stats = {0};
                for (int c = 0; c <= cycles && c < 64; c++) {
                    double ms = 0, cpu_ms = 0;
                    size_t count = 0;
                    bpx_status st =
                        run_cycle(world, boxes, n, mode, &ms, &cpu_ms, got, want, &count);
                    if (st == BPX_ERR_CAPACITY && c == 0 && mode == MODE_RESIDENT)
                        st = run_cycle(world, boxes, n, mode, &ms, &cpu_ms, got, want,
                                       &count); // room
                    stats = bpx_world_stats(world);
                    if (st != BPX_OK || count != want ||
                        (want && memcmp(got, expected, sizeof(bpx_pair) * want) != 0)) {
                        fprintf(stderr,
                                "bpx_clscale: %s n=%u %s %s: status %s, %zu pairs, want %zu%s\n",
                                scene_names[scenes[s]], n, method_names[method], mode_names[mode],
                                bpx_status_string(st), count, want,
                                st == BPX_OK && count == want ? " (other pairs)" : "");
                        failures++;
                        break;
                    }
                    if (c == 0)
                        continue; // cold: buffers grow
                    wall[timed++] = ms;
                    least_cpu = cpu_ms < least_cpu ? cpu_ms : least_cpu;
                    if (ms < fastest) {
                        fastest = ms;
                        device = (double)stats.device_ns * 1e-6;
                    }
                }
                bpx_world_destroy(world);
                if (timed == 0)
                    continue;
                qsort(wall, (size_t)timed, sizeof *wall, compare_double);
                printf("| %s | %u | %s%s | %.2f | %.1f | %.1f | %.1f | %.1f | %.1f |\n",
                       scene_names[scenes[s]], n, method_names[method],
                       mode == MODE_RESIDENT ? ", resident" : "", (double)want / (n ? n : 1),
                       (double)stats.pair_tests / (n ? n : 1), fastest, device, wall[timed / 2],
                       least_cpu);
                fflush(stdout);
            }
            free(expected);
            free(got);
            free(boxes);
        }
    return failures ? 1 : 0;
}
