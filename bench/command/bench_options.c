// bpx bench's flags (the help text is cmd_bench.c's), and the variants a run times.
// SPDX-License-Identifier: MIT

#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "bench_cmd.h"
#include "peers.h"

static int parse_list(const char *text, const char **out, int most, char *storage, size_t size)
{
    if (strlen(text) >= size)
        return -1;
    strcpy(storage, text);
    int count = 0;
    for (char *save = NULL, *tok = strtok_r(storage, ",", &save); tok;
         tok = strtok_r(NULL, ",", &save)) {
        if (count == most)
            return -1;
        out[count++] = tok;
    }
    return count;
}

static int parse_sizes(const char *text, bench_options *o)
{
    o->size_count = 0;
    const char *p = text;
    while (*p) {
        char *end;
        errno = 0;
        unsigned long n = strtoul(p, &end, 10);
        if (end == p || errno || n > BPX_MAX_BOXES || o->size_count == BENCH_MAX_SIZES)
            return -1;
        o->sizes[o->size_count++] = (uint32_t)n;
        if (*end == ',')
            end++;
        else if (*end != '\0')
            return -1;
        p = end;
    }
    return o->size_count > 0 ? 0 : -1;
}

static bool known_name(const char *name)
{
    bpx_backend b;
    return bpx_backend_from_name(name, &b) == BPX_OK || bench_peer_find(name) >= 0;
}

int bench_cmd_parse_args(int argc, char **argv, bench_options *o)
{
    static char name_storage[512], scene_storage[64];
    for (int k = 1; k < argc; k++) {
        const char *value = NULL;
        cli_match m;
        if (cli_is_flag(argv[k], "--all-simd")) {
            o->all_simd = true;
        } else if (cli_is_flag(argv[k], "--table2")) {
            o->table2 = true;
        } else if (cli_is_flag(argv[k], "--quick")) {
            o->quick = true;
        } else if (cli_is_flag(argv[k], "--profile")) {
            o->profile = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--sizes", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || parse_sizes(value, o) != 0)
                return cli_usage_error("bench", "--sizes wants box counts like 500,10000");
            o->sizes_given = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--backend", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE ||
                (o->name_count = parse_list(value, o->names, MAX_NAMES, name_storage,
                                            sizeof name_storage)) <= 0)
                return cli_usage_error("bench", "--backend wants names like prune,bullet-dbvt");
            for (int n = 0; n < o->name_count; n++) {
                if (known_name(o->names[n]))
                    continue;
                if (bench_peers_unavailable() && (strncmp(o->names[n], "bullet-", 7) == 0 ||
                                                  strncmp(o->names[n], "box2d-", 6) == 0 ||
                                                  strncmp(o->names[n], "fcl-", 4) == 0)) {
                    cli_error("bench", "peer \"%s\" is not available: %s", o->names[n],
                              bench_peers_unavailable());
                    return CLI_EXIT_ERROR;
                }
                return cli_usage_error("bench", "unknown backend or peer \"%s\" (see bpx backends)",
                                       o->names[n]);
            }
        } else if ((m = cli_flag_value(argc, argv, &k, "--scene", &value)) != CLI_NO_MATCH) {
            const char *list[SCENES + 1];
            int count = m == CLI_MATCH ? parse_list(value, list, SCENES + 1, scene_storage,
                                                    sizeof scene_storage)
                                       : -1;
            memset(o->scenes, 0, sizeof o->scenes);
            for (int s = 0; s < count; s++) {
                int found = -1;
                for (int t = 0; t < SCENES; t++)
                    if (strcmp(list[s], bench_scene_names[t]) == 0)
                        found = t;
                if (found < 0)
                    count = -1;
                else
                    o->scenes[found] = true;
            }
            if (count <= 0)
                return cli_usage_error("bench", "--scene wants uniform, heavy, resting or a list");
            o->scenes_given = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--threads", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 256, &o->threads))
                return cli_usage_error("bench", "--threads wants 1..256");
        } else if ((m = cli_flag_value(argc, argv, &k, "--cycles", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE || !cli_parse_int(value, 1, 100000000, &o->max_cycles))
                return cli_usage_error("bench", "--cycles wants a positive count");
            o->cycles_given = true;
        } else if ((m = cli_flag_value(argc, argv, &k, "--seconds", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            o->seconds = m == CLI_MATCH ? strtod(value, &end) : 0;
            if (m == CLI_MISSING_VALUE || *end != '\0' || !(o->seconds > 0 && o->seconds < 1e4))
                return cli_usage_error("bench", "--seconds wants a positive number");
        } else if ((m = cli_flag_value(argc, argv, &k, "--step", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            o->step = m == CLI_MATCH ? strtod(value, &end) : 0;
            if (m == CLI_MISSING_VALUE || *end != '\0' || !(o->step > 0 && o->step < 1e3))
                return cli_usage_error("bench", "--step wants a positive distance");
        } else if ((m = cli_flag_value(argc, argv, &k, "--seed", &value)) != CLI_NO_MATCH) {
            char *end = NULL;
            o->seed = m == CLI_MATCH ? strtoull(value, &end, 10) : 0;
            if (m == CLI_MISSING_VALUE || *end != '\0')
                return cli_usage_error("bench", "--seed wants an unsigned integer");
        } else if ((m = cli_flag_value(argc, argv, &k, "--device", &value)) != CLI_NO_MATCH) {
            int platform = -1, device = -1, used = 0;
            if (m == CLI_MISSING_VALUE ||
                sscanf(value, "%d:%d%n", &platform, &device, &used) != 2 || value[used] != '\0' ||
                platform < 0 || device < 0)
                return cli_usage_error("bench", "--device wants PLATFORM:DEVICE like 0:0");
            o->opencl_platform = platform + 1;
            o->opencl_device = device + 1;
        } else if ((m = cli_flag_value(argc, argv, &k, "--csv", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE)
                return cli_usage_error("bench", "--csv wants a file name");
            o->csv_path = value;
        } else if ((m = cli_flag_value(argc, argv, &k, "--out", &value)) != CLI_NO_MATCH) {
            if (m == CLI_MISSING_VALUE)
                return cli_usage_error("bench", "--out wants a directory");
            o->out_dir = value;
        } else {
            return cli_usage_error("bench", "unknown argument \"%s\"", argv[k]);
        }
    }
    return CLI_EXIT_OK;
}

bool bench_cmd_wanted(const bench_variant *v, const void *context)
{
    const bench_options *o = context;
    if (o->name_count == 0)
        return true;
    const char *name = v->peer >= 0 ? bench_peer_get(v->peer)->name : bpx_backend_name(v->backend);
    for (int k = 0; k < o->name_count; k++)
        if (strcmp(o->names[k], name) == 0)
            return true;
    return false;
}

// Where a variant stops: quadratic ones where one cycle would take seconds (less with --quick).
static bool fits(const bench_variant *v, uint32_t n, bool quick)
{
    if (v->peer >= 0) {
        const bench_peer_info *info = bench_peer_get(v->peer);
        // --quick: peers to 10k only, well inside their limits (creating Box2D's tree at 100k
        // takes seconds, Bullet's sweep and prune are quadratic to create).
        if (quick)
            return n <= 10000 && n <= info->max_n / 4 && n <= info->slow_n / 4;
        return n <= info->max_n && n <= info->slow_n;
    }
    uint32_t quadratic = quick ? 20000 : 200000;
    switch (v->backend) {
    case BPX_BACKEND_REFERENCE:
        return n <= (quick ? 5000u : 20000u);
    case BPX_BACKEND_BRUTE:
        return n <= quadratic;
    case BPX_BACKEND_RTL:
        return n <= BPX_RTL_MAX_BOXES; // the chip's RAMs
    case BPX_BACKEND_OPENCL:
        // The auto rule's rows: brute force, the tree from 2048 boxes. The forced paths
        // measure the crossover (full runs only): the sweep's candidates grow like n^(5/3), so
        // it stops at 200k.
        if (v->opencl_method == BPX_OPENCL_SWEEP)
            return !quick && n <= 200000u;
        if (v->opencl_method == BPX_OPENCL_TREE)
            return !quick && n <= 1000000u;
        return n <= (quick ? quadratic : 1000000u);
    default:
        return true;
    }
}

int bench_cmd_list_variants(const bench_options *o, uint32_t n, bench_variant *out)
{
    bench_variant all[BENCH_MAX_VARIANTS];
    int count = 0;
    all[count++] = (bench_variant){-1, BPX_BACKEND_REFERENCE, BPX_SIMD_AUTO, 1, false, 0};
    bpx_simd best = bpx_simd_best();
    for (int s = BPX_SIMD_COUNT - 1; s > BPX_SIMD_AUTO; s--) {
        if (!bpx_simd_supported((bpx_simd)s) || (!o->all_simd && s != (int)best))
            continue;
        all[count++] = (bench_variant){-1, BPX_BACKEND_BRUTE, (bpx_simd)s, 1, false, 0};
        if (o->threads > 1)
            all[count++] =
                (bench_variant){-1, BPX_BACKEND_BRUTE, (bpx_simd)s, o->threads, false, 0};
    }
    static const bpx_backend scalable[] = {BPX_BACKEND_PRUNE, BPX_BACKEND_SAP, BPX_BACKEND_GRID,
                                           BPX_BACKEND_AUTO};
    for (size_t k = 0; k < sizeof scalable / sizeof scalable[0]; k++) {
        all[count++] = (bench_variant){-1, scalable[k], BPX_SIMD_AUTO, 1, false, 0};
        if (o->threads > 1)
            all[count++] = (bench_variant){-1, scalable[k], BPX_SIMD_AUTO, o->threads, false, 0};
    }
    // The coprocessor: boxes over the link, then only centres (the paper's updater).
    if (bpx_backend_query(BPX_BACKEND_OPENCL).available) {
        all[count++] = (bench_variant){-1, BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, false, 0};
        all[count++] = (bench_variant){-1, BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, true, 0};
        all[count++] =
            (bench_variant){-1, BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, false, BPX_OPENCL_SWEEP};
        all[count++] =
            (bench_variant){-1, BPX_BACKEND_OPENCL, BPX_SIMD_AUTO, 1, false, BPX_OPENCL_TREE};
    }
    if (bpx_backend_query(BPX_BACKEND_CUDA).available)
        all[count++] = (bench_variant){-1, BPX_BACKEND_CUDA, BPX_SIMD_AUTO, 1, false, 0};
    // The chip's RTL, simulated (to BPX_RTL_MAX_BOXES boxes).
    if (bpx_backend_query(BPX_BACKEND_RTL).available)
        all[count++] = (bench_variant){-1, BPX_BACKEND_RTL, BPX_SIMD_AUTO, 1, false, 0};
    // CPU and device in one cycle, the CPU side on every thread.
    if (bpx_backend_query(BPX_BACKEND_HYBRID).available)
        all[count++] = (bench_variant){-1, BPX_BACKEND_HYBRID, BPX_SIMD_AUTO, o->threads, false, 0};
    for (int p = 0; p < bench_peer_count() && count < BENCH_MAX_VARIANTS; p++)
        all[count++] = (bench_variant){p, BPX_BACKEND_AUTO, BPX_SIMD_AUTO, 1, false, 0};
    int kept = 0;
    for (int k = 0; k < count; k++)
        if (bench_cmd_wanted(&all[k], o) && fits(&all[k], n, o->quick))
            out[kept++] = all[k];
    return kept;
}
