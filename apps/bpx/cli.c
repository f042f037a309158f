// bpx command-line tool: argument helpers shared by the commands.
// SPDX-License-Identifier: MIT
#define _POSIX_C_SOURCE 200809L // clock_gettime
#include "cli.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static void print_error(const char *cmd, const char *fmt, va_list args)
{
    fprintf(stderr, "bpx %s: ", cmd);
    vfprintf(stderr, fmt, args);
    fputc('\n', stderr);
}

void cli_error(const char *cmd, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    print_error(cmd, fmt, args);
    va_end(args);
}

int cli_usage_error(const char *cmd, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    print_error(cmd, fmt, args);
    va_end(args);
    fprintf(stderr, "Try 'bpx %s --help'.\n", cmd);
    return CLI_EXIT_USAGE;
}

bool cli_is_help(const char *arg)
{
    return strcmp(arg, "-h") == 0 || strcmp(arg, "--help") == 0;
}

bool cli_is_flag(const char *arg, const char *flag)
{
    return strcmp(arg, flag) == 0;
}

cli_match cli_flag_value(int argc, char **argv, int *index, const char *flag, const char **value)
{
    const char *arg = argv[*index];
    size_t len = strlen(flag);
    if (strncmp(arg, flag, len) != 0) {
        return CLI_NO_MATCH;
    }
    if (arg[len] == '=') {
        *value = arg + len + 1;
        return CLI_MATCH;
    }
    if (arg[len] != '\0') {
        return CLI_NO_MATCH; // a longer flag sharing the prefix, e.g. --threadsX
    }
    if (*index + 1 >= argc) {
        return CLI_MISSING_VALUE;
    }
    *index += 1;
    *value = argv[*index];
    return CLI_MATCH;
}

bool cli_parse_int(const char *text, long min, long max, int *out)
{
    // strtol alone accepts leading spaces and empty strings; insist on a plain number.
    char first = text[0];
    if (!(first == '-' || first == '+' || (first >= '0' && first <= '9'))) {
        return false;
    }
    char *end;
    errno = 0;
    long value = strtol(text, &end, 10);
    if (errno != 0 || *end != '\0' || value < min || value > max) {
        return false;
    }
    *out = (int)value;
    return true;
}

int cli_parse_backend(const char *cmd, const char *text, bpx_backend *out)
{
    if (bpx_backend_from_name(text, out) == BPX_OK) {
        return CLI_EXIT_OK;
    }
    fprintf(stderr, "bpx %s: unknown backend \"%s\"; expected one of:", cmd, text);
    for (int b = 0; b < BPX_BACKEND_COUNT; b++) {
        const char *name = bpx_backend_name((bpx_backend)b);
        fprintf(stderr, " %s", name ? name : "?");
    }
    fprintf(stderr, "\nTry 'bpx %s --help'.\n", cmd);
    return CLI_EXIT_USAGE;
}

int cli_parse_simd(const char *cmd, const char *text, bpx_simd *out)
{
    if (bpx_simd_from_name(text, out) == BPX_OK) {
        return CLI_EXIT_OK;
    }
    fprintf(stderr, "bpx %s: unknown SIMD width \"%s\"; expected one of:", cmd, text);
    for (int s = 0; s < BPX_SIMD_COUNT; s++) {
        const char *name = bpx_simd_name((bpx_simd)s);
        fprintf(stderr, " %s", name ? name : "?");
    }
    fprintf(stderr, "\nTry 'bpx %s --help'.\n", cmd);
    return CLI_EXIT_USAGE;
}

double cli_now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

int cli_compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
