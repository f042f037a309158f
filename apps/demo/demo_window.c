// bpx demo: the SDL2 window (see demo_window.h). SPDX-License-Identifier: MIT
#include "demo_window.h"

#include <stdio.h>
#include <stdlib.h>

#if defined(BPX_DEMO_WINDOW)
#include <SDL.h>

struct demo_window {
    SDL_Window *window;
    SDL_Renderer *renderer;
    SDL_Texture *texture;
    int width, height;
    bool closed;
    char renderer_name[64];
};

bool demo_window_available(void)
{
    return true;
}

static int sdl_fail(demo_error *err, const char *what)
{
    if (err)
        snprintf(err->message, sizeof err->message, "%s: %s", what, SDL_GetError());
    return -1;
}

int demo_window_open(int width, int height, const char *title, demo_window **out, demo_error *err)
{
    *out = NULL;
    if (SDL_InitSubSystem(SDL_INIT_VIDEO) != 0)
        return sdl_fail(err, "cannot start SDL video (is there a display? try xvfb-run)");
    demo_window *w = calloc(1, sizeof *w);
    if (!w) {
        SDL_QuitSubSystem(SDL_INIT_VIDEO);
        if (err)
            snprintf(err->message, sizeof err->message, "out of memory");
        return -1;
    }
    w->width = width;
    w->height = height;
    w->window = SDL_CreateWindow(title, SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, width,
                                 height, SDL_WINDOW_SHOWN);
    if (!w->window) {
        sdl_fail(err, "cannot open a window");
        demo_window_close(w);
        return -1;
    }
    // Any renderer will do for a blit; fall back to SDL's software renderer (no GPU, Xvfb).
    w->renderer = SDL_CreateRenderer(w->window, -1, 0);
    if (!w->renderer)
        w->renderer = SDL_CreateRenderer(w->window, -1, SDL_RENDERER_SOFTWARE);
    if (!w->renderer) {
        sdl_fail(err, "cannot create an SDL renderer");
        demo_window_close(w);
        return -1;
    }
    SDL_RendererInfo info;
    snprintf(w->renderer_name, sizeof w->renderer_name, "%s",
             SDL_GetRendererInfo(w->renderer, &info) == 0 ? info.name : "unknown");
    w->texture = SDL_CreateTexture(w->renderer, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING,
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
    if (SDL_UpdateTexture(w->texture, NULL, rgb, w->width * 3) != 0)
        return sdl_fail(err, "cannot update the window's texture");
    if (SDL_RenderClear(w->renderer) != 0 ||
        SDL_RenderCopy(w->renderer, w->texture, NULL, NULL) != 0)
        return sdl_fail(err, "cannot draw into the window");
    // Read back before presenting: after SDL_RenderPresent the back buffer is undefined.
    if (capture &&
        SDL_RenderReadPixels(w->renderer, NULL, SDL_PIXELFORMAT_RGB24, capture, w->width * 3) != 0)
        return sdl_fail(err, "cannot read the window's pixels back");
    SDL_RenderPresent(w->renderer);
    return 0;
}

bool demo_window_should_close(demo_window *w)
{
    SDL_Event event;
    while (SDL_PollEvent(&event)) {
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
    const char *driver = SDL_GetCurrentVideoDriver();
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
        SDL_DestroyTexture(w->texture);
    if (w->renderer)
        SDL_DestroyRenderer(w->renderer);
    if (w->window)
        SDL_DestroyWindow(w->window);
    free(w);
    SDL_QuitSubSystem(SDL_INIT_VIDEO);
    SDL_Quit();
}

#else // no SDL2 in this build

struct demo_window {
    int unused;
};

bool demo_window_available(void)
{
    return false;
}

int demo_window_open(int width, int height, const char *title, demo_window **out, demo_error *err)
{
    (void)width, (void)height, (void)title;
    *out = NULL;
    if (err)
        snprintf(err->message, sizeof err->message,
                 "this build has no window: SDL2 was not found when it was configured "
                 "(install libsdl2-dev, then configure and build again)");
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
