// Fuzzes the AABB-trace reader (trace/bpx_trace.c): the input bytes are the file.
// SPDX-License-Identifier: MIT
//
// Properties, besides no crash, leak, undefined behaviour or allocation beyond the file:
// - bpx_trace_load succeeds only for a file of exactly 32 + cycles * n * 24 bytes whose boxes
//   are all valid, and then gives back the file's floats bit for bit;
// - the streaming reader (open, read_cycle, seek_cycle) agrees with load, cycle by cycle;
// - writing the loaded cycles with the writer reproduces the input byte for byte;
// - every error has a message naming the file, and an offset inside it (or none).
#define _POSIX_C_SOURCE 200809L
#include <inttypes.h>
#include <math.h>
#include <stdint.h>
#include <string.h>
#include <unistd.h>

#include "bpx_trace.h"
#include "fuzz_check.h"

enum { READ_CYCLES_MAX = 64 }; // cycles of n = 0 cost nothing and may number 2^64 - 1

static char input_path[4096];
static char output_path[4096];

// Two scratch files per process, made once, removed at exit.
static void remove_scratch(void)
{
    unlink(input_path);
    unlink(output_path);
}

static void make_scratch(void)
{
    if (input_path[0])
        return;
    const char *dir = getenv("TMPDIR");
    if (!dir || !*dir)
        dir = "/tmp";
    snprintf(input_path, sizeof input_path, "%s/bpx-fuzz-trace-in-XXXXXX", dir);
    snprintf(output_path, sizeof output_path, "%s/bpx-fuzz-trace-out-XXXXXX", dir);
    int a = mkstemp(input_path), b = mkstemp(output_path);
    FUZZ_CHECK(a >= 0 && b >= 0, "cannot make scratch files in %s", dir);
    close(a);
    close(b);
    atexit(remove_scratch);
}

static void write_file(const char *path, const uint8_t *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    FUZZ_CHECK(f != NULL, "cannot write %s", path);
    FUZZ_CHECK(size == 0 || fwrite(data, 1, size, f) == size, "short write to %s", path);
    FUZZ_CHECK(fclose(f) == 0, "cannot close %s", path);
}

static void check_error(bpx_trace_status status, const bpx_trace_error *err, size_t size)
{
    FUZZ_CHECK(err->status == status, "error status %d, returned %d", err->status, status);
    FUZZ_CHECK(strstr(err->message, input_path) != NULL, "message \"%s\" does not name the file",
               err->message);
    FUZZ_CHECK(err->offset == UINT64_MAX || err->offset <= size,
               "offset %" PRIu64 " past the file's %zu bytes", err->offset, size);
    FUZZ_CHECK(bpx_trace_status_string(status) != NULL, "no name for status %d", status);
}

static float f32_at(const uint8_t *p)
{
    uint32_t bits = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                    (uint32_t)p[3] << 24;
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static void check_loaded(const uint8_t *data, size_t size, const bpx_trace_header *h,
                         const bpx_box *boxes)
{
    uint64_t total = h->cycle_count * h->box_count;
    FUZZ_CHECK(h->box_count == 0 || size == BPX_TRACE_HEADER_BYTES + total * BPX_TRACE_BOX_BYTES,
               "loaded %" PRIu64 " cycles of %" PRIu32 " boxes from %zu bytes", h->cycle_count,
               h->box_count, size);
    FUZZ_CHECK(h->box_count != 0 || size == BPX_TRACE_HEADER_BYTES,
               "n = 0 loaded from %zu bytes", size);
    FUZZ_CHECK(memcmp(data, BPX_TRACE_MAGIC, 8) == 0, "loaded without the magic");
    for (uint64_t k = 0; k < total; k++) {
        const uint8_t *p = data + BPX_TRACE_HEADER_BYTES + k * BPX_TRACE_BOX_BYTES;
        for (int a = 0; a < 3; a++) {
            float lo = f32_at(p + 4 * a), hi = f32_at(p + 12 + 4 * a);
            FUZZ_CHECK(memcmp(&lo, &boxes[k].min[a], 4) == 0 &&
                           memcmp(&hi, &boxes[k].max[a], 4) == 0,
                       "box %" PRIu64 " axis %d differs from the file", k, a);
            FUZZ_CHECK(isfinite(lo) && isfinite(hi) && lo <= hi,
                       "box %" PRIu64 " axis %d loaded though invalid: %g %g", k, a, (double)lo,
                       (double)hi);
        }
    }
}

// The streaming reader against load: every cycle in order, then one cycle after a seek.
static void check_stream(const bpx_trace_header *h, const bpx_box *boxes, uint8_t seek_byte)
{
    bpx_trace_reader *r;
    bpx_trace_error err;
    FUZZ_CHECK(bpx_trace_open(input_path, &r, &err) == BPX_TRACE_OK, "open after load: %s",
               err.message);
    uint32_t n = h->box_count;
    // Room for a cycle only when the file holds one: the header's n alone proves nothing.
    bpx_box *cycle = malloc((h->cycle_count && n ? n : 1) * sizeof *cycle);
    FUZZ_CHECK(cycle != NULL, "out of memory");
    uint64_t cycles = h->cycle_count < READ_CYCLES_MAX ? h->cycle_count : READ_CYCLES_MAX;
    for (uint64_t c = 0; c < cycles; c++) {
        FUZZ_CHECK(bpx_trace_read_cycle(r, cycle, &err) == BPX_TRACE_OK, "cycle %" PRIu64 ": %s",
                   c, err.message);
        FUZZ_CHECK(n == 0 || memcmp(cycle, boxes + c * n, n * sizeof *cycle) == 0,
                   "cycle %" PRIu64 " differs from load's", c);
    }
    if (h->cycle_count <= READ_CYCLES_MAX)
        FUZZ_CHECK(bpx_trace_read_cycle(r, cycle, &err) == BPX_TRACE_END, "no END after %" PRIu64
                   " cycles", h->cycle_count);
    uint64_t target = h->cycle_count ? seek_byte % (h->cycle_count < 256 ? h->cycle_count : 256)
                                     : 0;
    FUZZ_CHECK(bpx_trace_seek_cycle(r, target, &err) == BPX_TRACE_OK, "seek %" PRIu64 ": %s",
               target, err.message);
    bpx_trace_status s = bpx_trace_read_cycle(r, cycle, &err);
    if (h->cycle_count == 0)
        FUZZ_CHECK(s == BPX_TRACE_END, "read in an empty trace: %d", s);
    else
        FUZZ_CHECK(s == BPX_TRACE_OK && (n == 0 || memcmp(cycle, boxes + target * n,
                                                          n * sizeof *cycle) == 0),
                   "cycle %" PRIu64 " after a seek differs", target);
    bpx_trace_status past = bpx_trace_seek_cycle(r, h->cycle_count + 1, &err);
    FUZZ_CHECK(h->cycle_count == UINT64_MAX || past == BPX_TRACE_ERR_ARGUMENT,
               "seek past the end: %d", past);
    free(cycle);
    bpx_trace_close(r);
}

// The writer makes the same file from the loaded cycles.
static void check_rewrite(const uint8_t *data, size_t size, const bpx_trace_header *h,
                          const bpx_box *boxes)
{
    if (h->box_count == 0 && h->cycle_count > READ_CYCLES_MAX)
        return; // the writer would loop as long as the count is big
    if (h->cycle_count == 0 && h->box_count > 4096)
        return; // the writer holds a cycle's bytes from the start: n * 24, not in this file
    bpx_trace_writer *w;
    bpx_trace_error err;
    FUZZ_CHECK(bpx_trace_writer_open(output_path, h->box_count, &w, &err) == BPX_TRACE_OK,
               "writer: %s", err.message);
    for (uint64_t c = 0; c < h->cycle_count; c++)
        FUZZ_CHECK(bpx_trace_write_cycle(w, h->box_count ? boxes + c * h->box_count : NULL,
                                         &err) == BPX_TRACE_OK,
                   "write cycle %" PRIu64 ": %s", c, err.message);
    FUZZ_CHECK(bpx_trace_writer_close(w, &err) == BPX_TRACE_OK, "close: %s", err.message);
    FILE *f = fopen(output_path, "rb");
    FUZZ_CHECK(f != NULL, "cannot read back %s", output_path);
    uint8_t *copy = malloc(size + 1);
    FUZZ_CHECK(copy != NULL, "out of memory");
    size_t got = fread(copy, 1, size + 1, f);
    fclose(f);
    FUZZ_CHECK(got == size && memcmp(copy, data, size) == 0,
               "the writer made %zu bytes unlike the input's %zu", got, size);
    free(copy);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    make_scratch();
    write_file(input_path, data, size);
    bpx_trace_header h;
    bpx_box *boxes = (bpx_box *)&h; // must be reset to NULL whatever happens
    bpx_trace_error err;
    bpx_trace_status status = bpx_trace_load(input_path, &h, &boxes, &err);
    if (status != BPX_TRACE_OK) {
        FUZZ_CHECK(boxes == NULL, "boxes not NULL after an error");
        check_error(status, &err, size);
        // Open agrees: it fails the same way, unless the trouble lies in a cycle's boxes.
        bpx_trace_reader *r = (bpx_trace_reader *)&h;
        bpx_trace_error open_err;
        bpx_trace_status open_status = bpx_trace_open(input_path, &r, &open_err);
        if (status == BPX_TRACE_ERR_BAD_BOX || status == BPX_TRACE_ERR_NO_MEMORY) {
            FUZZ_CHECK(open_status == BPX_TRACE_OK || open_status == BPX_TRACE_ERR_NO_MEMORY,
                       "load: bad box, open: %s", open_err.message);
        } else {
            FUZZ_CHECK(open_status == status && r == NULL, "load: %s; open: %s", err.message,
                       open_err.message);
        }
        bpx_trace_close(r);
        return 0;
    }
    FUZZ_CHECK(err.status == BPX_TRACE_OK, "err.status %d after success", err.status);
    check_loaded(data, size, &h, boxes);
    check_stream(&h, boxes, size ? data[size - 1] : 0);
    check_rewrite(data, size, &h, boxes);
    free(boxes);
    return 0;
}
