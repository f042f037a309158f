// bpx demo: a live window through SDL2, opened at run time (when the build found SDL.h): the
// renderer's image blitted into a window each frame. SPDX-License-Identifier: MIT
#pragma once

#include <stdbool.h>

#include "demo_sim.h"

#ifdef __cplusplus
extern "C" {
#endif

/// Whether the window can be opened: this build has SDL2's header (found when it was configured)
/// and SDL2 (libSDL2-2.0.so.0) loads at run time. The first call loads it.
bool demo_window_available(void);

/// NULL when the window is available, else why not, naming what is missing (the library that
/// cannot be loaded, or the header the build did not find) and what to install.
const char *demo_window_unavailable(void);

typedef struct demo_window demo_window;

/// Opens a window of width x height pixels. Returns 0, or -1 with a message (no SDL2, no display,
/// SDL error).
int demo_window_open(int width, int height, const char *title, demo_window **out, demo_error *err);

/// Shows an RGB24 image of the window's size. If capture is not NULL it receives, as RGB24, the
/// pixels SDL drew into the window (read back from SDL's renderer before presenting).
/// Returns 0, or -1 with a message.
int demo_window_show(demo_window *window, const unsigned char *rgb, unsigned char *capture,
                     demo_error *err);

/// Handles pending window events; true once the window was closed or Escape or Q was pressed.
bool demo_window_should_close(demo_window *window);

/// SDL's video driver ("x11", "wayland", ...) and renderer ("software", "opengl", ...).
const char *demo_window_driver(const demo_window *window);
const char *demo_window_renderer(const demo_window *window);

/// Closes the window and shuts SDL's video down. NULL is allowed.
void demo_window_close(demo_window *window);

#ifdef __cplusplus
}
#endif
