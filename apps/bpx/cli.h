// bpx command-line tool: declarations shared by main.c and the commands.
// SPDX-License-Identifier: MIT
#pragma once

#include <stdbool.h>

#include <bpx/bpx.h>

// Exit codes of every command (also listed in `bpx --help`).
enum {
    CLI_EXIT_OK = 0,    // success
    CLI_EXIT_ERROR = 1, // runtime or input error: bad file, bad data, library error, write error
    CLI_EXIT_USAGE = 2, // usage error: unknown command or flag, missing or bad flag value
};

// Every command has this shape. argv[0] is the command name ("pairs"), argv[argc] is NULL.
// Returns the process exit code; commands never call exit().
typedef int cli_command_fn(int argc, char **argv);

cli_command_fn cmd_pairs;
cli_command_fn cmd_query;
cli_command_fn cmd_backends;
cli_command_fn cmd_bench;
cli_command_fn cmd_model;
cli_command_fn cmd_devices;
cli_command_fn cmd_demo;

#if defined(__GNUC__)
#define CLI_PRINTF(fmt_index, first_arg) __attribute__((format(printf, fmt_index, first_arg)))
#else
#define CLI_PRINTF(fmt_index, first_arg)
#endif

// Prints "bpx CMD: message" and a newline to stderr.
void cli_error(const char *cmd, const char *fmt, ...) CLI_PRINTF(2, 3);

// Prints a usage error plus a pointer to --help on stderr; returns CLI_EXIT_USAGE.
int cli_usage_error(const char *cmd, const char *fmt, ...) CLI_PRINTF(2, 3);

// True for "-h" and "--help".
bool cli_is_help(const char *arg);

// True when arg is exactly the value-less flag (e.g. "--count").
bool cli_is_flag(const char *arg, const char *flag);

typedef enum cli_match {
    CLI_NO_MATCH,      // arg is not this flag
    CLI_MATCH,         // *value is set; *index was advanced past a separate value
    CLI_MISSING_VALUE, // the flag is last on the command line with no value
} cli_match;

// Matches argv[*index] against a flag taking a value, as "--flag=value" or "--flag value".
cli_match cli_flag_value(int argc, char **argv, int *index, const char *flag, const char **value);

// Seconds on a monotonic clock, for timings.
double cli_now_s(void);

// qsort comparator for doubles, ascending.
int cli_compare_double(const void *a, const void *b);

// Parses a whole decimal integer in [min, max]. Returns false on anything else.
bool cli_parse_int(const char *text, long min, long max, int *out);

// Parse names with the library; on failure print a usage error listing the valid names and
// return CLI_EXIT_USAGE, else CLI_EXIT_OK.
int cli_parse_backend(const char *cmd, const char *text, bpx_backend *out);
int cli_parse_simd(const char *cmd, const char *text, bpx_simd *out);
