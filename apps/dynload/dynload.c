// Optional libraries at run time: see dynload.h. SPDX-License-Identifier: MIT
#define _POSIX_C_SOURCE 200809L
#include "dynload.h"

#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

bool bpx_dynload_refused(const char *name)
{
    const char *hook = getenv("BPX_NO_DLOPEN");
    if (!hook || !*hook || strcmp(hook, "0") == 0)
        return false;
    if (strcmp(hook, "1") == 0 || strcmp(hook, "all") == 0)
        return true;
    const char *slash = strrchr(name, '/');
    const char *base = slash ? slash + 1 : name;
    for (const char *item = hook; *item;) {
        size_t len = strcspn(item, ",");
        if (len > 0 && ((strlen(name) == len && strncmp(item, name, len) == 0) ||
                        (strlen(base) == len && strncmp(item, base, len) == 0)))
            return true;
        item += len;
        if (*item == ',')
            item++;
    }
    return false;
}

void *bpx_dynload_open(const char *name, char *err, size_t err_size)
{
    if (bpx_dynload_refused(name)) {
        if (err && err_size)
            snprintf(err, err_size, "%s cannot be loaded (refused by BPX_NO_DLOPEN, a test hook)",
                     name);
        return NULL;
    }
    void *handle = dlopen(name, RTLD_NOW | RTLD_LOCAL);
    if (!handle && err && err_size) {
        const char *why = dlerror();
        snprintf(err, err_size, "%s cannot be loaded (%s)", name, why ? why : "unknown error");
    }
    return handle;
}

bpx_dynload_fn bpx_dynload_symbol(void *handle, const char *name, const char *symbol, char *err,
                                  size_t err_size)
{
    dlerror();
    void *address = dlsym(handle, symbol);
    if (!address) {
        if (err && err_size)
            snprintf(err, err_size, "%s has no %s: not the library expected", name, symbol);
        return NULL;
    }
    // POSIX guarantees that an object pointer from dlsym converts to a function pointer.
    bpx_dynload_fn fn;
    memcpy(&fn, &address, sizeof fn);
    return fn;
}
