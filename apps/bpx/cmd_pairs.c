// bpx pairs: prints the overlapping pairs of boxes read from a CSV file.
// SPDX-License-Identifier: MIT
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "box_csv.h"
#include "cli.h"

enum {
    THREADS_MAX = 256,
    OUTPUT_BUFFER = 1 << 20,
    LINE_MAX_CHARS = 2 * 10 + 2, // "4294967295 4294967295\n"
    PARSE_CONTINUE = -1,         // parse_args: options complete, run the command
};

static const char *const command = "pairs";

typedef struct pairs_options {
    const char *path;
    bool count_only;
    bpx_backend backend;
    bpx_simd simd;
    int threads;                        // 0: not given, keep the library default
    int opencl_platform, opencl_device; // --device P:D, as bpx_world_def (from 1; 0 = best)
} pairs_options;

static void print_help(void)
{
    printf("usage: bpx pairs FILE [--count] [--backend NAME] [--threads N] [--simd NAME]\n"
           "                 [--device P:D]\n"
           "\n"
           "Prints every pair of overlapping boxes as \"i j\", one pair per line: 0-based box\n"
           "numbers in input order, i < j, sorted by i then j. Boxes are closed, so boxes that\n"
           "touch overlap.\n"
           "\n"
           "FILE is CSV, or - for standard input: one box per line as six numbers\n"
           "  min x, min y, min z, max x, max y, max z\n"
           "'#' starts a comment; blank lines are skipped.\n"
           "\n"
           "options:\n"
           "  --count          print only the number of pairs\n"
           "  --backend NAME   comparator backend:");
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        const char *name = bpx_backend_name((bpx_backend)b);
        printf("%s %s%s", b == 0 ? "" : ",", name ? name : "?",
               b == BPX_BACKEND_AUTO ? " (default)" : "");
    }
    printf("\n"
           "  --threads N      threads working on the cycle, 1..%d (default: the library's)\n"
           "  --simd NAME      SIMD width of the brute backend:",
           THREADS_MAX);
    for (int s = 0; s < BPX_SIMD_COUNT; s++) {
        const char *name = bpx_simd_name((bpx_simd)s);
        printf("%s %s%s", s == 0 ? "" : ",", name ? name : "?",
               s == BPX_SIMD_AUTO ? " (default)" : "");
    }
    printf("\n"
           "  --device P:D     OpenCL platform and device for --backend opencl (see\n"
           "                   `bpx devices`; default: the first GPU, else any device)\n"
           "  -h, --help       show this help\n"
           "\n"
           "Options may come before or after FILE, as --flag VALUE or --flag=VALUE.\n"
           "See `bpx backends` for what this machine supports.\n"
           "Exit status: 0 success, 1 bad input or runtime error, 2 usage error.\n");
}

// Returns PARSE_CONTINUE to run, or the exit code (help shown, or a usage error).
static int parse_args(int argc, char **argv, pairs_options *opt)
{
    bool options_done = false; // after "--" everything is a file name
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        const char *value = NULL;
        cli_match match;
        if (!options_done && arg[0] == '-' && arg[1] != '\0') {
            if (cli_is_help(arg)) {
                print_help();
                return CLI_EXIT_OK;
            }
            if (cli_is_flag(arg, "--")) {
                options_done = true;
            } else if (cli_is_flag(arg, "--count")) {
                opt->count_only = true;
            } else if ((match = cli_flag_value(argc, argv, &i, "--backend", &value))) {
                if (match == CLI_MISSING_VALUE) {
                    return cli_usage_error(command, "--backend needs a value");
                }
                if (cli_parse_backend(command, value, &opt->backend) != CLI_EXIT_OK) {
                    return CLI_EXIT_USAGE;
                }
            } else if ((match = cli_flag_value(argc, argv, &i, "--simd", &value))) {
                if (match == CLI_MISSING_VALUE) {
                    return cli_usage_error(command, "--simd needs a value");
                }
                if (cli_parse_simd(command, value, &opt->simd) != CLI_EXIT_OK) {
                    return CLI_EXIT_USAGE;
                }
            } else if ((match = cli_flag_value(argc, argv, &i, "--device", &value))) {
                int platform = -1, device = -1, used = 0;
                if (match == CLI_MISSING_VALUE ||
                    sscanf(value, "%d:%d%n", &platform, &device, &used) != 2 ||
                    value[used] != '\0' || platform < 0 || device < 0) {
                    return cli_usage_error(command, "--device wants PLATFORM:DEVICE like 0:0");
                }
                opt->opencl_platform = platform + 1;
                opt->opencl_device = device + 1;
            } else if ((match = cli_flag_value(argc, argv, &i, "--threads", &value))) {
                if (match == CLI_MISSING_VALUE) {
                    return cli_usage_error(command, "--threads needs a value");
                }
                if (!cli_parse_int(value, 1, THREADS_MAX, &opt->threads)) {
                    return cli_usage_error(command, "--threads: expected an integer in 1..%d, "
                                                    "got \"%s\"",
                                           THREADS_MAX, value);
                }
            } else {
                return cli_usage_error(command, "unknown option \"%s\"", arg);
            }
            continue;
        }
        if (opt->path != NULL) {
            return cli_usage_error(command, "only one FILE may be given (\"%s\", \"%s\")",
                                   opt->path, arg);
        }
        opt->path = arg;
    }
    if (opt->path == NULL) {
        return cli_usage_error(command, "missing FILE (use - for standard input)");
    }
    return PARSE_CONTINUE;
}

static char *put_u32(char *p, uint32_t value)
{
    char digits[10];
    int n = 0;
    do {
        digits[n++] = (char)('0' + value % 10);
        value /= 10;
    } while (value != 0);
    while (n > 0) {
        *p++ = digits[--n];
    }
    return p;
}

// Formats the pairs into a large buffer and writes it in big blocks: printf per pair would
// dominate the run time for millions of pairs. Returns 0, or -1 with errno set.
static int write_pairs(FILE *out, const bpx_pair *pairs, size_t count)
{
    char *buffer = malloc(OUTPUT_BUFFER);
    if (buffer == NULL) {
        errno = ENOMEM;
        return -1;
    }
    char *p = buffer;
    char *limit = buffer + OUTPUT_BUFFER - LINE_MAX_CHARS;
    int status = 0;
    for (size_t k = 0; k < count && status == 0; k++) {
        p = put_u32(p, pairs[k].i);
        *p++ = ' ';
        p = put_u32(p, pairs[k].j);
        *p++ = '\n';
        if (p >= limit) {
            size_t length = (size_t)(p - buffer);
            status = fwrite(buffer, 1, length, out) == length ? 0 : -1;
            p = buffer;
        }
    }
    size_t length = (size_t)(p - buffer);
    if (status == 0 && length > 0 && fwrite(buffer, 1, length, out) != length) {
        status = -1;
    }
    free(buffer);
    return status;
}

static void report_create_error(const pairs_options *opt, bpx_status status)
{
    const char *backend = bpx_backend_name(opt->backend);
    const char *simd = bpx_simd_name(opt->simd);
    if (status == BPX_ERR_BACKEND_UNAVAILABLE) {
        bpx_backend_info info = bpx_backend_query(opt->backend);
        if (!info.available) {
            cli_error(command, "backend %s is unavailable: %s", backend ? backend : "?",
                      info.reason && info.reason[0] ? info.reason : bpx_status_string(status));
            return;
        }
        if (opt->simd != BPX_SIMD_AUTO && !bpx_simd_supported(opt->simd)) {
            cli_error(command, "SIMD width %s is not supported on this machine or build",
                      simd ? simd : "?");
            return;
        }
    }
    cli_error(command, "cannot create a world (backend %s, simd %s, threads %d): %s",
              backend ? backend : "?", simd ? simd : "?", opt->threads,
              bpx_status_string(status));
}

// Runs the world on the boxes and prints the result. Returns the exit code.
static int find_and_print(const pairs_options *opt, const char *input_name,
                          const box_array *boxes)
{
    bpx_world_def def = bpx_default_world_def();
    def.backend = opt->backend;
    def.simd = opt->simd;
    if (opt->threads > 0) {
        def.worker_count = opt->threads;
    }
    def.capacity_hint = (uint32_t)boxes->count; // box_csv_read caps it at BPX_MAX_BOXES
    def.opencl_platform = opt->opencl_platform;
    def.opencl_device = opt->opencl_device;

    bpx_world *world = NULL;
    bpx_status status = bpx_world_create(&def, &world);
    if (status != BPX_OK) {
        report_create_error(opt, status);
        return CLI_EXIT_ERROR;
    }

    // The reader already rejects what the library would, so a failure here is unexpected;
    // report the library's own message. An empty array still needs a non-null pointer.
    bpx_box none;
    const bpx_box *data = boxes->count > 0 ? boxes->data : &none;
    status = bpx_world_set_boxes(world, data, (uint32_t)boxes->count);
    if (status == BPX_OK) {
        status = bpx_world_collide(world);
    }
    if (status != BPX_OK) {
        const bpx_error *error = bpx_world_error(world);
        const char *detail = error->message[0] ? error->message : bpx_status_string(status);
        if (error->index != UINT32_MAX) {
            cli_error(command, "%s: box %u (0-based): %s", input_name, (unsigned)error->index,
                      detail);
        } else {
            cli_error(command, "%s: %s", input_name, detail);
        }
        bpx_world_destroy(world);
        return CLI_EXIT_ERROR;
    }

    size_t count = 0;
    const bpx_pair *pairs = bpx_world_pairs(world, &count);
    int written;
    errno = 0;
    if (opt->count_only) {
        written = printf("%zu\n", count) < 0 ? -1 : 0;
    } else {
        written = write_pairs(stdout, pairs, count);
    }
    if (fflush(stdout) != 0) {
        written = -1;
    }
    bpx_world_destroy(world);
    if (written != 0) {
        cli_error(command, "write error: %s", errno ? strerror(errno) : "unknown");
        return CLI_EXIT_ERROR;
    }
    return CLI_EXIT_OK;
}

int cmd_pairs(int argc, char **argv)
{
    pairs_options opt = {NULL, false, BPX_BACKEND_AUTO, BPX_SIMD_AUTO, 0, 0, 0};
    int parsed = parse_args(argc, argv, &opt);
    if (parsed != PARSE_CONTINUE) {
        return parsed;
    }

    bool from_stdin = strcmp(opt.path, "-") == 0;
    const char *input_name = from_stdin ? "<stdin>" : opt.path;
    FILE *in = from_stdin ? stdin : fopen(opt.path, "rb");
    if (in == NULL) {
        cli_error(command, "cannot open \"%s\": %s", opt.path, strerror(errno));
        return CLI_EXIT_ERROR;
    }

    box_array boxes = {NULL, 0, 0};
    char message[512];
    int read_status = box_csv_read(in, input_name, &boxes, message, sizeof message);
    if (!from_stdin) {
        fclose(in);
    }
    int exit_code;
    if (read_status != 0) {
        cli_error(command, "%s", message);
        exit_code = CLI_EXIT_ERROR;
    } else {
        exit_code = find_and_print(&opt, input_name, &boxes);
    }
    box_array_free(&boxes);
    return exit_code;
}
