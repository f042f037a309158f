// bpx demo: PNG files through libpng's simplified API (no setjmp). SPDX-License-Identifier: MIT
#include "demo_png.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(BPX_DEMO_PNG)
#include <png.h>

bool demo_png_available(void)
{
    return true;
}

int demo_png_write(const char *path, const unsigned char *rgb, int width, int height,
                   demo_error *err)
{
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = (png_uint_32)width;
    image.height = (png_uint_32)height;
    image.format = PNG_FORMAT_RGB;
    if (!png_image_write_to_file(&image, path, 0, rgb, width * 3, NULL)) {
        if (err)
            snprintf(err->message, sizeof err->message, "cannot write %s: %s", path, image.message);
        png_image_free(&image);
        return -1;
    }
    png_image_free(&image);
    return 0;
}

int demo_png_read(const char *path, unsigned char **rgb, int *width, int *height, demo_error *err)
{
    *rgb = NULL;
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, path)) {
        if (err)
            snprintf(err->message, sizeof err->message, "cannot read %s: %s", path, image.message);
        png_image_free(&image);
        return -1;
    }
    image.format = PNG_FORMAT_RGB;
    unsigned char *pixels = malloc(PNG_IMAGE_SIZE(image));
    if (!pixels) {
        png_image_free(&image);
        if (err)
            snprintf(err->message, sizeof err->message, "out of memory reading %s", path);
        return -1;
    }
    if (!png_image_finish_read(&image, NULL, pixels, 0, NULL)) {
        if (err)
            snprintf(err->message, sizeof err->message, "cannot decode %s: %s", path,
                     image.message);
        free(pixels);
        png_image_free(&image);
        return -1;
    }
    *rgb = pixels;
    *width = (int)image.width;
    *height = (int)image.height;
    png_image_free(&image);
    return 0;
}

#else // no libpng in this build

bool demo_png_available(void)
{
    return false;
}

int demo_png_write(const char *path, const unsigned char *rgb, int width, int height,
                   demo_error *err)
{
    (void)rgb, (void)width, (void)height;
    if (err)
        snprintf(err->message, sizeof err->message,
                 "cannot write %s: this build has no PNG support (libpng was not found)", path);
    return -1;
}

int demo_png_read(const char *path, unsigned char **rgb, int *width, int *height, demo_error *err)
{
    (void)width, (void)height;
    *rgb = NULL;
    if (err)
        snprintf(err->message, sizeof err->message,
                 "cannot read %s: this build has no PNG support (libpng was not found)", path);
    return -1;
}

#endif
