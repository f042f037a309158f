// bpx demo: PNG files through libpng's simplified API (no setjmp), libpng opened at run time
// (dlopen of libpng16.so.16), so that bpx starts without it. SPDX-License-Identifier: MIT
#include "demo_png.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(BPX_DEMO_PNG)
#include <png.h>

#include "dynload.h"

#if PNG_LIBPNG_VER_MAJOR != 1 || PNG_LIBPNG_VER_MINOR != 6
#error "bpx demo opens libpng 1.6 (libpng16.so.16) at run time: its png.h is needed to build"
#endif
#if defined(__APPLE__)
#define PNG_LIBRARY "libpng16.16.dylib"
#else
#define PNG_LIBRARY "libpng16.so.16"
#endif

// The functions of libpng the demo calls, each with its type from png.h.
#define PNG_FUNCTIONS(X)                                                                           \
    X(png_image_write_to_file)                                                                     \
    X(png_image_begin_read_from_file)                                                              \
    X(png_image_finish_read)                                                                       \
    X(png_image_free)

#define PNG_POINTER(f) __typeof__(&f) f;
static struct {
    PNG_FUNCTIONS(PNG_POINTER)
} png;

static pthread_once_t png_once = PTHREAD_ONCE_INIT;
static char png_missing[512]; // empty once libpng is loaded
static const char png_install[] = "; install libpng (Debian: libpng16-16) for pictures";

static void load_png(void)
{
    void *handle = bpx_dynload_open(PNG_LIBRARY, png_missing, sizeof png_missing);
#define PNG_LOAD(f)                                                                                \
    if (handle && !(png.f = (__typeof__(&f))bpx_dynload_symbol(handle, PNG_LIBRARY, #f,            \
                                                                png_missing, sizeof png_missing)))     \
        handle = NULL;
    PNG_FUNCTIONS(PNG_LOAD)
#undef PNG_LOAD
    if (handle)
        png_missing[0] = '\0';
    else
        strncat(png_missing, png_install, sizeof png_missing - strlen(png_missing) - 1);
}

const char *demo_png_unavailable(void)
{
    pthread_once(&png_once, load_png);
    return png_missing[0] ? png_missing : NULL;
}

static int unavailable(const char *what, const char *path, demo_error *err)
{
    if (err)
        snprintf(err->message, sizeof err->message, "cannot %s %s: %.*s", what, path,
                 (int)sizeof err->message / 2, demo_png_unavailable());
    return -1;
}

int demo_png_write(const char *path, const unsigned char *rgb, int width, int height,
                   demo_error *err)
{
    if (demo_png_unavailable())
        return unavailable("write", path, err);
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = (png_uint_32)width;
    image.height = (png_uint_32)height;
    image.format = PNG_FORMAT_RGB;
    if (!png.png_image_write_to_file(&image, path, 0, rgb, width * 3, NULL)) {
        if (err)
            snprintf(err->message, sizeof err->message, "cannot write %s: %s", path, image.message);
        png.png_image_free(&image);
        return -1;
    }
    png.png_image_free(&image);
    return 0;
}

int demo_png_read(const char *path, unsigned char **rgb, int *width, int *height, demo_error *err)
{
    *rgb = NULL;
    if (demo_png_unavailable())
        return unavailable("read", path, err);
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (!png.png_image_begin_read_from_file(&image, path)) {
        if (err)
            snprintf(err->message, sizeof err->message, "cannot read %s: %s", path, image.message);
        png.png_image_free(&image);
        return -1;
    }
    image.format = PNG_FORMAT_RGB;
    unsigned char *pixels = malloc(PNG_IMAGE_SIZE(image));
    if (!pixels) {
        png.png_image_free(&image);
        if (err)
            snprintf(err->message, sizeof err->message, "out of memory reading %s", path);
        return -1;
    }
    if (!png.png_image_finish_read(&image, NULL, pixels, 0, NULL)) {
        if (err)
            snprintf(err->message, sizeof err->message, "cannot decode %s: %s", path,
                     image.message);
        free(pixels);
        png.png_image_free(&image);
        return -1;
    }
    *rgb = pixels;
    *width = (int)image.width;
    *height = (int)image.height;
    png.png_image_free(&image);
    return 0;
}

#else // png.h was not found when this build was configured

const char *demo_png_unavailable(void)
{
    return "this bpx was built without libpng (png.h was not found: install libpng-dev, "
           "configure and build again)";
}

int demo_png_write(const char *path, const unsigned char *rgb, int width, int height,
                   demo_error *err)
{
    (void)rgb, (void)width, (void)height;
    if (err)
        snprintf(err->message, sizeof err->message, "cannot write %s: %s", path,
                 demo_png_unavailable());
    return -1;
}

int demo_png_read(const char *path, unsigned char **rgb, int *width, int *height, demo_error *err)
{
    (void)width, (void)height;
    *rgb = NULL;
    if (err)
        snprintf(err->message, sizeof err->message, "cannot read %s: %s", path,
                 demo_png_unavailable());
    return -1;
}

#endif

bool demo_png_available(void)
{
    return demo_png_unavailable() == NULL;
}
