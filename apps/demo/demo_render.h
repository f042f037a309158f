// bpx demo: stage 5, display. A small software renderer: a perspective view of the box from an
// upper corner (floor with a grid and shadows, the far walls, the box's edges) and shaded
// spheres, z-buffered and ray-traced per pixel; text drawn with the built-in bitmap font. One
// RGB24 image serves both outputs: PNG files and the SDL window. SPDX-License-Identifier: MIT
#pragma once

#include <stdint.h>

#include "demo_sim.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct demo_renderer demo_renderer;

/// Creates a renderer of width x height pixels (16 .. 8192 each) for a box of the given inner
/// size (m; x width, y height, z depth; see demo_params_box_size). The camera is placed so the
/// whole box fills the image. Returns 0, or -1 with a message.
int demo_renderer_create(int width, int height, const double box_size[3], demo_renderer **out,
                         demo_error *err);

/// Frees the renderer. NULL is allowed.
void demo_renderer_destroy(demo_renderer *renderer);

/// Draws n spheres of the given radius (m) at centres (x, y, z per sphere, m) into the image,
/// replacing what was there. Sphere i always has the same colour.
void demo_renderer_draw(demo_renderer *renderer, const double *centres, uint32_t n, double radius);

/// Writes lines of text over a darkened band at the top-left of the image.
void demo_renderer_overlay(demo_renderer *renderer, const char *const *lines, int count);

/// The image: RGB24, 3 bytes per pixel, rows top first, no padding (width * 3 bytes per row).
const unsigned char *demo_renderer_pixels(const demo_renderer *renderer);
int demo_renderer_width(const demo_renderer *renderer);
int demo_renderer_height(const demo_renderer *renderer);

#ifdef __cplusplus
}
#endif
