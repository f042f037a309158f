// bpx demo: the software renderer (see demo_render.h). SPDX-License-Identifier: MIT
#include "demo_render.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "demo_font.h"

typedef struct vec3 {
    double x, y, z;
} vec3;

static vec3 v3(double x, double y, double z)
{
    return (vec3){x, y, z};
}
static vec3 add(vec3 a, vec3 b)
{
    return v3(a.x + b.x, a.y + b.y, a.z + b.z);
}
static vec3 sub(vec3 a, vec3 b)
{
    return v3(a.x - b.x, a.y - b.y, a.z - b.z);
}
static vec3 scale(vec3 a, double s)
{
    return v3(a.x * s, a.y * s, a.z * s);
}
static double dot(vec3 a, vec3 b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static vec3 cross(vec3 a, vec3 b)
{
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static vec3 normalize(vec3 a)
{
    double len = sqrt(dot(a, a));
    return len > 0 ? scale(a, 1.0 / len) : a;
}

struct demo_renderer {
    int width, height;
    double size[3];
    // Camera: position, orthonormal basis (right, up, forward), focal lengths and centre, pixels.
    vec3 eye, right, up, forward;
    double fx, fy, cx, cy;
    vec3 light;      // towards the light, world space
    vec3 light_view; // the same in camera space
    unsigned char *rgb;
    float *depth;          // camera-space z per pixel (distance along forward)
    unsigned char *bg_rgb; // the empty box, drawn once
    float *bg_depth;
    int *floor_pixels; // pixels where the floor is seen, and where on the floor (x, z)
    float *floor_xz;
    int floor_count;
    int *cell_start, *cell_items; // shadow grid over the floor, rebuilt per frame
    int cells_x, cells_z;
    int items_cap;
};

static const unsigned char edge_colour[3] = {52, 56, 66};

static vec3 to_view(const demo_renderer *r, vec3 world)
{
    vec3 d = sub(world, r->eye);
    return v3(dot(d, r->right), dot(d, r->up), dot(d, r->forward));
}

// Places the camera above a front corner, looking at the box's centre, as far away as needed for
// the box to fill the image with a margin, then centres the box's projection in the image.
static void place_camera(demo_renderer *r)
{
    const double *s = r->size;
    vec3 target = v3(0.5 * s[0], 0.5 * s[1], 0.5 * s[2]);
    vec3 towards_eye = normalize(v3(0.55, 0.8, 1.0));
    r->forward = scale(towards_eye, -1.0);
    r->right = normalize(cross(r->forward, v3(0, 1, 0)));
    r->up = cross(r->right, r->forward);
    r->fy = 0.5 * r->height / 0.41421356237309503; // 45 degree vertical field of view
    r->fx = r->fy;
    double need = 0;
    for (int c = 0; c < 8; c++) {
        vec3 corner = v3(c & 1 ? s[0] : 0, c & 2 ? s[1] : 0, c & 4 ? s[2] : 0);
        vec3 d = sub(corner, target);
        double xc = dot(d, r->right), yc = dot(d, r->up), zc = dot(d, r->forward);
        double by_x = fabs(xc) * r->fx / (0.47 * r->width) - zc;
        double by_y = fabs(yc) * r->fy / (0.43 * r->height) - zc;
        need = fmax(need, fmax(by_x, by_y));
    }
    need = fmax(need, 1.0);
    r->eye = sub(target, scale(r->forward, need));
    double lo_x = DBL_MAX, hi_x = -DBL_MAX, lo_y = DBL_MAX, hi_y = -DBL_MAX;
    for (int c = 0; c < 8; c++) {
        vec3 p = to_view(r, v3(c & 1 ? s[0] : 0, c & 2 ? s[1] : 0, c & 4 ? s[2] : 0));
        double sx = r->fx * p.x / p.z, sy = -r->fy * p.y / p.z;
        lo_x = fmin(lo_x, sx);
        hi_x = fmax(hi_x, sx);
        lo_y = fmin(lo_y, sy);
        hi_y = fmax(hi_y, sy);
    }
    r->cx = 0.5 * r->width - 0.5 * (lo_x + hi_x);
    r->cy = 0.5 * r->height - 0.5 * (lo_y + hi_y) + 0.03 * r->height; // room for the text
    r->light = normalize(v3(-0.35, 1.0, 0.5));
    r->light_view = v3(dot(r->light, r->right), dot(r->light, r->up), dot(r->light, r->forward));
}

static vec3 pixel_ray_view(const demo_renderer *r, double px, double py)
{
    return v3((px - r->cx) / r->fx, (r->cy - py) / r->fy, 1.0);
}

static unsigned char clamp_byte(double v)
{
    return v <= 0 ? 0 : v >= 255 ? 255 : (unsigned char)(v + 0.5);
}

// The empty box: each pixel shows where its ray leaves the box's inside (the floor or a far
// wall; the near walls and the ceiling are seen through), or the background.
static int draw_background(demo_renderer *r)
{
    const double *s = r->size;
    double pitch = 60.0; // floor grid: the initial sphere spacing with the default parameters
    int floor_count = 0;
    for (int py = 0; py < r->height; py++)
        for (int px = 0; px < r->width; px++) {
            size_t k = (size_t)py * r->width + px;
            vec3 dv = pixel_ray_view(r, px + 0.5, py + 0.5);
            vec3 dw = add(add(scale(r->right, dv.x), scale(r->up, dv.y)), r->forward);
            double e[3] = {r->eye.x, r->eye.y, r->eye.z}, d[3] = {dw.x, dw.y, dw.z};
            double t_in = 0, t_out = DBL_MAX;
            int out_axis = -1, out_high = 0;
            for (int a = 0; a < 3; a++) {
                if (d[a] == 0) {
                    if (e[a] < 0 || e[a] > s[a])
                        t_in = DBL_MAX;
                    continue;
                }
                double t0 = (0 - e[a]) / d[a], t1 = (s[a] - e[a]) / d[a];
                double near = fmin(t0, t1), far = fmax(t0, t1);
                t_in = fmax(t_in, near);
                if (far < t_out) {
                    t_out = far;
                    out_axis = a;
                    out_high = t1 > t0;
                }
            }
            unsigned char *px_rgb = r->bg_rgb + 3 * k;
            if (out_axis < 0 || !(t_out > t_in)) {
                double g = (double)py / r->height; // backdrop: a dark vertical gradient
                px_rgb[0] = clamp_byte(44 - 20 * g);
                px_rgb[1] = clamp_byte(48 - 20 * g);
                px_rgb[2] = clamp_byte(58 - 22 * g);
                r->bg_depth[k] = FLT_MAX;
                continue;
            }
            vec3 q = add(r->eye, scale(dw, t_out));
            r->bg_depth[k] = (float)t_out;
            double base[3];
            if (out_axis == 1 && !out_high) {
                // Floor: warm grey with grid lines every pitch metres.
                double gx = fabs(q.x / pitch - floor(q.x / pitch + 0.5)) * pitch;
                double gz = fabs(q.z / pitch - floor(q.z / pitch + 0.5)) * pitch;
                double line = (gx < 0.8 || gz < 0.8) ? 0.88 : 1.0;
                base[0] = 206 * line;
                base[1] = 200 * line;
                base[2] = 188 * line;
                r->floor_pixels[floor_count] = (int)k;
                r->floor_xz[2 * floor_count] = (float)q.x;
                r->floor_xz[2 * floor_count + 1] = (float)q.z;
                floor_count++;
            } else {
                // A far wall (or the ceiling, seen from below): cool grey, lighter upwards.
                vec3 inward = v3(out_axis == 0 ? (out_high ? -1 : 1) : 0,
                                 out_axis == 1 ? (out_high ? -1 : 1) : 0,
                                 out_axis == 2 ? (out_high ? -1 : 1) : 0);
                double lit = 0.78 + 0.12 * fmax(0, dot(inward, r->light)) + 0.1 * q.y / s[1];
                base[0] = 168 * lit;
                base[1] = 180 * lit;
                base[2] = 196 * lit;
            }
            px_rgb[0] = clamp_byte(base[0]);
            px_rgb[1] = clamp_byte(base[1]);
            px_rgb[2] = clamp_byte(base[2]);
        }
    r->floor_count = floor_count;
    return 0;
}

int demo_renderer_create(int width, int height, const double box_size[3], demo_renderer **out,
                         demo_error *err)
{
    if (!out)
        return -1;
    *out = NULL;
    if (width < 16 || height < 16 || width > 8192 || height > 8192) {
        if (err)
            snprintf(err->message, sizeof err->message,
                     "image size %dx%d is outside 16x16 .. 8192x8192", width, height);
        return -1;
    }
    if (!box_size || !(box_size[0] > 0 && box_size[1] > 0 && box_size[2] > 0)) {
        if (err)
            snprintf(err->message, sizeof err->message, "the box size must be positive");
        return -1;
    }
    demo_renderer *r = calloc(1, sizeof *r);
    size_t pixels = (size_t)width * height;
    if (r) {
        r->width = width;
        r->height = height;
        memcpy(r->size, box_size, sizeof r->size);
        r->rgb = malloc(3 * pixels);
        r->bg_rgb = malloc(3 * pixels);
        r->depth = malloc(pixels * sizeof *r->depth);
        r->bg_depth = malloc(pixels * sizeof *r->bg_depth);
        r->floor_pixels = malloc(pixels * sizeof *r->floor_pixels);
        r->floor_xz = malloc(2 * pixels * sizeof *r->floor_xz);
    }
    if (!r || !r->rgb || !r->bg_rgb || !r->depth || !r->bg_depth || !r->floor_pixels ||
        !r->floor_xz) {
        demo_renderer_destroy(r);
        if (err)
            snprintf(err->message, sizeof err->message, "out of memory for a %dx%d image", width,
                     height);
        return -1;
    }
    place_camera(r);
    draw_background(r);
    memcpy(r->rgb, r->bg_rgb, 3 * pixels);
    memcpy(r->depth, r->bg_depth, pixels * sizeof *r->depth);
    *out = r;
    return 0;
}

void demo_renderer_destroy(demo_renderer *r)
{
    if (!r)
        return;
    free(r->rgb);
    free(r->bg_rgb);
    free(r->depth);
    free(r->bg_depth);
    free(r->floor_pixels);
    free(r->floor_xz);
    free(r->cell_start);
    free(r->cell_items);
    free(r);
}

// Shadows on the floor: each sphere casts a soft disc of its radius along the light. Spheres are
// binned by shadow centre into cells of one diameter, so a floor pixel looks at 3 x 3 cells.
static void draw_shadows(demo_renderer *r, const double *centres, uint32_t n, double radius)
{
    double cell = 2.0 * radius;
    int cx = (int)(r->size[0] / cell) + 1, cz = (int)(r->size[2] / cell) + 1;
    if (cx > 4096 || cz > 4096)
        return; // a very large box: no shadows rather than a huge grid
    size_t cells = (size_t)cx * cz;
    if (r->cells_x != cx || r->cells_z != cz) {
        free(r->cell_start);
        r->cell_start = malloc((2 * cells + 1) * sizeof *r->cell_start);
        r->cells_x = r->cell_start ? cx : 0;
        r->cells_z = r->cell_start ? cz : 0;
        if (!r->cell_start)
            return; // no memory: no shadows this frame
    }
    if ((int)n > r->items_cap) {
        free(r->cell_items);
        r->cell_items = malloc(2 * (size_t)n * sizeof *r->cell_items);
        r->items_cap = r->cell_items ? (int)n : 0;
        if (!r->cell_items)
            return;
    }
    // Counting sort of spheres by the cell of their shadow's centre (off the floor: none).
    int *start = r->cell_start, *cursor = r->cell_start + cells + 1;
    int *items = r->cell_items, *cell_of = r->cell_items + n;
    memset(start, 0, (cells + 1) * sizeof *start);
    double lx = r->light.x / r->light.y, lz = r->light.z / r->light.y;
    for (uint32_t i = 0; i < n; i++) {
        const double *c = &centres[3 * (size_t)i];
        double sx = c[0] - c[1] * lx, sz = c[2] - c[1] * lz;
        double gx = floor(sx / cell), gz = floor(sz / cell);
        cell_of[i] = (gx < 0 || gz < 0 || gx >= cx || gz >= cz) ? -1 : (int)gz * cx + (int)gx;
        if (cell_of[i] >= 0)
            start[cell_of[i] + 1]++;
    }
    for (size_t k = 0; k < cells; k++)
        start[k + 1] += start[k];
    memcpy(cursor, start, cells * sizeof *cursor);
    for (uint32_t i = 0; i < n; i++)
        if (cell_of[i] >= 0)
            items[cursor[cell_of[i]]++] = (int)i;

    double r2 = radius * radius;
    for (int f = 0; f < r->floor_count; f++) {
        double x = r->floor_xz[2 * f], z = r->floor_xz[2 * f + 1];
        int gx = (int)floor(x / cell), gz = (int)floor(z / cell);
        double shade = 0;
        for (int dz = -1; dz <= 1; dz++)
            for (int dx = -1; dx <= 1; dx++) {
                int ux = gx + dx, uz = gz + dz;
                if (ux < 0 || uz < 0 || ux >= cx || uz >= cz)
                    continue;
                int k = uz * cx + ux;
                for (int m = start[k]; m < start[k + 1]; m++) {
                    const double *c = &centres[3 * (size_t)items[m]];
                    double sx = c[0] - c[1] * lx - x, sz = c[2] - c[1] * lz - z;
                    double d2 = sx * sx + sz * sz;
                    if (d2 < r2) {
                        double height = c[1] / r->size[1];
                        double s = (1.0 - d2 / r2) * 2.5;
                        s = (s > 1 ? 1 : s) * (0.5 - 0.3 * height);
                        shade = fmax(shade, s);
                    }
                }
            }
        if (shade > 0) {
            unsigned char *p = r->rgb + 3 * (size_t)r->floor_pixels[f];
            for (int ch = 0; ch < 3; ch++)
                p[ch] = clamp_byte(p[ch] * (1.0 - shade));
        }
    }
}

// Sphere i's colour: hues spread by the golden ratio, so neighbours differ.
static void sphere_colour(uint32_t i, double rgb[3])
{
    double h = fmod(i * 0.6180339887498949, 1.0) * 6.0, s = 0.6, v = 0.95;
    int sector = (int)h;
    double f = h - sector, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    double table[6][3] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
    for (int c = 0; c < 3; c++)
        rgb[c] = 255.0 * table[sector % 6][c];
}

static void draw_sphere(demo_renderer *r, vec3 centre_world, double radius, uint32_t index)
{
    vec3 c = to_view(r, centre_world);
    if (c.z <= radius * 1.001)
        return; // at or behind the camera
    // Screen bounds: the projections of the corners of the sphere's camera-space box.
    double lo_x = DBL_MAX, hi_x = -DBL_MAX, lo_y = DBL_MAX, hi_y = -DBL_MAX;
    for (int k = 0; k < 8; k++) {
        double x = c.x + (k & 1 ? radius : -radius), y = c.y + (k & 2 ? radius : -radius);
        double z = c.z + (k & 4 ? radius : -radius);
        double sx = r->cx + r->fx * x / z, sy = r->cy - r->fy * y / z;
        lo_x = fmin(lo_x, sx);
        hi_x = fmax(hi_x, sx);
        lo_y = fmin(lo_y, sy);
        hi_y = fmax(hi_y, sy);
    }
    int x0 = (int)fmax(0, floor(lo_x)), x1 = (int)fmin(r->width - 1, ceil(hi_x));
    int y0 = (int)fmax(0, floor(lo_y)), y1 = (int)fmin(r->height - 1, ceil(hi_y));
    double base[3];
    sphere_colour(index, base);
    double cc = dot(c, c) - radius * radius;
    const vec3 l = r->light_view;
    for (int py = y0; py <= y1; py++)
        for (int px = x0; px <= x1; px++) {
            vec3 d = pixel_ray_view(r, px + 0.5, py + 0.5);
            double a = dot(d, d), b = dot(d, c);
            double disc = b * b - a * cc;
            if (disc < 0)
                continue;
            double t = (b - sqrt(disc)) / a; // nearest hit; camera-space z = t, as d.z = 1
            size_t k = (size_t)py * r->width + px;
            if (t >= r->depth[k])
                continue;
            vec3 p = scale(d, t);
            vec3 nrm = scale(sub(p, c), 1.0 / radius);
            double diffuse = fmax(0, dot(nrm, l));
            vec3 h = normalize(sub(l, normalize(p)));
            double spec = pow(fmax(0, dot(nrm, h)), 48.0);
            double rim = 1.0 - fabs(dot(nrm, normalize(p))); // darken the silhouette a little
            double lit = 0.22 + 0.78 * diffuse - 0.12 * rim * rim;
            // Edge coverage: how far inside the silhouette, in pixels at this depth.
            double miss = sqrt(fmax(0, dot(c, c) - b * b / a)); // ray-to-centre distance
            double footprint = t * sqrt(a) / r->fx;
            double cover = fmin(1.0, (radius - miss) / footprint + 0.5);
            unsigned char *out = r->rgb + 3 * k;
            for (int ch = 0; ch < 3; ch++) {
                double v = base[ch] * lit + 230.0 * spec;
                out[ch] = clamp_byte(cover * v + (1.0 - cover) * out[ch]);
            }
            r->depth[k] = (float)t;
        }
}

// A box edge, depth-tested (1/z is linear along a projected line), so spheres hide it.
static void draw_edge(demo_renderer *r, vec3 a_world, vec3 b_world)
{
    vec3 a = to_view(r, a_world), b = to_view(r, b_world);
    if (a.z <= 0 || b.z <= 0)
        return;
    double ax = r->cx + r->fx * a.x / a.z, ay = r->cy - r->fy * a.y / a.z;
    double bx = r->cx + r->fx * b.x / b.z, by = r->cy - r->fy * b.y / b.z;
    int steps = (int)fmax(fabs(bx - ax), fabs(by - ay)) + 1;
    if (steps > 4 * (r->width + r->height))
        return;
    for (int s = 0; s <= steps; s++) {
        double u = (double)s / steps;
        int px = (int)floor(ax + (bx - ax) * u), py = (int)floor(ay + (by - ay) * u);
        if (px < 0 || py < 0 || px >= r->width || py >= r->height)
            continue;
        double inv_z = (1.0 - u) / a.z + u / b.z;
        double z = 1.0 / inv_z;
        size_t k = (size_t)py * r->width + px;
        if (z > r->depth[k] * 1.002 + 0.5)
            continue;
        unsigned char *out = r->rgb + 3 * k;
        for (int ch = 0; ch < 3; ch++)
            out[ch] = edge_colour[ch];
    }
}

void demo_renderer_draw(demo_renderer *r, const double *centres, uint32_t n, double radius)
{
    size_t pixels = (size_t)r->width * r->height;
    memcpy(r->rgb, r->bg_rgb, 3 * pixels);
    memcpy(r->depth, r->bg_depth, pixels * sizeof *r->depth);
    draw_shadows(r, centres, n, radius);
    for (uint32_t i = 0; i < n; i++) {
        const double *c = &centres[3 * (size_t)i];
        draw_sphere(r, v3(c[0], c[1], c[2]), radius, i);
    }
    const double *s = r->size;
    for (int c = 0; c < 8; c++)
        for (int axis = 0; axis < 3; axis++) {
            if (c & (1 << axis))
                continue; // each edge once, from its low end
            vec3 a = v3(c & 1 ? s[0] : 0, c & 2 ? s[1] : 0, c & 4 ? s[2] : 0);
            int d = c | (1 << axis);
            vec3 b = v3(d & 1 ? s[0] : 0, d & 2 ? s[1] : 0, d & 4 ? s[2] : 0);
            draw_edge(r, a, b);
        }
}

void demo_renderer_overlay(demo_renderer *r, const char *const *lines, int count)
{
    if (count <= 0)
        return;
    int widest = 0;
    for (int k = 0; k < count; k++) {
        int w = demo_font_text_width(lines[k], 1);
        widest = w > widest ? w : widest;
    }
    int band_w = widest + 12, band_h = count * DEMO_FONT_LINE + 8;
    for (int y = 0; y < band_h && y < r->height; y++)
        for (int x = 0; x < band_w && x < r->width; x++) {
            unsigned char *p = r->rgb + 3 * ((size_t)y * r->width + x);
            for (int ch = 0; ch < 3; ch++)
                p[ch] = (unsigned char)(p[ch] * 2 / 5);
        }
    static const unsigned char ink[3] = {240, 240, 232};
    for (int k = 0; k < count; k++)
        demo_font_draw(r->rgb, r->width, r->height, 6, 5 + k * DEMO_FONT_LINE, lines[k], ink, 1);
}

const unsigned char *demo_renderer_pixels(const demo_renderer *r)
{
    return r->rgb;
}

int demo_renderer_width(const demo_renderer *r)
{
    return r->width;
}

int demo_renderer_height(const demo_renderer *r)
{
    return r->height;
}
