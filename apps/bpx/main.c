// bpx command-line tool: git-style dispatch, `bpx <command> [args]`.
// SPDX-License-Identifier: MIT
//
// Exit codes (every command):
//   0  success
//   1  runtime or input error: unreadable file, malformed data, library error, write error
//   2  usage error: unknown command or flag, missing or bad flag value
#include <stdio.h>
#include <string.h>

#include "cli.h"

typedef struct cli_command {
    const char *name;
    cli_command_fn *run;
    const char *summary;
} cli_command;

// Adding a command is one line here plus its declaration in cli.h.
static const cli_command commands[] = {
    {"pairs", cmd_pairs, "print the overlapping pairs of boxes read from a CSV file"},
    {"query", cmd_query, "ray casts, region, sphere and swept-box queries on boxes from a CSV file"},
    {"backends", cmd_backends, "list the backends and SIMD widths usable on this machine"},
    {"devices", cmd_devices, "list the OpenCL devices (P:D for --device) of the opencl backend"},
    {"bench", cmd_bench, "time every backend side by side on the same scenes"},
    {"model", cmd_model, "the paper's FPGA clock by clock: timings, Table 1 schedule, Table 2"},
    {"demo", cmd_demo, "the paper's test scenario: spheres in a box, timed, pictures, trace"},
};

enum { COMMAND_COUNT = sizeof commands / sizeof commands[0] };

static void print_usage(FILE *out)
{
    fprintf(out, "usage: bpx <command> [args]\n"
                 "       bpx <command> --help\n"
                 "       bpx --help | --version\n"
                 "\n"
                 "Broad-phase collision detection: all overlapping pairs of axis-aligned boxes.\n"
                 "\n"
                 "commands:\n");
    int width = 0;
    for (int c = 0; c < COMMAND_COUNT; c++) {
        int len = (int)strlen(commands[c].name);
        width = len > width ? len : width;
    }
    for (int c = 0; c < COMMAND_COUNT; c++) {
        fprintf(out, "  %-*s  %s\n", width, commands[c].name, commands[c].summary);
    }
    fprintf(out, "\n"
                 "exit codes:\n"
                 "  0  success\n"
                 "  1  runtime or input error (bad file, bad data, library error)\n"
                 "  2  usage error (unknown command or flag, bad flag value)\n");
}

static const cli_command *find_command(const char *name)
{
    for (int c = 0; c < COMMAND_COUNT; c++) {
        if (strcmp(commands[c].name, name) == 0) {
            return &commands[c];
        }
    }
    return NULL;
}

static int unknown_command(const char *name)
{
    fprintf(stderr, "bpx: unknown command \"%s\"\nTry 'bpx --help'.\n", name);
    return CLI_EXIT_USAGE;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        print_usage(stderr);
        return CLI_EXIT_USAGE;
    }
    const char *name = argv[1];
    if (cli_is_help(name)) {
        print_usage(stdout);
        return CLI_EXIT_OK;
    }
    if (strcmp(name, "--version") == 0) {
        printf("bpx %s\n", bpx_version());
        return CLI_EXIT_OK;
    }
    if (strcmp(name, "help") == 0) {
        // `bpx help CMD` is `bpx CMD --help`.
        if (argc < 3) {
            print_usage(stdout);
            return CLI_EXIT_OK;
        }
        const cli_command *command = find_command(argv[2]);
        if (command == NULL) {
            return unknown_command(argv[2]);
        }
        char help_flag[] = "--help";
        char *help_argv[] = {argv[2], help_flag, NULL};
        return command->run(2, help_argv);
    }
    if (name[0] == '-') {
        fprintf(stderr, "bpx: unknown option \"%s\"\nTry 'bpx --help'.\n", name);
        return CLI_EXIT_USAGE;
    }
    const cli_command *command = find_command(name);
    if (command == NULL) {
        return unknown_command(name);
    }
    return command->run(argc - 1, argv + 1);
}
