// bpx backends: lists the backends (or, with --simd, the SIMD widths) and whether each is
// usable on this machine. One row per line, columns aligned, name first, so scripts can use
// `bpx backends | awk '$2 == "available" { print $1 }'`.
// SPDX-License-Identifier: MIT
#include <stdio.h>
#include <string.h>

#include "cli.h"

static const char *const command = "backends";

static void print_help(void)
{
    printf("usage: bpx backends [--simd]\n"
           "\n"
           "Lists every backend, one per line: its name, \"available\" or \"unavailable\", then\n"
           "why not (when unavailable) or details such as the SIMD width and lanes.\n"
           "\n"
           "options:\n"
           "  --simd       list the SIMD widths of the brute backend instead: name,\n"
           "               \"supported\" or \"unsupported\", lanes per comparator step\n"
           "  -h, --help   show this help\n");
}

static int name_width(const char *name, int width)
{
    int length = (int)strlen(name);
    return length > width ? length : width;
}

// Prints "NAME  STATE  TEXT" with the first two columns padded; no trailing blanks.
static void print_row(int width, const char *name, const char *state, int state_width,
                      const char *text)
{
    if (text[0] == '\0') {
        printf("%-*s  %s\n", width, name, state);
    } else {
        printf("%-*s  %-*s  %s\n", width, name, state_width, state, text);
    }
}

static void list_backends(void)
{
    int width = 0;
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        const char *name = bpx_backend_name((bpx_backend)b);
        width = name_width(name ? name : "?", width);
    }
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        bpx_backend_info info = bpx_backend_query((bpx_backend)b);
        const char *name = info.name ? info.name : bpx_backend_name((bpx_backend)b);
        const char *text = info.available ? info.detail : info.reason;
        print_row(width, name ? name : "?", info.available ? "available" : "unavailable",
                  (int)strlen("unavailable"), text ? text : "");
    }
}

static void list_simd(void)
{
    int width = 0;
    for (int s = 0; s < BPX_SIMD_COUNT; s++) {
        const char *name = bpx_simd_name((bpx_simd)s);
        width = name_width(name ? name : "?", width);
    }
    bpx_simd best = bpx_simd_best();
    for (int s = 0; s < BPX_SIMD_COUNT; s++) {
        bpx_simd simd = (bpx_simd)s;
        const char *name = bpx_simd_name(simd);
        char text[96];
        if (simd == BPX_SIMD_AUTO) {
            // auto is not a width of its own: show what it resolves to.
            const char *best_name = bpx_simd_name(best);
            int lanes = bpx_simd_lanes(best);
            snprintf(text, sizeof text, "%d lane%s (%s)", lanes, lanes == 1 ? "" : "s",
                     best_name ? best_name : "?");
        } else {
            int lanes = bpx_simd_lanes(simd);
            snprintf(text, sizeof text, "%d lane%s", lanes, lanes == 1 ? "" : "s");
        }
        bool supported = simd == BPX_SIMD_AUTO || bpx_simd_supported(simd);
        print_row(width, name ? name : "?", supported ? "supported" : "unsupported",
                  (int)strlen("unsupported"), text);
    }
}

int cmd_backends(int argc, char **argv)
{
    bool simd = false;
    for (int i = 1; i < argc; i++) {
        if (cli_is_help(argv[i])) {
            print_help();
            return CLI_EXIT_OK;
        }
        if (cli_is_flag(argv[i], "--simd")) {
            simd = true;
        } else if (argv[i][0] == '-') {
            return cli_usage_error(command, "unknown option \"%s\"", argv[i]);
        } else {
            return cli_usage_error(command, "unexpected argument \"%s\"", argv[i]);
        }
    }
    if (simd) {
        list_simd();
    } else {
        list_backends();
    }
    if (fflush(stdout) != 0) {
        cli_error(command, "write error");
        return CLI_EXIT_ERROR;
    }
    return CLI_EXIT_OK;
}
