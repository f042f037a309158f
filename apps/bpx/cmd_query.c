// bpx query: ray casts, region, sphere and swept-box queries on boxes read from a CSV file.
// SPDX-License-Identifier: MIT
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "box_csv.h"
#include "cli.h"

enum { THREADS_MAX = 256, FIELDS_MAX = 10, PARSE_CONTINUE = -1 };

static const char *const command = "query";

typedef struct query_options {
    const char *path;
    const char *batch_path;
    bpx_query query;
    bool have_query;
    bool all;
    bool count_only;
    int threads;
} query_options;

static void print_help(void)
{
    printf("usage: bpx query FILE --ray OX,OY,OZ,DX,DY,DZ[,MAX] [--all]\n"
           "       bpx query FILE --box X0,Y0,Z0,X1,Y1,Z1\n"
           "       bpx query FILE --sphere CX,CY,CZ,R\n"
           "       bpx query FILE --sweep X0,Y0,Z0,X1,Y1,Z1,DX,DY,DZ[,MAX] [--all]\n"
           "       bpx query FILE --batch QUERIES.csv\n"
           "\n"
           "Asks which boxes of FILE a ray, a region, a sphere or a moving box hits. FILE is\n"
           "read as by `bpx pairs` (CSV, six numbers a box; - for standard input); boxes are\n"
           "numbered from 0 in input order.\n"
           "\n"
           "  --ray      origin and direction; hits at origin + t * direction for t in\n"
           "             [0, MAX] (default MAX: unbounded). Prints the closest hit as \"id t\"\n"
           "             (ties: the lowest id); with --all every hit, by t then id\n"
           "  --box      prints every box overlapping the region (touching counts), by id\n"
           "  --sphere   prints every box within distance R of the centre, by id\n"
           "  --sweep    a box moved by t * (DX, DY, DZ), t in [0, MAX] (default 1): the first\n"
           "             box it touches as \"id t\"; with --all every one\n"
           "  --batch    one query a line: KIND,numbers as above, KIND one of box, sphere,\n"
           "             ray, ray_all, sweep, sweep_all; prints \"query id t\" lines\n"
           "  --count    print only the number of hits\n"
           "  --threads N  workers for --batch, 1..%d\n"
           "  -h, --help   show this help\n"
           "\n"
           "Exit status: 0 success, 1 bad input or runtime error, 2 usage error.\n",
           THREADS_MAX);
}

// Splits "a,b,c" into floats. Returns the count, or -1 on a field that is not a number.
static int parse_numbers(const char *text, float *out, int max, int *bad_field)
{
    int count = 0;
    const char *p = text;
    for (;;) {
        while (isspace((unsigned char)*p))
            p++;
        char *end = NULL;
        errno = 0;
        float v = strtof(p, &end);
        if (end == p || count == max) {
            *bad_field = count + 1;
            return -1;
        }
        out[count++] = v;
        p = end;
        while (isspace((unsigned char)*p))
            p++;
        if (*p == '\0')
            return count;
        if (*p != ',') {
            *bad_field = count + 1;
            return -1;
        }
        p++;
    }
}

// Makes a query of `kind` from its numbers. Returns NULL, or what is wrong.
static const char *make_query(const char *kind, const float *v, int count, bpx_query *q)
{
    bool all = strcmp(kind, "ray_all") == 0 || strcmp(kind, "sweep_all") == 0;
    if (strcmp(kind, "box") == 0) {
        if (count != 6)
            return "a box wants 6 numbers: X0,Y0,Z0,X1,Y1,Z1";
        *q = bpx_query_box((bpx_box){{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
    } else if (strcmp(kind, "sphere") == 0) {
        if (count != 4)
            return "a sphere wants 4 numbers: CX,CY,CZ,R";
        *q = bpx_query_sphere(v, v[3]);
    } else if (strncmp(kind, "ray", 3) == 0 && (kind[3] == '\0' || all)) {
        if (count != 6 && count != 7)
            return "a ray wants 6 or 7 numbers: OX,OY,OZ,DX,DY,DZ[,MAX]";
        *q = bpx_query_ray(v, v + 3, count == 7 ? v[6] : INFINITY, !all);
    } else if (strncmp(kind, "sweep", 5) == 0 && (kind[5] == '\0' || all)) {
        if (count != 9 && count != 10)
            return "a sweep wants 9 or 10 numbers: X0,Y0,Z0,X1,Y1,Z1,DX,DY,DZ[,MAX]";
        *q = bpx_query_sweep((bpx_box){{v[0], v[1], v[2]}, {v[3], v[4], v[5]}}, v + 6,
                             count == 10 ? v[9] : 1.0f, !all);
    } else {
        return "unknown query kind (box, sphere, ray, ray_all, sweep, sweep_all)";
    }
    return NULL;
}

static int parse_args(int argc, char **argv, query_options *opt)
{
    static const char *const kinds[] = {"--box", "--sphere", "--ray", "--sweep"};
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i], *value = NULL;
        cli_match match = CLI_NO_MATCH;
        if (cli_is_help(arg)) {
            print_help();
            return CLI_EXIT_OK;
        }
        if (cli_is_flag(arg, "--all")) {
            opt->all = true;
            continue;
        }
        if (cli_is_flag(arg, "--count")) {
            opt->count_only = true;
            continue;
        }
        if ((match = cli_flag_value(argc, argv, &i, "--threads", &value))) {
            if (match == CLI_MISSING_VALUE || !cli_parse_int(value, 1, THREADS_MAX, &opt->threads))
                return cli_usage_error(command, "--threads wants an integer in 1..%d",
                                       THREADS_MAX);
            continue;
        }
        if ((match = cli_flag_value(argc, argv, &i, "--batch", &value))) {
            if (match == CLI_MISSING_VALUE)
                return cli_usage_error(command, "--batch needs a file");
            opt->batch_path = value;
            continue;
        }
        int k = 0;
        while (k < 4 && !(match = cli_flag_value(argc, argv, &i, kinds[k], &value)))
            k++;
        if (k < 4) {
            if (match == CLI_MISSING_VALUE)
                return cli_usage_error(command, "%s needs its numbers", kinds[k]);
            if (opt->have_query)
                return cli_usage_error(command, "one query a run (use --batch for more)");
            float v[FIELDS_MAX];
            int bad = 0, count = parse_numbers(value, v, FIELDS_MAX, &bad);
            if (count < 0)
                return cli_usage_error(command, "%s: number %d is not a number: \"%s\"",
                                       kinds[k], bad, value);
            const char *why = make_query(kinds[k] + 2, v, count, &opt->query);
            if (why)
                return cli_usage_error(command, "%s: %s", kinds[k], why);
            opt->have_query = true;
            continue;
        }
        if (arg[0] == '-' && arg[1] != '\0')
            return cli_usage_error(command, "unknown option \"%s\"", arg);
        if (opt->path)
            return cli_usage_error(command, "one box file, got \"%s\" and \"%s\"", opt->path, arg);
        opt->path = arg;
    }
    if (!opt->path)
        return cli_usage_error(command, "missing the box file");
    if (opt->have_query == !!opt->batch_path)
        return cli_usage_error(command, "give one of --ray, --box, --sphere, --sweep, --batch");
    if (opt->all) {
        if (!opt->have_query || opt->query.kind == BPX_QUERY_BOX ||
            opt->query.kind == BPX_QUERY_SPHERE)
            return cli_usage_error(command, "--all goes with --ray or --sweep");
        opt->query.closest = false;
    }
    return PARSE_CONTINUE;
}

// Reads the batch file: one query a line. Returns 0, or -1 with message set.
static int read_batch(const char *path, bpx_query **out, uint32_t *count, char *message,
                      size_t size)
{
    FILE *in = fopen(path, "r");
    if (!in) {
        snprintf(message, size, "%s: %s", path, strerror(errno));
        return -1;
    }
    size_t capacity = 0;
    *out = NULL;
    *count = 0;
    char line[1024];
    int status = 0;
    for (long number = 1; fgets(line, sizeof line, in); number++) {
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        char *p = line;
        while (isspace((unsigned char)*p))
            p++;
        if (*p == '\0')
            continue;
        char *comma = strchr(p, ',');
        if (!comma) {
            snprintf(message, size, "%s:%ld: expected KIND,numbers", path, number);
            status = -1;
            break;
        }
        *comma = '\0';
        char *kind_end = comma;
        while (kind_end > p && isspace((unsigned char)kind_end[-1]))
            *--kind_end = '\0';
        float v[FIELDS_MAX];
        int bad = 0, n = parse_numbers(comma + 1, v, FIELDS_MAX, &bad);
        bpx_query q;
        const char *why = n < 0 ? "a field is not a number" : make_query(p, v, n, &q);
        if (why) {
            snprintf(message, size, "%s:%ld: %s", path, number, why);
            status = -1;
            break;
        }
        if (*count == capacity) {
            capacity = capacity ? 2 * capacity : 256;
            bpx_query *grown = realloc(*out, capacity * sizeof **out);
            if (!grown || capacity > UINT32_MAX) {
                snprintf(message, size, "%s: out of memory", path);
                status = -1;
                break;
            }
            *out = grown;
        }
        (*out)[(*count)++] = q;
    }
    fclose(in);
    return status;
}

int cmd_query(int argc, char **argv)
{
    query_options opt = {0};
    int parsed = parse_args(argc, argv, &opt);
    if (parsed != PARSE_CONTINUE)
        return parsed;
    char message[512];
    box_array boxes = {0};
    FILE *in = strcmp(opt.path, "-") == 0 ? stdin : fopen(opt.path, "r");
    if (!in) {
        cli_error(command, "%s: %s", opt.path, strerror(errno));
        return CLI_EXIT_ERROR;
    }
    int read = box_csv_read(in, opt.path, &boxes, message, sizeof message);
    if (in != stdin)
        fclose(in);
    if (read != 0) {
        cli_error(command, "%s", message);
        box_array_free(&boxes);
        return CLI_EXIT_ERROR;
    }
    bpx_query *queries = &opt.query;
    uint32_t count = 1;
    if (opt.batch_path && read_batch(opt.batch_path, &queries, &count, message, sizeof message)) {
        cli_error(command, "%s", message);
        free(queries);
        box_array_free(&boxes);
        return CLI_EXIT_ERROR;
    }
    bpx_world_def def = bpx_default_world_def();
    def.worker_count = opt.threads;
    bpx_world *world = NULL;
    int code = CLI_EXIT_ERROR;
    size_t *offsets = malloc(sizeof(size_t) * ((size_t)count + 1));
    size_t total = 0;
    if (!offsets) {
        cli_error(command, "out of memory");
    } else if (bpx_world_create(&def, &world) != BPX_OK) {
        cli_error(command, "cannot create a world");
    } else if (bpx_world_set_boxes(world, boxes.data, (uint32_t)boxes.count) != BPX_OK) {
        cli_error(command, "%s", bpx_world_error(world)->message);
    } else {
        bpx_status s = bpx_world_query_batch(world, queries, count, offsets, NULL, 0, &total);
        if (s != BPX_OK && s != BPX_ERR_CAPACITY) {
            const bpx_error *e = bpx_world_error(world);
            if (opt.batch_path)
                cli_error(command, "%s: %s", opt.batch_path, e->message);
            else
                cli_error(command, "%s", e->message);
        } else {
            const bpx_hit *hits = bpx_world_query_hits(world, NULL, NULL, NULL);
            bool cast = !opt.batch_path && (opt.query.kind == BPX_QUERY_RAY ||
                                            opt.query.kind == BPX_QUERY_SWEEP);
            if (opt.count_only) {
                printf("%zu\n", total);
            } else {
                for (uint32_t k = 0; k < count; k++)
                    for (size_t h = offsets[k]; h < offsets[k + 1]; h++) {
                        if (opt.batch_path)
                            printf("%u %u %.9g\n", k, hits[h].id, (double)hits[h].fraction);
                        else if (cast)
                            printf("%u %.9g\n", hits[h].id, (double)hits[h].fraction);
                        else
                            printf("%u\n", hits[h].id);
                    }
            }
            code = fflush(stdout) == 0 && !ferror(stdout) ? CLI_EXIT_OK : CLI_EXIT_ERROR;
            if (code != CLI_EXIT_OK)
                cli_error(command, "cannot write the output");
        }
    }
    bpx_world_destroy(world);
    free(offsets);
    if (queries != &opt.query)
        free(queries);
    box_array_free(&boxes);
    return code;
}
