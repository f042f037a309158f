// bpx model in a build without the FPGA model (-DBPX_MODEL=OFF): --help says so, and running it
// is an error that says so. SPDX-License-Identifier: MIT
#include <stdio.h>

#include "cli.h"

static const char not_built[] = "the FPGA model is not in this build (configured with "
                                "-DBPX_MODEL=OFF; configure with -DBPX_MODEL=ON and build again)";

int cmd_model(int argc, char **argv)
{
    for (int k = 1; k < argc; k++) {
        if (cli_is_help(argv[k])) {
            printf("usage: bpx model [--m M] [--clock MHZ] [--boxes N | --trace FILE] [--schedule] "
                   "[--paper]\n\n"
                   "The paper's FPGA clock by clock: not available here, %s.\n",
                   not_built);
            return CLI_EXIT_OK;
        }
    }
    cli_error("model", "%s", not_built);
    return CLI_EXIT_ERROR;
}
