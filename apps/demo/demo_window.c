// bpx demo: the SDL2 window (see demo_window.h), SDL2 opened at run time (dlopen of
// libSDL2-2.0.so.0), so that bpx starts without it. SPDX-License-Identifier: MIT
#include "demo_window.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(BPX_DEMO_WINDOW)
#include <SDL.h>

#include "dynload.h"

#if defined(__APPLE__)
#define SDL_LIBRARY "libSDL2-2.0.0.dylib"
#else
#define SDL_LIBRARY "libSDL2-2.0.so.0"
#endif

// The functions of SDL2 the window calls, each with its type from SDL.h; called as sdl.F(...).
#define SDL_FUNCTIONS(X)                                                                           \
    X(SDL_InitSubSystem)                                                                           \
    X(SDL_QuitSubSystem)                                                                           \
    X(SDL_Quit)                                                                                    \
    X(SDL_GetError)                                                                                \
    X(SDL_CreateWindow)                                                                            \
    X(SDL_DestroyWindow)                                                                           \
    X(SDL_CreateRenderer)                                                                          \
    X(SDL_GetRendererInfo)                                                                         \
    X(SDL_DestroyRenderer)                                                                         \
    X(SDL_CreateTexture)                                                                           \
    X(SDL_UpdateTexture)                                                                           \
    X(SDL_DestroyTexture)                                                                          \
    X(SDL_RenderClear)                                                                             \
    X(SDL_RenderCopy)                                                                              \
    X(SDL_RenderReadPixels)                                                                        \
    X(SDL_RenderPresent)                                                                           \
    X(SDL_PollEvent)                                                                               \
    X(SDL_GetCurrentVideoDriver)

#define SDL_POINTER(f) __typeof__(&f) f;
static struct {
    SDL_FUNCTIONS(SDL_POINTER)
} sdl;

static pthread_once_t sdl_once = PTHREAD_ONCE_INIT;
static char sdl_missing[512]; // empty once SDL2 is loaded

static void load_sdl(void)
{
    void *handle = bpx_dynload_open(SDL_LIBRARY, sdl_missing, sizeof sdl_missing);
#define SDL_LOAD(f)                                                                                \
    if (handle && !(sdl.f = (__typeof__(&f))bpx_dynload_symbol(handle, SDL_LIBRARY, #f,            \
                                                                sdl_missing, sizeof sdl_missing)))     \
        handle = NULL;
    SDL_FUNCTIONS(SDL_LOAD)
#undef SDL_LOAD
    if (handle)
        sdl_missing[0] = '\0';
    else
        strncat(sdl_missing, "; install SDL2 (Debian: libsdl2-2.0-0) for --window",
                sizeof sdl_missing - strlen(sdl_missing) - 1);
}

const char *demo_window_unavailable(void)
{
    pthread_once(&sdl_once, load_sdl);
    return sdl_missing[0] ? sdl_missing : NULL;
}

struct demo_window {
    SDL_Window *window;
    SDL_Renderer *renderer;
    SDL_Texture *texture;
    int width, height;
    bool closed;
    char renderer_name[64];
};

static int sdl_fail(demo_error *err, const char *what)
{
    if (err)
        snprintf(err->message, sizeof err->message, "%s: %s", what, sdl.SDL_GetError());
    return -1;
}

int demo_window_open(int width, int height, const char *title, demo_window **out, demo_error *err)
{
    *out = NULL;
    const char *missing = demo_window_unavailable();
    if (missing) {
        if (err)
            snprintf(err->message, sizeof err->message, "no window: %.*s",
                     (int)sizeof err->message - 16, missing);
        return -1;
    }
    if (sdl.SDL_InitSubSystem(SDL_INIT_VIDEO) != 0)
        return sdl_fail(err, "cannot start SDL video (is there a display? try xvfb-run)");
    demo_window *w = calloc(1, sizeof *w);
    if (!w) {
        sdl.SDL_QuitSubSystem(SDL_INIT_VIDEO);
        if (err)
            snprintf(err->message, sizeof err->message, "out of memory");
        return -1;
    }
    w->width = width;
    w->height = height;
    w->window = sdl.SDL_CreateWindow(title, SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, width,
                                 height, SDL_WINDOW_SHOWN);
    if (!w->window) {
        sdl_fail(err, "cannot open a window");
        demo_window_close(w);
        return -1;
    }
    // Any renderer will do for a blit; fall back to SDL's software renderer (no GPU, Xvfb).
    w->renderer = sdl.SDL_CreateRenderer(w->window, -1, 0);
    if (!w->renderer)
        w->renderer = sdl.SDL_CreateRenderer(w->window, -1, SDL_RENDERER_SOFTWARE);
    if (!w->renderer) {
        sdl_fail(err, "cannot create an SDL renderer");
        demo_window_close(w);
        return -1;
    }
    SDL_RendererInfo info;
    snprintf(w->renderer_name, sizeof w->renderer_name, "%s",
             sdl.SDL_GetRendererInfo(w->renderer, &info) == 0 ? info.name : "unknown");
    w->texture = sdl.SDL_CreateTexture(w->renderer, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING,
                                   width, height);
    if (!w->texture) {
        sdl_fail(err, "cannot create an SDL texture");
        demo_window_close(w);
        return -1;
    }
    *out = w;
    return 0;
}

int demo_window_show(demo_window *w, const unsigned char *rgb, unsigned char *capture,
                     demo_error *err)
{
    if (sdl.SDL_UpdateTexture(w->texture, NULL, rgb, w->width * 3) != 0)
        return sdl_fail(err, "cannot update the window's texture");
    if (sdl.SDL_RenderClear(w->renderer) != 0 ||
        sdl.SDL_RenderCopy(w->renderer, w->texture, NULL, NULL) != 0)
        return sdl_fail(err, "cannot draw into the window");
    // Read back before presenting: after SDL_RenderPresent the back buffer is undefined.
    if (capture &&
        sdl.SDL_RenderReadPixels(w->renderer, NULL, SDL_PIXELFORMAT_RGB24, capture, w->width * 3) != 0)
        return sdl_fail(err, "cannot read the window's pixels back");
    sdl.SDL_RenderPresent(w->renderer);
    return 0;
}

bool demo_window_should_close(demo_window *w)
{
    SDL_Event event;
    while (sdl.SDL_PollEvent(&event)) {
        if (event.type == SDL_QUIT)
            w->closed = true;
        else if (event.type == SDL_KEYDOWN &&
                 (event.key.keysym.sym == SDLK_ESCAPE || event.key.keysym.sym == SDLK_q))
            w->closed = true;
    }
    return w->closed;
}

const char *demo_window_driver(const demo_window *w)
{
    (void)w;
    const char *driver = sdl.SDL_GetCurrentVideoDriver();
    return driver ? driver : "none";
}

const char *demo_window_renderer(const demo_window *w)
{
    return w->renderer_name;
}

void demo_window_close(demo_window *w)
{
    if (!w)
        return;
    if (w->texture)
        sdl.SDL_DestroyTexture(w->texture);
    if (w->renderer)
        sdl.SDL_DestroyRenderer(w->renderer);
    if (w->window)
        sdl.SDL_DestroyWindow(w->window);
    free(w);
    sdl.SDL_QuitSubSystem(SDL_INIT_VIDEO);
    sdl.SDL_Quit();
}

#else // SDL.h was not found when this build was configured

struct demo_window {
    int unused;
};

const char *demo_window_unavailable(void)
{
    return "this bpx was built without SDL2 (SDL.h was not found: install libsdl2-dev, "
           "configure and build again)";
}

int demo_window_open(int width, int height, const char *title, demo_window **out, demo_error *err)
{
    (void)width, (void)height, (void)title;
    *out = NULL;
    if (err)
        snprintf(err->message, sizeof err->message, "no window: %.*s",
                 (int)sizeof err->message - 16, demo_window_unavailable());
    return -1;
}

int demo_window_show(demo_window *w, const unsigned char *rgb, unsigned char *capture,
                     demo_error *err)
{
    (void)w, (void)rgb, (void)capture, (void)err;
    return -1;
}

bool demo_window_should_close(demo_window *w)
{
    (void)w;
    return true;
}

const char *demo_window_driver(const demo_window *w)
{
    (void)w;
    return "none";
}

const char *demo_window_renderer(const demo_window *w)
{
    (void)w;
    return "none";
}

void demo_window_close(demo_window *w)
{
    free(w);
}

#endif

bool demo_window_available(void)
{
    return demo_window_unavailable() == NULL;
}
