// SPDX-License-Identifier: MIT
// The fake CUDA runtime's side of nvcc's host code (runtime.c says what the fake is): the hooks
// every .cu object calls to register its fat binary and its kernels, and those a <<<>>> launch
// goes through.

// Exported whatever visibility the build sets: the library calls these from its own objects.
#pragma GCC visibility push(default)

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>

#include "runtime.h"

// The hooks that nvcc's host code calls (declared by crt/host_runtime.h and
// crt/device_functions.h, which are C++ only).
void **__cudaRegisterFatBinary(void *fatCubin);
void __cudaRegisterFatBinaryEnd(void **fatCubinHandle);
void __cudaUnregisterFatBinary(void **fatCubinHandle);
void __cudaRegisterFunction(void **fatCubinHandle, const char *hostFun, char *deviceFun,
                            const char *deviceName, int thread_limit, uint3 *tid, uint3 *bid,
                            dim3 *bDim, dim3 *gDim, int *wSize);
void __cudaRegisterVar(void **fatCubinHandle, char *hostVar, char *deviceAddress,
                       const char *deviceName, int ext, size_t size, int constant, int global);
char __cudaInitModule(void **fatCubinHandle);
unsigned __cudaPushCallConfiguration(dim3 gridDim, dim3 blockDim, size_t sharedMem,
                                     struct CUstream_st *stream);
cudaError_t __cudaPopCallConfiguration(dim3 *gridDim, dim3 *blockDim, size_t *sharedMem,
                                       void *stream);
cudaError_t __cudaGetKernel(cudaKernel_t *kernel, const void *func);
cudaError_t __cudaLaunchKernel(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                               size_t sharedMem, cudaStream_t stream);
cudaError_t __cudaLaunchKernel_ptsz(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                                    size_t sharedMem, cudaStream_t stream);

// The kernel handle (an opaque type of the header, completed here): one for every kernel.
struct CUkern_st {
    char unused;
};

static _Thread_local struct {
    bool pushed;
    dim3 grid, block;
    size_t shared;
    cudaStream_t stream;
} launch_config;
static void *fat_binary_handle;
static struct CUkern_st kernel_handle;

// Every .cu object registers its fat binary at load time: accepted and ignored. A <<<>>> launch
// pushes its configuration, the stub pops it and launches: the launch aborts, since every kernel
// the fake-device tests run is host code.

void **__cudaRegisterFatBinary(void *fatCubin)
{
    (void)fatCubin;
    return &fat_binary_handle;
}

void __cudaRegisterFatBinaryEnd(void **fatCubinHandle)
{
    (void)fatCubinHandle;
}

void __cudaUnregisterFatBinary(void **fatCubinHandle)
{
    (void)fatCubinHandle;
}

void __cudaRegisterFunction(void **fatCubinHandle, const char *hostFun, char *deviceFun,
                            const char *deviceName, int thread_limit, uint3 *tid, uint3 *bid,
                            dim3 *bDim, dim3 *gDim, int *wSize)
{
    (void)fatCubinHandle, (void)hostFun, (void)deviceFun, (void)deviceName, (void)thread_limit;
    (void)tid, (void)bid, (void)bDim, (void)gDim, (void)wSize;
}

void __cudaRegisterVar(void **fatCubinHandle, char *hostVar, char *deviceAddress,
                       const char *deviceName, int ext, size_t size, int constant, int global)
{
    (void)fatCubinHandle, (void)hostVar, (void)deviceAddress, (void)deviceName, (void)ext;
    (void)size, (void)constant, (void)global;
}

// Nonzero: the module is initialised (the managed runtime's flag).
char __cudaInitModule(void **fatCubinHandle)
{
    (void)fatCubinHandle;
    return 1;
}

// 0: go on to the kernel's stub.
unsigned __cudaPushCallConfiguration(dim3 gridDim, dim3 blockDim, size_t sharedMem,
                                     struct CUstream_st *stream)
{
    launch_config.pushed = true;
    launch_config.grid = gridDim;
    launch_config.block = blockDim;
    launch_config.shared = sharedMem;
    launch_config.stream = stream;
    return 0;
}

cudaError_t __cudaPopCallConfiguration(dim3 *gridDim, dim3 *blockDim, size_t *sharedMem,
                                       void *stream)
{
    if (!launch_config.pushed)
        fake_die("__cudaPopCallConfiguration", "no launch configuration was pushed");
    launch_config.pushed = false;
    *gridDim = launch_config.grid;
    *blockDim = launch_config.block;
    *sharedMem = launch_config.shared;
    *(cudaStream_t *)stream = launch_config.stream;
    return cudaSuccess;
}

cudaError_t __cudaGetKernel(cudaKernel_t *kernel, const void *func)
{
    (void)func;
    *kernel = &kernel_handle;
    return cudaSuccess;
}

__attribute__((noreturn)) static void launched(void)
{
    fputs("fake cuda: a kernel launch reached the fake runtime\n", stderr);
    fflush(stderr);
    abort();
}

cudaError_t __cudaLaunchKernel(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                               size_t sharedMem, cudaStream_t stream)
{
    (void)kernel, (void)gridDim, (void)blockDim, (void)args, (void)sharedMem, (void)stream;
    launched();
}

cudaError_t __cudaLaunchKernel_ptsz(cudaKernel_t kernel, dim3 gridDim, dim3 blockDim, void **args,
                                    size_t sharedMem, cudaStream_t stream)
{
    (void)kernel, (void)gridDim, (void)blockDim, (void)args, (void)sharedMem, (void)stream;
    launched();
}

cudaError_t cudaLaunchKernel(const void *func, dim3 gridDim, dim3 blockDim, void **args,
                             size_t sharedMem, cudaStream_t stream)
{
    (void)func, (void)gridDim, (void)blockDim, (void)args, (void)sharedMem, (void)stream;
    launched();
}

cudaError_t cudaLaunchKernelExC(const cudaLaunchConfig_t *config, const void *func, void **args)
{
    (void)config, (void)func, (void)args;
    launched();
}

#pragma GCC visibility pop
