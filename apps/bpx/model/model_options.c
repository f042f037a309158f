// bpx model's flags: the parser (the help text is cmd_model.c's). SPDX-License-Identifier: MIT

#include <stdlib.h>
#include <string.h>

#include "model_cmd.h"

static bool parse_double(const char *text, double lo, double hi, double *out)
{
    char *end = NULL;
    double v = strtod(text, &end);
    if (end == text || *end != '\0' || !(v >= lo && v <= hi))
        return false;
    *out = v;
    return true;
}

int model_parse_args(int argc, char **argv, model_options *o)
{
    for (int k = 1; k < argc; k++) {
        const char *v = NULL;
        cli_match m;
        double d;
        int i;
#define FLAG(name) (m = cli_flag_value(argc, argv, &k, name, &v)) != CLI_NO_MATCH
#define NEED(ok, message)                                                                          \
    if (m == CLI_MISSING_VALUE || !(ok))                                                           \
        return cli_usage_error(command, message);
        if (cli_is_flag(argv[k], "--schedule")) {
            o->schedule = true;
        } else if (cli_is_flag(argv[k], "--paper")) {
            o->paper = true;
        } else if (FLAG("--m")) {
            NEED(cli_parse_int(v, 1, BPX_MODEL_MAX_M, &o->config.m), "--m wants 1..32");
        } else if (FLAG("--clock")) {
            NEED(parse_double(v, 1e-3, 1e6, &d), "--clock wants MHz, e.g. 108");
            o->config.clock_hz = d * 1e6;
        } else if (FLAG("--boxes")) {
            NEED(cli_parse_int(v, 1, MAX_SCENE_BOXES, &i), "--boxes wants 1..1000000");
            o->boxes = (uint32_t)i;
        } else if (FLAG("--trace")) {
            NEED(v[0] != '\0', "--trace wants a file name");
            o->trace_path = v;
        } else if (FLAG("--clocks")) {
            NEED(cli_parse_int(v, 0, 100000000, &o->clocks), "--clocks wants a count");
        } else if (FLAG("--cycles")) {
            NEED(cli_parse_int(v, 1, 10000000, &o->cycles), "--cycles wants a positive count");
            o->cycles_given = true;
        } else if (FLAG("--warmup")) {
            NEED(cli_parse_int(v, 0, 10000000, &o->warmup), "--warmup wants a count");
        } else if (FLAG("--seed")) {
            char *end = NULL;
            o->seed = m == CLI_MATCH ? strtoull(v, &end, 10) : 0;
            NEED(end && end != v && *end == '\0', "--seed wants an unsigned integer");
        } else if (FLAG("--store")) {
            bool found = false;
            for (int s = 0; s < BPX_MODEL_STORE_COUNT && m == CLI_MATCH; s++)
                if (strcmp(v, bpx_model_store_name((bpx_model_store)s)) == 0) {
                    o->config.store = (bpx_model_store)s;
                    found = true;
                }
            NEED(found, "--store wants on-chip, ssram or stream");
        } else if (FLAG("--ram-depth")) {
            NEED(cli_parse_int(v, 4, 1 << 20, &i), "--ram-depth wants 4..1048576");
            o->config.ram_depth = (uint32_t)i;
        } else if (FLAG("--fifo-depth")) {
            NEED(cli_parse_int(v, 1, 1 << 20, &i), "--fifo-depth wants 1..1048576");
            o->config.fifo_depth = (uint32_t)i;
        } else if (FLAG("--setup-us")) {
            NEED(parse_double(v, 0, 1e9, &d), "--setup-us wants microseconds >= 0");
            o->config.link.setup_ns = d * 1e3;
        } else if (FLAG("--link-mbs")) {
            NEED(parse_double(v, 1e-6, 1e9, &d), "--link-mbs wants MB/s > 0");
            o->config.link.bytes_per_s = d * 1e6;
        } else if (FLAG("--register-us")) {
            NEED(parse_double(v, 0, 1e9, &d), "--register-us wants microseconds >= 0");
            o->config.link.register_ns = d * 1e3;
        } else {
            return cli_usage_error(command, "unknown argument \"%s\"", argv[k]);
        }
#undef FLAG
#undef NEED
    }
    if (o->trace_path && o->boxes)
        return cli_usage_error(command, "--boxes and --trace exclude each other");
    if (o->paper && (o->trace_path || o->boxes || o->schedule))
        return cli_usage_error(command, "--paper runs its own scenes: no --boxes, --trace or "
                                        "--schedule");
    if (o->schedule && o->trace_path)
        return cli_usage_error(command, "--schedule takes --boxes, not --trace");
    bpx_error err;
    if (bpx_model_check_config(&o->config, &err) != BPX_OK)
        return cli_usage_error(command, "%s", err.message);
    return CLI_EXIT_OK;
}
