// bpx devices: lists the OpenCL platforms' devices, numbered P:D as --device takes them.
// SPDX-License-Identifier: MIT
#include <stdio.h>
#include <stdlib.h>

#include <bpx/opencl.h>

#include "cli.h"

static const char *const command = "devices";

static void print_help(void)
{
    printf("usage: bpx devices\n"
           "\n"
           "Lists every OpenCL device, one per line: P:D (platform and device number, as\n"
           "`--device P:D` takes them), type, compute units, global memory, name, platform and\n"
           "version, then which device the opencl backend picks by default.\n"
           "Exit status: 0 success (also when there is no device: the list is empty), 1 error,\n"
           "2 usage error.\n");
}

static const char *type_name(int type)
{
    return type == BPX_OPENCL_GPU           ? "gpu"
           : type == BPX_OPENCL_CPU         ? "cpu"
           : type == BPX_OPENCL_ACCELERATOR ? "accelerator"
                                            : "other";
}

int cmd_devices(int argc, char **argv)
{
    for (int i = 1; i < argc; i++) {
        if (cli_is_help(argv[i])) {
            print_help();
            return CLI_EXIT_OK;
        }
        return cli_usage_error(command, "unexpected argument \"%s\"", argv[i]);
    }
    int count = 0;
    bpx_status status = bpx_opencl_devices(NULL, 0, &count);
    bpx_backend_info info = bpx_backend_query(BPX_BACKEND_OPENCL);
    if (status == BPX_ERR_BACKEND_UNAVAILABLE) {
        printf("no OpenCL devices (%s)\n", info.available ? "none listed" : info.reason);
        return fflush(stdout) == 0 ? CLI_EXIT_OK : CLI_EXIT_ERROR;
    }
    bpx_opencl_device *devices = count > 0 ? malloc(sizeof *devices * (size_t)count) : NULL;
    if (status == BPX_OK && count > 0 && !devices)
        status = BPX_ERR_OUT_OF_MEMORY;
    if (status == BPX_OK && count > 0)
        status = bpx_opencl_devices(devices, count, &count);
    if (status != BPX_OK) {
        cli_error(command, "cannot list OpenCL devices: %s", bpx_status_string(status));
        free(devices);
        return CLI_EXIT_ERROR;
    }
    for (int k = 0; k < count; k++) {
        const bpx_opencl_device *d = &devices[k];
        printf("%d:%d  %-11s  %3d units  %6.1f GiB  %s  (%s; %s)\n", d->platform, d->device,
               type_name(d->type), d->compute_units, (double)d->global_memory / (1u << 30), d->name,
               d->platform_name, d->version);
    }
    printf("opencl backend: %s\n", info.available ? info.detail : info.reason);
    free(devices);
    if (fflush(stdout) != 0) {
        cli_error(command, "write error");
        return CLI_EXIT_ERROR;
    }
    return CLI_EXIT_OK;
}
