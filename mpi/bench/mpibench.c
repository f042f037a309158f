// bpx_mpibench: libbpx_mpi's weak and strong scaling, run under mpiexec.
//   mpiexec -n P bpx_mpibench --weak 100000     (100k boxes per rank, constant density)
//   mpiexec -n P bpx_mpibench --strong 1000000  (1M boxes over all ranks)
// Objects move every cycle at their own constant velocity; bpx_mpi_world_migrate keeps each on
// its home rank, moving those that crossed a border with their velocity (as particle codes do),
// so bpx sends only the copies near borders. Prints one row: per-rank time (wall and
// CPU), imbalance, bytes and messages per rank per cycle, and the CPU time of a single-process
// world on this rank's boxes, measured in the same run. With more ranks than cores, wall time
// counts waits for a core: read CPU time.
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <bpx/mpi.h>

#include "scenes.h"

typedef struct velocity {
    float v[3];
} velocity_t;

static int rank, ranks;

static double cpu_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

static void die(const char *what, bpx_status s)
{
    fprintf(stderr, "rank %d: %s: %s\n", rank, what, bpx_status_name(s));
    MPI_Abort(MPI_COMM_WORLD, 1);
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &ranks);
    size_t per_rank = 100000, total = 0;
    int cycles = 10, heavy = 0, header = 0, phases = 0;
    float step = 0.05f;
    for (int a = 1; a < argc; a++) {
        if (!strcmp(argv[a], "--weak") && a + 1 < argc)
            per_rank = strtoull(argv[++a], NULL, 10), total = 0;
        else if (!strcmp(argv[a], "--strong") && a + 1 < argc)
            total = strtoull(argv[++a], NULL, 10);
        else if (!strcmp(argv[a], "--cycles") && a + 1 < argc)
            cycles = atoi(argv[++a]);
        else if (!strcmp(argv[a], "--step") && a + 1 < argc)
            step = (float)atof(argv[++a]);
        else if (!strcmp(argv[a], "--heavy"))
            heavy = 1;
        else if (!strcmp(argv[a], "--header"))
            header = 1;
        else if (!strcmp(argv[a], "--phases"))
            phases = 1;
        else {
            if (rank == 0)
                fprintf(stderr, "usage: bpx_mpibench [--weak N | --strong N] [--cycles C] "
                                "[--step S] [--heavy] [--header]\n");
            MPI_Finalize();
            return 2;
        }
    }
    const char *mode = total ? "strong" : "weak";
    if (!total)
        total = per_rank * (size_t)ranks;

    // The global scene, the same on every rank; each keeps every ranks-th object to start.
    bpx_box *all = malloc(total * sizeof *all);
    if (heavy)
        scene_heavy_tailed_density((uint32_t)total, 1, all);
    else
        scene_uniform_density((uint32_t)total, 1.0f, 1, all);
    // This rank's objects (room for all: migrations may gather many on one rank).
    size_t count = 0, capacity = total;
    uint64_t *ids = malloc(capacity * sizeof *ids);
    bpx_box *boxes = malloc(capacity * sizeof *boxes);
    velocity_t *velocity = malloc(capacity * sizeof *velocity);
    scene_rng rng;
    scene_rng_seed(&rng, 2);
    for (size_t k = 0; k < total; k++) {
        velocity_t v = {{scene_rng_range(&rng, -step, step), scene_rng_range(&rng, -step, step),
                         scene_rng_range(&rng, -step, step)}};
        if ((int)(k % (size_t)ranks) == rank) {
            ids[count] = k;
            boxes[count] = all[k];
            velocity[count++] = v;
        }
    }
    free(all);

    bpx_mpi_world_def def = bpx_mpi_default_world_def();
    bpx_mpi_world *world;
    bpx_status s = bpx_mpi_world_create(MPI_COMM_WORLD, &def, &world, NULL);
    if (s != BPX_OK)
        die("create", s);
    // Sums over the measured cycles (all but the first two: decomposition and the big move).
    double wall = 0, cpu = 0, compute = 0, imbalance = 0, bytes = 0, messages = 0, copies = 0,
           moved_sum = 0, own_sum = 0, pairs = 0;
    int measured = 0;
    for (int c = 0; c < cycles + 2; c++) {
        MPI_Barrier(MPI_COMM_WORLD);
        if ((s = bpx_mpi_world_collide(world, ids, boxes, NULL, count)) != BPX_OK)
            die(bpx_mpi_world_error(world)->message, s);
        bpx_mpi_stats st = bpx_mpi_world_stats(world);
        // The application's step: move, then send the objects that left this rank's region
        // to their new home, with their velocities (bpx_mpi_world_migrate).
        for (size_t k = 0; k < count; k++)
            for (int d = 0; d < 3; d++) {
                boxes[k].min[d] += velocity[k].v[d];
                boxes[k].max[d] += velocity[k].v[d];
            }
        size_t own = count, moved = count;
        s = bpx_mpi_world_migrate(world, ids, boxes, velocity, sizeof *velocity, capacity, &moved,
                                  NULL);
        if (s != BPX_OK)
            die(bpx_mpi_world_error(world)->message, s);
        count = moved;
        moved = bpx_mpi_world_stats(world).migrated_sent;
        if (c >= 2) {
            wall += st.total_ns * 1e-6, cpu += st.cpu_ns * 1e-6;
            compute += st.compute_cpu_ns * 1e-6, imbalance += st.imbalance;
            bytes += (double)st.bytes_sent, messages += (double)st.messages_sent;
            copies += (double)st.copies_sent, moved_sum += (double)moved, own_sum += (double)own;
            pairs += (double)st.total_pair_count;
            measured++;
            if (phases && rank == 0)
                fprintf(stderr,
                        "cycle %d: route %.2f exchange %.2f local %.2f select %.2f events %.2f "
                        "total %.2f ms; present %llu\n",
                        c, st.route_ns * 1e-6, st.exchange_ns * 1e-6, st.local_ns * 1e-6,
                        st.select_ns * 1e-6, st.events_ns * 1e-6, st.total_ns * 1e-6,
                        (unsigned long long)st.present_count);
        }
    }

    // The same work in one process: a plain world on this rank's boxes, same CPU clock (the
    // boxes move on as before; they are this rank's own copy now).
    bpx_world *single;
    bpx_world_def sdef = bpx_default_world_def();
    if ((s = bpx_world_create(&sdef, &single)) != BPX_OK)
        die("single", s);
    double single_cpu = 0;
    for (int c = 0; c < cycles + 2; c++) {
        double t0 = cpu_ms();
        bpx_world_set_boxes(single, boxes, (uint32_t)count);
        bpx_world_collide(single);
        if (c >= 2)
            single_cpu += cpu_ms() - t0;
        for (size_t k = 0; k < count; k++)
            for (int d = 0; d < 3; d++)
                boxes[k].min[d] += velocity[k].v[d], boxes[k].max[d] += velocity[k].v[d];
    }
    bpx_world_destroy(single);

    // Per rank means per cycle, then mean and max over ranks on rank 0.
    double mine[8] = {wall / measured,       cpu / measured,    compute / measured,
                      single_cpu / measured, bytes / measured,  messages / measured,
                      moved_sum / measured,  own_sum / measured};
    double sum[8], most[8];
    MPI_Reduce(mine, sum, 8, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
    MPI_Reduce(mine, most, 8, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
    if (rank == 0) {
        if (header)
            printf("| mode | scene | ranks | boxes/rank | wall ms (max) | cpu ms (mean) | "
                   "compute cpu ms (mean / max) | single-process cpu ms | compute / single | "
                   "imbalance | bytes sent/rank | %% of box bytes | messages/rank | "
                   "migrated/rank | pairs |\n"
                   "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | "
                   "--- | --- | --- |\n");
        double boxes_mean = sum[7] / ranks;
        printf("| %s | %s | %d | %.0f | %.1f | %.1f | %.1f / %.1f | %.1f | %.2f | %.3f | %.0f | "
               "%.2f%% | %.1f | %.1f | %.0f |\n",
               mode, heavy ? "heavy" : "uniform", ranks, boxes_mean, most[0], sum[1] / ranks,
               sum[2] / ranks, most[2], sum[3] / ranks, most[2] / (sum[3] / ranks),
               imbalance / measured, sum[4] / ranks,
               100.0 * (sum[4] / ranks) / (boxes_mean * sizeof(bpx_box)), sum[5] / ranks,
               sum[6] / ranks, pairs / measured);
    }
    bpx_mpi_world_destroy(world);
    free(ids), free(boxes), free(velocity);
    MPI_Finalize();
    return 0;
}
