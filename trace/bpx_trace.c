// bpx trace: reader and writer of the AABB-trace file (format in bpx_trace.h).
// SPDX-License-Identifier: MIT
#define _POSIX_C_SOURCE 200809L
#include "bpx_trace.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>

struct bpx_trace_reader {
    FILE *file;
    char *path;
    bpx_trace_header header;
    uint64_t file_bytes;
    uint64_t next_cycle;
    unsigned char *buffer; // one cycle of file bytes
};

struct bpx_trace_writer {
    FILE *file;
    char *path;
    uint32_t box_count;
    uint64_t cycles;
    unsigned char *buffer;
};

static const char *const axis_names[3] = {"x", "y", "z"};

const char *bpx_trace_status_string(bpx_trace_status status)
{
    switch (status) {
    case BPX_TRACE_OK:
        return "ok";
    case BPX_TRACE_END:
        return "end of trace";
    case BPX_TRACE_ERR_ARGUMENT:
        return "bad argument";
    case BPX_TRACE_ERR_IO:
        return "input/output error";
    case BPX_TRACE_ERR_NO_MEMORY:
        return "out of memory";
    case BPX_TRACE_ERR_BAD_MAGIC:
        return "not a bpx trace";
    case BPX_TRACE_ERR_BAD_VERSION:
        return "unsupported trace version";
    case BPX_TRACE_ERR_BAD_HEADER:
        return "bad trace header";
    case BPX_TRACE_ERR_TRUNCATED:
        return "truncated trace";
    case BPX_TRACE_ERR_TRAILING:
        return "trailing data after the last cycle";
    case BPX_TRACE_ERR_BAD_BOX:
        return "invalid box in trace";
    }
    return "unknown trace status";
}

#if defined(__GNUC__)
__attribute__((format(printf, 5, 6)))
#endif
static bpx_trace_status
fail(bpx_trace_error *err, bpx_trace_status status, uint64_t offset, const char *path,
     const char *fmt, ...)
{
    if (err) {
        err->status = status;
        err->offset = offset;
        int used = snprintf(err->message, sizeof err->message, "%s: ", path ? path : "(null)");
        if (used < 0 || (size_t)used >= sizeof err->message)
            used = 0;
        va_list args;
        va_start(args, fmt);
        vsnprintf(err->message + used, sizeof err->message - (size_t)used, fmt, args);
        va_end(args);
    }
    return status;
}

static bpx_trace_status ok(bpx_trace_error *err, bpx_trace_status status)
{
    if (err) {
        err->status = status;
        err->offset = UINT64_MAX;
        err->message[0] = '\0';
    }
    return status;
}

static char *copy_string(const char *s)
{
    size_t len = strlen(s) + 1;
    char *copy = malloc(len);
    if (copy)
        memcpy(copy, s, len);
    return copy;
}

// --- Little-endian bytes, whatever the host's order ----------------------------------------------

static uint32_t get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get_u64(const unsigned char *p)
{
    return (uint64_t)get_u32(p) | (uint64_t)get_u32(p + 4) << 32;
}

static void put_u32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
    p[2] = (unsigned char)(v >> 16);
    p[3] = (unsigned char)(v >> 24);
}

static void put_u64(unsigned char *p, uint64_t v)
{
    put_u32(p, (uint32_t)v);
    put_u32(p + 4, (uint32_t)(v >> 32));
}

static float get_f32(const unsigned char *p)
{
    uint32_t bits = get_u32(p);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static void put_f32(unsigned char *p, float f)
{
    uint32_t bits;
    memcpy(&bits, &f, sizeof bits);
    put_u32(p, bits);
}

// The first problem of a box: -1 if valid, else the axis; *what says which problem.
static int box_problem(const bpx_box *b, const char **what)
{
    for (int a = 0; a < 3; a++) {
        if (!isfinite(b->min[a]) || !isfinite(b->max[a])) {
            *what = "a NaN or infinite coordinate";
            return a;
        }
    }
    for (int a = 0; a < 3; a++) {
        if (b->min[a] > b->max[a]) {
            *what = "min > max";
            return a;
        }
    }
    return -1;
}

// --- Reader --------------------------------------------------------------------------------------

bpx_trace_status bpx_trace_open(const char *path, bpx_trace_reader **out, bpx_trace_error *err)
{
    if (out)
        *out = NULL;
    if (!path || !out)
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, path, "null argument");
    FILE *file = fopen(path, "rb");
    if (!file)
        return fail(err, BPX_TRACE_ERR_IO, UINT64_MAX, path, "cannot open: %s", strerror(errno));

    struct stat st;
    if (fstat(fileno(file), &st) != 0) {
        int e = errno;
        fclose(file);
        return fail(err, BPX_TRACE_ERR_IO, UINT64_MAX, path, "cannot stat: %s", strerror(e));
    }
    uint64_t file_bytes = (uint64_t)st.st_size;

    unsigned char h[BPX_TRACE_HEADER_BYTES];
    size_t got = fread(h, 1, sizeof h, file);
    bpx_trace_status status = BPX_TRACE_OK;
    if (got >= 8 && memcmp(h, BPX_TRACE_MAGIC, 8) != 0) {
        status = fail(err, BPX_TRACE_ERR_BAD_MAGIC, 0, path,
                      "not a bpx trace: bytes 0..7 are not \"" BPX_TRACE_MAGIC "\"");
    } else if (got < sizeof h) {
        status = ferror(file) ? fail(err, BPX_TRACE_ERR_IO, got, path, "read error in the header")
                              : fail(err, BPX_TRACE_ERR_TRUNCATED, got, path,
                                     "truncated header: the file has %zu bytes, a header needs %u",
                                     got, BPX_TRACE_HEADER_BYTES);
    }
    bpx_trace_header header = {0};
    if (status == BPX_TRACE_OK) {
        header.version = get_u32(h + 8);
        header.box_count = get_u32(h + 12);
        header.cycle_count = get_u64(h + 16);
        uint32_t floats = get_u32(h + 24);
        uint32_t reserved = get_u32(h + 28);
        uint64_t cycle_bytes = (uint64_t)header.box_count * BPX_TRACE_BOX_BYTES; // < 2^35
        // The file may have grown between fstat and fread: never below 0.
        uint64_t data_bytes =
            file_bytes > BPX_TRACE_HEADER_BYTES ? file_bytes - BPX_TRACE_HEADER_BYTES : 0;
        if (header.version != BPX_TRACE_VERSION) {
            status = fail(err, BPX_TRACE_ERR_BAD_VERSION, 8, path,
                          "version %" PRIu32 " at byte 8; this reader knows version %u",
                          header.version, BPX_TRACE_VERSION);
        } else if (header.box_count > BPX_MAX_BOXES) {
            status = fail(err, BPX_TRACE_ERR_BAD_HEADER, 12, path,
                          "box count %" PRIu32 " at byte 12 exceeds %u", header.box_count,
                          BPX_MAX_BOXES);
        } else if (floats != 6) {
            status = fail(err, BPX_TRACE_ERR_BAD_HEADER, 24, path,
                          "floats per box at byte 24 is %" PRIu32 ", expected 6", floats);
        } else if (reserved != 0) {
            status = fail(err, BPX_TRACE_ERR_BAD_HEADER, 28, path,
                          "reserved word at byte 28 is %" PRIu32 ", expected 0", reserved);
        } else if (cycle_bytes == 0 && data_bytes != 0) {
            status = fail(err, BPX_TRACE_ERR_TRAILING, BPX_TRACE_HEADER_BYTES, path,
                          "%" PRIu64 " bytes after the header of a trace with 0 boxes per cycle",
                          data_bytes);
        } else if (cycle_bytes != 0 && header.cycle_count > data_bytes / cycle_bytes) {
            uint64_t whole = data_bytes / cycle_bytes;
            uint64_t end = BPX_TRACE_HEADER_BYTES + whole * cycle_bytes;
            status = fail(err, BPX_TRACE_ERR_TRUNCATED, file_bytes, path,
                          "truncated: the header announces %" PRIu64 " cycles of %" PRIu32
                          " boxes (%" PRIu64 " bytes each), the file has %" PRIu64
                          " bytes: it ends at byte %" PRIu64 " inside cycle %" PRIu64
                          " (which starts at byte %" PRIu64 ")",
                          header.cycle_count, header.box_count, cycle_bytes, file_bytes, file_bytes,
                          whole, end);
        } else if (cycle_bytes != 0 && header.cycle_count * cycle_bytes != data_bytes) {
            uint64_t end = BPX_TRACE_HEADER_BYTES + header.cycle_count * cycle_bytes;
            status = fail(err, BPX_TRACE_ERR_TRAILING, end, path,
                          "%" PRIu64 " unexpected bytes from byte %" PRIu64 " after the %" PRIu64
                          " cycles the header announces%s",
                          file_bytes - end, end, header.cycle_count,
                          header.cycle_count == 0 ? " (was the writer interrupted?)" : "");
        }
    }
    if (status != BPX_TRACE_OK) {
        fclose(file);
        return status;
    }

    // The buffer holds one cycle, which lies in the file only if there is one: a header of n
    // boxes and no cycles (an empty trace) must not make it allocate n * 24 bytes.
    uint64_t buffer_bytes =
        header.cycle_count ? (uint64_t)header.box_count * BPX_TRACE_BOX_BYTES : 0;
    bpx_trace_reader *r = buffer_bytes <= SIZE_MAX ? calloc(1, sizeof *r) : NULL;
    if (r) {
        r->path = copy_string(path);
        r->buffer = malloc(buffer_bytes ? (size_t)buffer_bytes : 1);
    }
    if (!r || !r->path || !r->buffer) {
        if (r) {
            free(r->path);
            free(r->buffer);
        }
        free(r);
        fclose(file);
        return fail(err, BPX_TRACE_ERR_NO_MEMORY, UINT64_MAX, path, "out of memory");
    }
    r->file = file;
    r->header = header;
    r->file_bytes = file_bytes;
    *out = r;
    return ok(err, BPX_TRACE_OK);
}

const bpx_trace_header *bpx_trace_header_of(const bpx_trace_reader *reader)
{
    return reader ? &reader->header : NULL;
}

static uint64_t cycle_offset(const bpx_trace_header *h, uint64_t cycle)
{
    return BPX_TRACE_HEADER_BYTES + cycle * (uint64_t)h->box_count * BPX_TRACE_BOX_BYTES;
}

bpx_trace_status bpx_trace_read_cycle(bpx_trace_reader *r, bpx_box *out, bpx_trace_error *err)
{
    if (!r || (!out && r->header.box_count > 0))
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, r ? r->path : NULL, "null argument");
    if (r->next_cycle >= r->header.cycle_count)
        return ok(err, BPX_TRACE_END);
    uint32_t n = r->header.box_count;
    size_t bytes = (size_t)n * BPX_TRACE_BOX_BYTES;
    uint64_t start = cycle_offset(&r->header, r->next_cycle);
    size_t got = fread(r->buffer, 1, bytes, r->file);
    if (got != bytes) {
        if (ferror(r->file))
            return fail(err, BPX_TRACE_ERR_IO, start + got, r->path,
                        "read error at byte %" PRIu64 " in cycle %" PRIu64, start + got,
                        r->next_cycle);
        return fail(err, BPX_TRACE_ERR_TRUNCATED, start + got, r->path,
                    "the file ends at byte %" PRIu64 " inside cycle %" PRIu64
                    " (did it shrink since it was opened?)",
                    start + got, r->next_cycle);
    }
    for (uint32_t i = 0; i < n; i++) {
        const unsigned char *p = r->buffer + (size_t)i * BPX_TRACE_BOX_BYTES;
        bpx_box b;
        for (int a = 0; a < 3; a++) {
            b.min[a] = get_f32(p + 4 * a);
            b.max[a] = get_f32(p + 12 + 4 * a);
        }
        const char *what = "";
        int axis = box_problem(&b, &what);
        if (axis >= 0) {
            uint64_t at = start + (uint64_t)i * BPX_TRACE_BOX_BYTES;
            // Leave the caller's array as it was: a bad cycle is not half-delivered.
            return fail(err, BPX_TRACE_ERR_BAD_BOX, at, r->path,
                        "cycle %" PRIu64 " box %" PRIu32 " (byte %" PRIu64 "): %s on axis %s "
                        "(min %.9g, max %.9g)",
                        r->next_cycle, i, at, what, axis_names[axis], (double)b.min[axis],
                        (double)b.max[axis]);
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        const unsigned char *p = r->buffer + (size_t)i * BPX_TRACE_BOX_BYTES;
        for (int a = 0; a < 3; a++) {
            out[i].min[a] = get_f32(p + 4 * a);
            out[i].max[a] = get_f32(p + 12 + 4 * a);
        }
    }
    r->next_cycle++;
    return ok(err, BPX_TRACE_OK);
}

bpx_trace_status bpx_trace_seek_cycle(bpx_trace_reader *r, uint64_t cycle, bpx_trace_error *err)
{
    if (!r)
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, NULL, "null reader");
    if (cycle > r->header.cycle_count)
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, r->path,
                    "cycle %" PRIu64 " is past the last (%" PRIu64 " cycles)", cycle,
                    r->header.cycle_count);
    uint64_t at = cycle_offset(&r->header, cycle);
    if (at > (uint64_t)INT64_MAX || fseeko(r->file, (off_t)at, SEEK_SET) != 0)
        return fail(err, BPX_TRACE_ERR_IO, at, r->path, "cannot seek to byte %" PRIu64, at);
    r->next_cycle = cycle;
    return ok(err, BPX_TRACE_OK);
}

void bpx_trace_close(bpx_trace_reader *r)
{
    if (!r)
        return;
    fclose(r->file);
    free(r->buffer);
    free(r->path);
    free(r);
}

bpx_trace_status bpx_trace_load(const char *path, bpx_trace_header *header, bpx_box **boxes,
                                bpx_trace_error *err)
{
    if (boxes)
        *boxes = NULL;
    if (!boxes)
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, path, "null argument");
    bpx_trace_reader *r;
    bpx_trace_status status = bpx_trace_open(path, &r, err);
    if (status != BPX_TRACE_OK)
        return status;
    const bpx_trace_header *h = bpx_trace_header_of(r);
    uint64_t total = h->cycle_count * h->box_count; // at most the file's length / 24 (open)
    bpx_box *all = NULL;
    if (total > 0) {
        if (total > SIZE_MAX / sizeof(bpx_box) || !(all = malloc((size_t)total * sizeof *all))) {
            bpx_trace_close(r);
            return fail(err, BPX_TRACE_ERR_NO_MEMORY, UINT64_MAX, path,
                        "out of memory for %" PRIu64 " boxes", total);
        }
    }
    // Cycles of 0 boxes take no bytes, so nothing in the file bounds their count (it may be
    // 2^64 - 1): there is nothing to read or check in them, and no loop runs over them.
    uint64_t cycles = h->box_count ? h->cycle_count : 0;
    for (uint64_t c = 0; c < cycles && status == BPX_TRACE_OK; c++)
        status = bpx_trace_read_cycle(r, all + c * h->box_count, err);
    if (status != BPX_TRACE_OK) {
        free(all);
        bpx_trace_close(r);
        return status;
    }
    if (header)
        *header = *h;
    bpx_trace_close(r);
    *boxes = all;
    return ok(err, BPX_TRACE_OK);
}

// --- Writer --------------------------------------------------------------------------------------

bpx_trace_status bpx_trace_writer_open(const char *path, uint32_t box_count, bpx_trace_writer **out,
                                       bpx_trace_error *err)
{
    if (out)
        *out = NULL;
    if (!path || !out)
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, path, "null argument");
    if (box_count > BPX_MAX_BOXES)
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, path,
                    "box count %" PRIu32 " exceeds %u", box_count, BPX_MAX_BOXES);
    bpx_trace_writer *w = calloc(1, sizeof *w);
    size_t cycle_bytes = (size_t)box_count * BPX_TRACE_BOX_BYTES;
    if (w) {
        w->path = copy_string(path);
        w->buffer = malloc(cycle_bytes ? cycle_bytes : 1);
    }
    if (!w || !w->path || !w->buffer) {
        if (w) {
            free(w->path);
            free(w->buffer);
        }
        free(w);
        return fail(err, BPX_TRACE_ERR_NO_MEMORY, UINT64_MAX, path, "out of memory");
    }
    w->box_count = box_count;
    w->file = fopen(path, "wb");
    if (!w->file) {
        int e = errno;
        free(w->path);
        free(w->buffer);
        free(w);
        return fail(err, BPX_TRACE_ERR_IO, UINT64_MAX, path, "cannot create: %s", strerror(e));
    }
    unsigned char h[BPX_TRACE_HEADER_BYTES] = {0};
    memcpy(h, BPX_TRACE_MAGIC, 8);
    put_u32(h + 8, BPX_TRACE_VERSION);
    put_u32(h + 12, box_count);
    put_u64(h + 16, 0); // written by close: an interrupted file is recognisably incomplete
    put_u32(h + 24, 6);
    put_u32(h + 28, 0);
    if (fwrite(h, 1, sizeof h, w->file) != sizeof h) {
        int e = errno;
        fclose(w->file);
        free(w->path);
        free(w->buffer);
        free(w);
        return fail(err, BPX_TRACE_ERR_IO, 0, path, "cannot write the header: %s", strerror(e));
    }
    *out = w;
    return ok(err, BPX_TRACE_OK);
}

bpx_trace_status bpx_trace_write_cycle(bpx_trace_writer *w, const bpx_box *boxes,
                                       bpx_trace_error *err)
{
    if (!w || (!boxes && w->box_count > 0))
        return fail(err, BPX_TRACE_ERR_ARGUMENT, UINT64_MAX, w ? w->path : NULL, "null argument");
    uint64_t start =
        BPX_TRACE_HEADER_BYTES + w->cycles * (uint64_t)w->box_count * BPX_TRACE_BOX_BYTES;
    for (uint32_t i = 0; i < w->box_count; i++) {
        const char *what = "";
        int axis = box_problem(&boxes[i], &what);
        if (axis >= 0) {
            uint64_t at = start + (uint64_t)i * BPX_TRACE_BOX_BYTES;
            return fail(err, BPX_TRACE_ERR_BAD_BOX, at, w->path,
                        "cycle %" PRIu64 " box %" PRIu32 " (would be byte %" PRIu64
                        "): %s on axis %s; nothing of this cycle was written",
                        w->cycles, i, at, what, axis_names[axis]);
        }
        unsigned char *p = w->buffer + (size_t)i * BPX_TRACE_BOX_BYTES;
        for (int a = 0; a < 3; a++) {
            put_f32(p + 4 * a, boxes[i].min[a]);
            put_f32(p + 12 + 4 * a, boxes[i].max[a]);
        }
    }
    size_t bytes = (size_t)w->box_count * BPX_TRACE_BOX_BYTES;
    if (bytes > 0 && fwrite(w->buffer, 1, bytes, w->file) != bytes)
        return fail(err, BPX_TRACE_ERR_IO, start, w->path,
                    "cannot write cycle %" PRIu64 " at byte %" PRIu64 ": %s", w->cycles, start,
                    strerror(errno));
    w->cycles++;
    return ok(err, BPX_TRACE_OK);
}

uint64_t bpx_trace_writer_cycles(const bpx_trace_writer *w)
{
    return w ? w->cycles : 0;
}

bpx_trace_status bpx_trace_writer_close(bpx_trace_writer *w, bpx_trace_error *err)
{
    if (!w)
        return ok(err, BPX_TRACE_OK);
    unsigned char count[8];
    put_u64(count, w->cycles);
    bpx_trace_status status = BPX_TRACE_OK;
    if (fflush(w->file) != 0 || fseeko(w->file, 16, SEEK_SET) != 0 ||
        fwrite(count, 1, sizeof count, w->file) != sizeof count)
        status = fail(err, BPX_TRACE_ERR_IO, 16, w->path,
                      "cannot write the cycle count at byte 16: %s", strerror(errno));
    if (fclose(w->file) != 0 && status == BPX_TRACE_OK)
        status =
            fail(err, BPX_TRACE_ERR_IO, UINT64_MAX, w->path, "cannot close: %s", strerror(errno));
    free(w->buffer);
    free(w->path);
    free(w);
    return status == BPX_TRACE_OK ? ok(err, BPX_TRACE_OK) : status;
}
