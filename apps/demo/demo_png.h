// bpx demo: PNG files through libpng, opened at run time (when the build found png.h).
// SPDX-License-Identifier: MIT
#pragma once

#include <stdbool.h>

#include "demo_sim.h"

#ifdef __cplusplus
extern "C" {
#endif

/// Whether PNG files can be written and read: this build has libpng's header (found when it was
/// configured) and libpng (libpng16.so.16) loads at run time. The first call loads it.
bool demo_png_available(void);

/// NULL when PNG files can be written, else why not, naming what is missing (the library that
/// cannot be loaded, or the header the build did not find) and what to install.
const char *demo_png_unavailable(void);

/// Writes an RGB24 image (rows top first, width * 3 bytes each) as an 8-bit RGB PNG.
/// Returns 0, or -1 with a message (no libpng, cannot create, write error).
int demo_png_write(const char *path, const unsigned char *rgb, int width, int height,
                   demo_error *err);

/// Reads a PNG file as RGB24 (any PNG libpng reads is converted). *rgb is released with free().
/// Returns 0, or -1 with a message; on error nothing is allocated.
int demo_png_read(const char *path, unsigned char **rgb, int *width, int *height, demo_error *err);

#ifdef __cplusplus
}
#endif
