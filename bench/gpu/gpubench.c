// bpx_gpubench: the cuda backend against the host's grid on all its threads, side by side in one
// run, on the uniform scene that `bpx bench` uses (about one overlap per box, every box moving
// 5% of its size per cycle). Per n it times:
//   cuda resident  bpx_cuda_collide_device + bpx_cuda_finish, boxes already in device memory
//                  (moved on the host and copied in between cycles, untimed), pairs left there
//   cuda host      bpx_world_set_boxes + bpx_world_collide: boxes in, pairs out over the link
//   grid Nt        bpx_world_set_boxes + bpx_world_collide on every hardware thread
// and checks that all three give the same pairs. Prints a markdown table; --csv FILE adds CSV.
// First it measures the link: 24 MB in from pageable and from pinned memory, and out.
//
//   bpx_gpubench [--sizes 500,1000000] [--seconds S] [--csv FILE]
#define _POSIX_C_SOURCE 200809L
#include <cuda_runtime_api.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <bpx/bpx.h>
#include <bpx/cuda.h>

#include "scenes.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

typedef struct timing {
    double mean_ms, median_ms, min_ms;
    int cycles;
    size_t pairs;
    bool exact;
} timing;

static timing summarise(double *ms, int cycles)
{
    timing t = {0};
    t.cycles = cycles;
    double sum = 0;
    for (int k = 0; k < cycles; k++)
        sum += ms[k];
    qsort(ms, (size_t)cycles, sizeof *ms, compare_double);
    t.mean_ms = cycles ? sum / cycles : 0;
    t.median_ms = cycles ? ms[cycles / 2] : 0;
    t.min_ms = cycles ? ms[0] : 0;
    return t;
}

static bpx_world *make_world(bpx_backend backend, int threads)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = backend;
    def.worker_count = threads;
    bpx_world *w = NULL;
    if (bpx_world_create(&def, &w) != BPX_OK) {
        fprintf(stderr, "bpx_gpubench: cannot create a %s world\n", bpx_backend_name(backend));
        exit(1);
    }
    return w;
}

// Device failures name the CUDA call and error only through the logger.
static void print_log(int level, const char *message, void *user)
{
    (void)user;
    if (level <= 1)
        fprintf(stderr, "bpx log: %s\n", message);
}

static bool check(bpx_status s, bpx_world *w, const char *what)
{
    if (s == BPX_OK)
        return true;
    fprintf(stderr, "bpx_gpubench: %s: %s (%s)\n", what, bpx_status_name(s),
            bpx_world_error(w)->message);
    return false;
}

// The link as the host path meets it: `bytes` copied in from pageable memory (what a host cycle
// sends from the world's arrays above 65536 boxes) and from pinned memory (what it could send
// were those arrays page-locked), and out to pageable memory (where the pairs land), in GB/s,
// the best of 5 copies each. Tells whether the host path's time is the link's or the copies'.
static void print_link(size_t bytes)
{
    void *device = NULL, *pinned = NULL;
    char *pageable = malloc(bytes);
    if (!pageable || cudaMalloc(&device, bytes) != cudaSuccess ||
        cudaMallocHost(&pinned, bytes) != cudaSuccess) {
        printf("link: no memory for the probe\n\n");
        free(pageable), cudaFree(device), cudaFreeHost(pinned);
        return;
    }
    memset(pageable, 1, bytes); // touched: no page faults inside the copies
    memset(pinned, 1, bytes);
    double best[3] = {1e30, 1e30, 1e30};
    for (int k = 0; k < 5; k++) {
        double t0 = now_s();
        cudaMemcpy(device, pageable, bytes, cudaMemcpyHostToDevice);
        cudaDeviceSynchronize();
        double t1 = now_s();
        cudaMemcpy(device, pinned, bytes, cudaMemcpyHostToDevice);
        cudaDeviceSynchronize();
        double t2 = now_s();
        cudaMemcpy(pageable, device, bytes, cudaMemcpyDeviceToHost);
        double t3 = now_s();
        double took[3] = {t1 - t0, t2 - t1, t3 - t2};
        for (int v = 0; v < 3; v++)
            best[v] = took[v] < best[v] ? took[v] : best[v];
    }
    printf("link, %zu MB (best of 5): in from pageable %.1f GB/s (%.0f us), in from pinned %.1f "
           "GB/s (%.0f us), out to pageable %.1f GB/s (%.0f us)\n\n",
           bytes >> 20, bytes / best[0] / 1e9, best[0] * 1e6, bytes / best[1] / 1e9, best[1] * 1e6,
           bytes / best[2] / 1e9, best[2] * 1e6);
    free(pageable), cudaFree(device), cudaFreeHost(pinned);
}

int main(int argc, char **argv)
{
    const char *sizes_arg = "500,10000,100000,1000000,10000000";
    double seconds = 2.0;
    FILE *csv = NULL;
    for (int a = 1; a < argc; a++) {
        if (!strcmp(argv[a], "--sizes") && a + 1 < argc)
            sizes_arg = argv[++a];
        else if (!strcmp(argv[a], "--seconds") && a + 1 < argc)
            seconds = atof(argv[++a]);
        else if (!strcmp(argv[a], "--csv") && a + 1 < argc) {
            csv = fopen(argv[++a], "w");
            if (!csv) {
                perror(argv[a]);
                return 1;
            }
        } else {
            fprintf(stderr, "usage: bpx_gpubench [--sizes N,N,...] [--seconds S] [--csv FILE]\n");
            return 2;
        }
    }
    bpx_set_logger(print_log, NULL);
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_CUDA);
    if (!info.available) {
        printf("bpx_gpubench: cuda unavailable (%s)\n", info.reason);
        return 77;
    }
    int threads = (int)sysconf(_SC_NPROCESSORS_ONLN);
    printf("cuda: %s; host grid on %d threads; uniform scene, 5%% motion per cycle, %.1f s per "
           "variant and size\n\n",
           info.detail, threads, seconds);
    print_link(24u << 20); // a million boxes' 24 bytes
    printf("| n | pairs | cuda resident ms (median) | cuda host ms (median) | grid %dt ms (median) "
           "| grid / resident | grid / host | in us | kernels us | out us | exact |\n"
           "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
           threads);
    if (csv)
        fprintf(csv, "n,pairs,variant,cycles,mean_ms,median_ms,min_ms,exact\n");
    char *list = strdup(sizes_arg);
    for (char *tok = strtok(list, ","); tok; tok = strtok(NULL, ",")) {
        uint32_t n = (uint32_t)strtoul(tok, NULL, 10);
        bpx_box *boxes = malloc(sizeof(bpx_box) * n);
        scene_uniform_density(n, 1.0f, 42, boxes);
        scene_rng rng;
        scene_rng_seed(&rng, 7);
        void *d_boxes = NULL;
        if (cudaMalloc(&d_boxes, sizeof(bpx_box) * n) != cudaSuccess) {
            fprintf(stderr, "bpx_gpubench: no device memory for %u boxes\n", n);
            return 1;
        }
        bpx_world *resident = make_world(BPX_BACKEND_CUDA, 1);
        bpx_world *host = make_world(BPX_BACKEND_CUDA, 1);
        bpx_world *grid = make_world(BPX_BACKEND_GRID, threads);
        enum { max_cycles = 20000 };
        double *ms[3];
        for (int v = 0; v < 3; v++)
            ms[v] = malloc(sizeof(double) * max_cycles);
        timing t[3] = {{0}};
        for (int v = 0; v < 3; v++)
            t[v].exact = true;
        uint64_t in_ns = 0, dev_ns = 0, out_ns = 0;
        size_t pairs = 0;
        double start = now_s();
        int cycles = 0, warm = 3;
        // Variants alternate cycle by cycle, on the same boxes, so drift hits them alike. The
        // device boxes are checked when set: they hold the scene first, not what cudaMalloc left
        // (memory an earlier size's worlds freed: NaNs, min > max).
        bool ok = cudaMemcpy(d_boxes, boxes, sizeof(bpx_box) * n, cudaMemcpyHostToDevice) ==
                      cudaSuccess &&
                  cudaDeviceSynchronize() == cudaSuccess;
        if (!ok)
            fprintf(stderr, "bpx_gpubench: copying the boxes to the device failed\n");
        ok = ok && check(bpx_cuda_set_boxes_device(resident, d_boxes, n), resident, "set device");
        // The device boxes are read in place: each cycle's copy below changes them.
        while (ok && cycles < max_cycles && (cycles < warm + 5 || now_s() - start < 3 * seconds)) {
            scene_move(boxes, n, 0.05f, &rng);
            // Landed before the world's non-blocking stream reads them: a cudaMemcpy from
            // pageable memory may return before its DMA ends.
            if (cudaMemcpy(d_boxes, boxes, sizeof(bpx_box) * n, cudaMemcpyHostToDevice) !=
                    cudaSuccess ||
                cudaDeviceSynchronize() != cudaSuccess) {
                fprintf(stderr, "bpx_gpubench: copying the boxes to the device failed\n");
                ok = false;
                break;
            }
            double t1 = now_s();
            size_t on_device = 0;
            ok = ok && check(bpx_cuda_collide_device(resident, NULL), resident, "collide_device");
            ok = ok && check(bpx_cuda_finish(resident, &on_device), resident, "finish");
            double t2 = now_s();
            ok = ok && check(bpx_world_set_boxes(host, boxes, n), host, "set_boxes") &&
                 check(bpx_world_collide(host), host, "collide");
            double t3 = now_s();
            ok = ok && check(bpx_world_set_boxes(grid, boxes, n), grid, "set_boxes") &&
                 check(bpx_world_collide(grid), grid, "collide");
            double t4 = now_s();
            if (!ok)
                break;
            size_t hn = 0, gn = 0;
            const bpx_pair *hp = bpx_world_pairs(host, &hn);
            const bpx_pair *gp = bpx_world_pairs(grid, &gn);
            bool same = hn == gn && memcmp(hp, gp, sizeof(bpx_pair) * hn) == 0;
            t[1].exact &= same;
            t[0].exact &= on_device == gn;
            if (on_device == gn) { // every cycle, untimed: the resident pairs themselves
                void *dp = NULL;
                bpx_cuda_device_pairs(resident, &dp, NULL, NULL);
                bpx_pair *back = malloc(sizeof(bpx_pair) * (gn ? gn : 1));
                t[0].exact &= back &&
                              cudaMemcpy(back, dp, sizeof(bpx_pair) * gn, cudaMemcpyDeviceToHost) ==
                                  cudaSuccess &&
                              memcmp(back, gp, sizeof(bpx_pair) * gn) == 0;
                free(back);
            }
            pairs = gn;
            if (cycles >= warm) {
                int k = cycles - warm;
                ms[0][k] = 1e3 * (t2 - t1);
                ms[1][k] = 1e3 * (t3 - t2);
                ms[2][k] = 1e3 * (t4 - t3);
                bpx_cycle_stats st = bpx_world_stats(host);
                in_ns += st.transfer_in_ns, dev_ns += st.device_ns, out_ns += st.transfer_out_ns;
            }
            cycles++;
        }
        int timed = cycles > warm ? cycles - warm : 0;
        static const char *names[3] = {"cuda resident", "cuda host", "grid"};
        for (int v = 0; v < 3; v++) {
            bool exact = t[v].exact;
            t[v] = summarise(ms[v], timed);
            t[v].exact = exact && ok;
            if (csv)
                fprintf(csv, "%u,%zu,%s,%d,%.4f,%.4f,%.4f,%d\n", n, pairs, names[v], timed,
                        t[v].mean_ms, t[v].median_ms, t[v].min_ms, t[v].exact);
        }
        double d = timed ? (double)timed : 1.0;
        printf("| %u | %zu | %.3f (%.3f) | %.3f (%.3f) | %.3f (%.3f) | %.1fx | %.1fx | %.0f | %.0f | "
               "%.0f | %s |\n",
               n, pairs, t[0].mean_ms, t[0].median_ms, t[1].mean_ms, t[1].median_ms, t[2].mean_ms,
               t[2].median_ms, t[0].median_ms > 0 ? t[2].median_ms / t[0].median_ms : 0,
               t[1].median_ms > 0 ? t[2].median_ms / t[1].median_ms : 0, in_ns / d / 1e3,
               dev_ns / d / 1e3, out_ns / d / 1e3,
               t[0].exact && t[1].exact ? "yes" : "**NO**");
        fflush(stdout);
        for (int v = 0; v < 3; v++)
            free(ms[v]);
        bpx_world_destroy(resident);
        bpx_world_destroy(host);
        bpx_world_destroy(grid);
        cudaFree(d_boxes);
        free(boxes);
    }
    free(list);
    if (csv)
        fclose(csv);
    return 0;
}
