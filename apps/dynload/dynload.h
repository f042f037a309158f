// bpx's programs: optional libraries opened at run time (dlopen), so that the bpx program starts
// and runs its other commands on a machine without them: libpng and SDL2 for the demo's pictures
// and window (apps/demo), the benchmark peers' module and through it Bullet and Box2D
// (bench/peers). SPDX-License-Identifier: MIT
//
// Test hook: the environment variable BPX_NO_DLOPEN makes loads fail as if the library were not
// installed: "1" (or "all") refuses every load, a comma-separated list of names refuses those
// (each matched against the name asked for and, for a path, its last component), e.g.
// BPX_NO_DLOPEN=libSDL2-2.0.so.0,bpx_peers.so. Unset, empty or "0": no effect.
#pragma once

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/// A function found in a library: cast it to its own type before calling it.
typedef void (*bpx_dynload_fn)(void);

/// Opens the shared library `name` (a soname, searched as the dynamic linker does, or a path)
/// and keeps it open for the life of the process. Returns the handle, or NULL with a message in
/// err that names the library: "libpng16.so.16 cannot be loaded (libpng16.so.16: cannot open
/// shared object file: No such file or directory)", or "... (refused by BPX_NO_DLOPEN, a test
/// hook)".
void *bpx_dynload_open(const char *name, char *err, size_t err_size);

/// The function `symbol` of a library from bpx_dynload_open, or NULL with a message in err that
/// names the library and the symbol.
bpx_dynload_fn bpx_dynload_symbol(void *handle, const char *name, const char *symbol, char *err,
                                  size_t err_size);

/// Whether BPX_NO_DLOPEN refuses loading `name` (see above).
bool bpx_dynload_refused(const char *name);

#ifdef __cplusplus
}
#endif
