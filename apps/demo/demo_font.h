// bpx demo: a small built-in bitmap font (5 x 7 pixels, printable ASCII) for on-screen text.
// SPDX-License-Identifier: MIT
#pragma once

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/// Horizontal advance per character and line height, in pixels at scale 1.
#define DEMO_FONT_ADVANCE 6
#define DEMO_FONT_LINE 10

/// Width of text in pixels at the given scale.
int demo_font_text_width(const char *text, int scale);

/// Draws text with its top-left corner at (x, y) into an RGB24 image (3 bytes per pixel, rows top
/// first, no padding). Pixels outside the image are skipped; other characters than printable ASCII
/// are drawn as '?'. scale >= 1 magnifies each font pixel into scale x scale.
void demo_font_draw(unsigned char *rgb, int width, int height, int x, int y, const char *text,
                    const unsigned char colour[3], int scale);

#ifdef __cplusplus
}
#endif
