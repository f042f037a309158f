// bpx demo: PNG files through libpng (when the build found it). SPDX-License-Identifier: MIT
#pragma once

#include <stdbool.h>

#include "demo_sim.h"

#ifdef __cplusplus
extern "C" {
#endif

/// Whether this build can write PNG files (libpng was found at build time).
bool demo_png_available(void);

/// Writes an RGB24 image (rows top first, width * 3 bytes each) as an 8-bit RGB PNG.
/// Returns 0, or -1 with a message (no libpng in this build, cannot create, write error).
int demo_png_write(const char *path, const unsigned char *rgb, int width, int height,
                   demo_error *err);

/// Reads a PNG file as RGB24 (any PNG libpng reads is converted). *rgb is released with free().
/// Returns 0, or -1 with a message; on error nothing is allocated.
int demo_png_read(const char *path, unsigned char **rgb, int *width, int *height, demo_error *err);

#ifdef __cplusplus
}
#endif
